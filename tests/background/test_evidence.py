"""The photometric motion evidence (bgsub.background.evidence): what a patch can and cannot tell."""

import cv2
import numpy as np
import pytest

from helpers import random_texture, shifted

from bgsub.background.evidence import camera_evidence_map, motion_evidence_map, residual_field
from bgsub.background.fusion import flow_violation_map
from bgsub.errors import InputError

H, W = 96, 128


def _translation(dx, dy):
    return np.array([[1.0, 0, dx], [0, 1.0, dy], [0, 0, 1.0]])


def _grid_vectors(disp, step=8):
    ys, xs = np.mgrid[step // 2:H:step, step // 2:W:step]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    return pts, np.tile(np.float32(disp), (len(pts), 1)), np.ones(len(pts), np.float32)


def _stripes():
    """Vertical stripes: an image of edges only, the same along every column."""
    x = np.arange(W + 16)
    row = (127 + 100 * np.sign(np.sin(x / 3.0))).astype(np.uint8)
    return np.tile(row, (H + 16, 1))


def test_an_edge_moving_along_itself_gives_no_evidence():
    # The camera moves 3 px along the stripes; each patch reads no motion (it cannot tell) and
    # so disagrees with the camera by 3 px: a vector test calls all of it violating.
    prev = _stripes()[:H, :W]
    cur = _stripes()[3:H + 3, :W]  # the same image: a shift along the edges changes nothing
    cam = _translation(0.0, 3.0)
    pts, disp, w = _grid_vectors((0.0, 0.0))
    res = residual_field(pts, disp, w, cam, (H, W))
    evidence = motion_evidence_map(prev, cur, cam, residual=res)
    assert evidence.max() < 0.05
    assert flow_violation_map(pts, disp, cam, weights=w, shape=(H, W),
                              noise_scale=0.0).min() > 0.9


def test_an_edge_moving_across_itself_gives_evidence_where_it_disagrees():
    tex = _stripes()
    prev, cur = tex[:H, :W], tex[:H, 2:W + 2].copy()  # the stripes moved 2 px left ...
    cam = _translation(0.0, 0.0)  # ... while the camera stood still
    pts, disp, w = _grid_vectors((-2.0, 0.0))
    evidence = motion_evidence_map(prev, cur, cam,
                                   residual=residual_field(pts, disp, w, cam, (H, W)))
    assert np.median(evidence[8:-8, 8:-8]) > 0.9


def test_a_flat_region_gives_no_evidence_whatever_its_vectors_say():
    prev = np.full((H, W), 120, np.uint8)
    cam = _translation(2.0, 1.0)
    pts, disp, w = _grid_vectors((-5.0, 4.0))  # nonsense vectors on a blank wall
    evidence = motion_evidence_map(prev, prev.copy(), cam,
                                   residual=residual_field(pts, disp, w, cam, (H, W)))
    assert evidence.max() < 0.05


def test_a_wrong_vector_on_textured_background_gives_no_evidence():
    tex = random_texture(H, W, seed=3)
    prev, cur = tex[:H, :W], shifted(tex, -2, 0, H, W)
    cam = _translation(-2.0, 0.0)  # the true motion
    pts, disp, w = _grid_vectors((1.0, 1.0))  # every vector wrong by 3 px
    evidence = motion_evidence_map(prev, cur, cam,
                                   residual=residual_field(pts, disp, w, cam, (H, W)))
    assert evidence.max() < 0.05


def test_a_textured_object_moving_against_the_camera_is_marked():
    bg, obj = random_texture(H, W, seed=1), random_texture(32, 32, seed=2)[:32, :32]
    prev, cur = bg[:H, :W].copy(), shifted(bg, -2, 0, H, W)
    prev[40:72, 40:72] = obj
    cur[40:72, 44:76] = obj  # the object moved 4 px right while the background moved 2 left
    cam = _translation(-2.0, 0.0)
    pts, disp, w = _grid_vectors((-2.0, 0.0))
    on_obj = (pts[:, 0] >= 44) & (pts[:, 0] < 68) & (pts[:, 1] >= 44) & (pts[:, 1] < 68)
    disp[on_obj] = (4.0, 0.0)
    evidence = motion_evidence_map(prev, cur, cam,
                                   residual=residual_field(pts, disp, w, cam, (H, W)))
    assert evidence[46:66, 48:70].mean() > 0.5  # where its texture tells (not its flat parts)
    outside = np.ones((H, W), bool)
    outside[32:80, 32:84] = False
    assert np.percentile(evidence[outside], 99) < 0.1


def test_an_object_the_camera_follows_is_marked_without_vectors():
    bg, obj = random_texture(H, W, seed=4), random_texture(32, 32, seed=5)[:32, :32]
    prev, cur = bg[:H, :W].copy(), shifted(bg, -3, 0, H, W)
    prev[30:62, 40:72] = obj
    cur[30:62, 40:72] = obj  # stays put in the image while the background pans
    evidence = motion_evidence_map(prev, cur, _translation(-3.0, 0.0))
    assert evidence[36:56, 46:66].mean() > 0.7


def test_a_colour_only_difference_counts_in_colour_frames():
    # Two colours of one gray level: a gray test sees nothing, a colour one sees the object.
    a, b = np.array([60, 160, 110], np.uint8), np.array([200, 168, 41], np.uint8)
    assert (int(cv2.cvtColor(a[None, None], cv2.COLOR_BGR2GRAY)[0, 0])
            == int(cv2.cvtColor(b[None, None], cv2.COLOR_BGR2GRAY)[0, 0]))
    prev = np.tile(a, (H, W, 1))
    cur = prev.copy()
    prev[30:60, 30:60] = b
    cur[30:60, 36:66] = b  # moved 6 px on a still camera
    colour = motion_evidence_map(prev, cur, np.eye(3))
    gray = motion_evidence_map(cv2.cvtColor(prev, cv2.COLOR_BGR2GRAY),
                               cv2.cvtColor(cur, cv2.COLOR_BGR2GRAY), np.eye(3))
    assert gray.max() == 0.0 and colour.max() == 0.0  # "no motion" is the camera's motion
    pts, disp, w = _grid_vectors((0.0, 0.0))
    disp[(pts[:, 0] > 32) & (pts[:, 0] < 64) & (pts[:, 1] > 30) & (pts[:, 1] < 60)] = (6, 0)
    res = residual_field(pts, disp, w, np.eye(3), (H, W))
    assert motion_evidence_map(prev, cur, np.eye(3), residual=res)[30:60, 56:66].max() > 0.7
    assert motion_evidence_map(cv2.cvtColor(prev, cv2.COLOR_BGR2GRAY),
                               cv2.cvtColor(cur, cv2.COLOR_BGR2GRAY), np.eye(3),
                               residual=res).max() < 0.05


def test_background_moving_with_the_camera_is_confirmed_where_its_texture_tells():
    tex = random_texture(H, W, seed=6)
    prev, cur = tex[:H, :W].copy(), shifted(tex, -3, 0, H, W)
    prev[:, 64:] = cur[:, 64:] = 120  # a flat half: every motion explains it alike
    along = camera_evidence_map(prev, cur, _translation(-3.0, 0.0))
    assert np.median(along[8:-8, 8:56]) > 0.9
    assert along[:, 72:].max() == 0.0


@pytest.mark.parametrize("what", ["still camera", "followed object"])
def test_nothing_is_confirmed_where_no_motion_explains_the_frame_as_well(what):
    bg, obj = random_texture(H, W, seed=4), random_texture(32, 32, seed=5)[:32, :32]
    if what == "still camera":
        prev, cur, cam = bg[:H, :W], bg[:H, :W].copy(), np.eye(3)
        region = (slice(8, -8), slice(8, -8))
    else:
        prev, cur, cam = bg[:H, :W].copy(), shifted(bg, -3, 0, H, W), _translation(-3.0, 0.0)
        prev[30:62, 40:72] = cur[30:62, 40:72] = obj  # stays put while the background pans
        region = (slice(36, 56), slice(46, 66))
    assert camera_evidence_map(prev, cur, cam)[region].max() == 0.0


def test_the_residual_field_is_zero_where_no_vector_reports():
    pts, disp, w = _grid_vectors((1.0, 0.0))
    w[:] = 0
    assert not residual_field(pts, disp, w, np.eye(3), (H, W)).any()


@pytest.mark.parametrize("prev, cur", [
    (np.zeros((H, W), np.float32), np.zeros((H, W), np.uint8)),
    (np.zeros((H, W), np.uint8), np.zeros((H, W + 1), np.uint8)),
    (np.zeros((H, W, 3), np.uint8), np.zeros((H, W), np.uint8)),
])
def test_frames_of_another_type_or_shape_are_refused(prev, cur):
    with pytest.raises(InputError, match="motion_evidence_map"):
        motion_evidence_map(prev, cur, np.eye(3))


def _violation(fusion, pts, disp, w, cam, prev, cur):
    """The engine's violation map: the vectors' and the frames' evidence combined."""
    image = fusion.image_evidence(pts, disp, w, cam, prev, cur)
    vectors = fusion.vector_evidence(pts, disp, w, cam, cur.shape[:2])
    return fusion.combined(vectors, None if image is None else image[0])


def test_the_fusion_takes_the_larger_of_the_vectors_and_the_frames_evidence():
    from bgsub.background.fusion import Fusion, FusionConfig

    bg, obj = random_texture(H, W, seed=4), random_texture(32, 32, seed=5)[:32, :32]
    prev, cur = bg[:H, :W].copy(), shifted(bg, -3, 0, H, W)
    prev[30:62, 20:52] = obj
    cur[30:62, 20:52] = obj  # followed by the camera: only the frames tell
    cam = _translation(-3.0, 0.0)
    pts, disp, w = _grid_vectors((-3.0, 0.0))
    right = pts[:, 0] > 96
    disp[right] = (3.0, 0.0)  # the vectors see a mover on the right, the frames do not agree
    w[(pts[:, 0] > 12) & (pts[:, 0] < 60)] = 0  # and nothing over the followed object
    fusion = Fusion(FusionConfig(violation_threshold=1.5, violation_noise=0.0))
    both = _violation(fusion, pts, disp, w, cam, prev, cur)
    vectors = flow_violation_map(pts, disp, cam, weights=w, shape=(H, W), threshold=1.5)
    frames = motion_evidence_map(prev, cur, cam,
                                 residual=residual_field(pts, disp, w, cam, (H, W)))
    np.testing.assert_allclose(both, np.maximum(vectors, frames), atol=1e-6)
    assert both[36:56, 26:46].mean() > 0.7 and both[:, 110:].mean() > 0.9
    off = Fusion(FusionConfig(violation_threshold=1.5, violation_noise=0.0, image_cue=0.0))
    np.testing.assert_allclose(_violation(off, pts, disp, w, cam, prev, cur), vectors, atol=1e-6)


@pytest.mark.parametrize("confirm, mover_disputes", [(0.5, True), (0.5, False), (0.0, False)])
def test_only_undisputed_foreground_moving_with_the_camera_is_confirmed(confirm, mover_disputes):
    from bgsub.background.fusion import Fusion, FusionConfig

    tex = random_texture(H, W, seed=7)
    prev, cur = tex[:H, :W], shifted(tex, -3, 0, H, W)  # all background, moving with the camera
    cam = _translation(-3.0, 0.0)
    pts, disp, w = _grid_vectors((-3.0, 0.0))
    if mover_disputes:
        disp[pts[:, 0] < 64] = (3.0, 0.0)  # the vectors of the left half disagree
    fusion = Fusion(FusionConfig(violation_threshold=1.5, violation_noise=0.0, confirm=confirm))
    violation = _violation(fusion, pts, disp, w, cam, prev, cur)
    along = fusion.image_evidence(pts, disp, w, cam, prev, cur)[1]
    mask = np.zeros((H, W), np.uint8)
    mask[20:76, 20:108] = 255  # foreground across both halves
    confirmed = fusion.confirmed(mask, violation, along)
    if confirm == 0:
        assert confirmed is None
        return
    assert not confirmed[mask == 0].any()
    assert confirmed[24:72, 80:104].mean() > 0.9  # undisputed
    assert confirmed[24:72, 24:56].any() != mover_disputes
