"""The colour cut (bgsub.background.colour_cut): an object's flat parts, which show no motion,
added to its mask by their colours."""

import cv2
import numpy as np

from bgsub.background.colour_cut import colour_cut
from bgsub.samples import SceneSpec, render_frames

H, W = 120, 160
FLANK, PATCH = (25, 25, 30), (230, 230, 235)  # BGR: a cow's black flank, a white patch


def _cow(seed=0):
    """A textured green-and-brown field with a 40 x 60 black object (rows 40-79, columns
    50-109) whose left third is a white patch: ``(frame (H, W, 3) uint8, object (H, W) bool,
    found (H, W) bool)``; ``found`` is what the motion found of it, all but a flat 25 x 25
    corner of the flank."""
    rng = np.random.default_rng(seed)
    grass = rng.integers(0, 2, (H // 4, W // 4))
    field = np.where(grass[..., None], (60, 140, 70), (50, 90, 130)).astype(np.float32)
    frame = cv2.resize(field, (W, H), interpolation=cv2.INTER_NEAREST)
    obj = np.zeros((H, W), bool)
    obj[40:80, 50:110] = True
    frame[obj] = FLANK
    frame[40:80, 50:70] = PATCH
    frame += rng.normal(0, 3, frame.shape)
    found = obj.copy()
    found[55:80, 85:110] = False
    return np.clip(frame, 0, 255).astype(np.uint8), obj, found


def _mask(where):
    return where.astype(np.uint8) * np.uint8(255)


def test_the_flat_part_next_to_what_was_found_joins_the_mask():
    frame, obj, found = _cow()
    out = colour_cut(_mask(found), frame, radius=20) > 0
    assert out[found].all()  # nothing found is taken away
    assert out[obj].mean() > 0.95  # found: 0.74
    assert out[~obj].mean() < 0.01


def test_only_pixels_within_the_radius_can_join():
    frame, obj, found = _cow()
    out = colour_cut(_mask(found), frame, radius=2) > 0
    assert out[obj].mean() < 0.8


def test_a_grey_frame_is_cut_as_well():
    frame, obj, found = _cow()
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    out = colour_cut(_mask(found), grey, radius=20) > 0
    assert out.shape == (H, W) and out[obj].mean() > 0.95


def test_an_empty_or_tiny_mask_comes_back_as_it_is():
    frame, _, _ = _cow()
    empty = np.zeros((H, W), np.uint8)
    assert not colour_cut(empty, frame, radius=9).any()
    dot = empty.copy()
    dot[60:63, 60:63] = 255
    np.testing.assert_array_equal(colour_cut(dot, frame, radius=9), dot)


def test_a_mask_over_the_whole_frame_has_no_background_to_learn_and_stays():
    frame, _, _ = _cow()
    full = np.full((H, W), 255, np.uint8)
    np.testing.assert_array_equal(colour_cut(full, frame, radius=9), full)


def test_the_cut_is_the_same_whatever_used_opencvs_random_generator_before():
    # (GrabCut's k-means draws from OpenCV's generator; on this frame, unseeded, a pixel or two
    # of the cut changed with the generator's state.)
    frame = list(render_frames(SceneSpec("pan", seed=0, n_frames=20)))[-1]
    found = cv2.erode(_mask(frame.groundtruth == 255), np.ones((5, 5), np.uint8))
    cuts = []
    for _ in range(6):
        cuts.append(colour_cut(found, frame.image, radius=9))
        cv2.randu(np.empty((64, 64), np.float32), 0, 1)  # moves OpenCV's generator on
    assert np.count_nonzero(cuts[0] & ~found) > 100
    for cut in cuts[1:]:
        np.testing.assert_array_equal(cut, cuts[0])
