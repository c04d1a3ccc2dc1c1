"""Plane plus parallax (bgsub.camera.parallax): the background's motion beyond the homography,
from vectors with exact answers, and through the engine on the ``parallax`` sample scene (a
camera translating past a near ground band)."""

import numpy as np
import pytest

from bgsub import create_engine
from bgsub.camera.parallax import ParallaxConfig, ParallaxField, fit_epipole, without_parallax
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.result import MotionResult
from bgsub.samples import SceneSpec, render_frames

SHAPE = (240, 320)  # (h, w)
PAN = np.array([[1.0, 0.0, -2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # the far layer's motion


def _grid(step=8):
    ys, xs = np.mgrid[4:SHAPE[0]:step, 4:SHAPE[1]:step]
    return np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)


def _band_vectors(seed, *, band_speed=2.0, band_top=0.7, object_box=None,
                  object_disp=(0.0, 0.0), band_ramp=0.0):
    """``(points, disp, weights)``: the far layer moving by ``PAN``, the frame below
    ``band_top`` of its height (a near band) ``band_speed`` times as fast (plus ``band_ramp``
    times the vector's x from -1/2 to 1/2 across the frame), an object moving by
    ``object_disp`` in ``object_box`` (x0, y0, x1, y1); 0.1 px of noise."""
    rng = np.random.default_rng(seed)
    pts = _grid()
    disp = np.tile(PAN[:2, 2], (len(pts), 1))
    band = pts[:, 1] >= band_top * SHAPE[0]
    disp[band] *= band_speed + band_ramp * (pts[band, :1] / SHAPE[1] - 0.5)
    if object_box is not None:
        x0, y0, x1, y1 = object_box
        inside = (pts[:, 0] >= x0) & (pts[:, 0] < x1) & (pts[:, 1] >= y0) & (pts[:, 1] < y1)
        disp[inside] = object_disp
    disp += rng.normal(0, 0.1, disp.shape)
    return pts, disp, np.ones(len(pts))


def _field(frames, config=ParallaxConfig(), **vectors):
    """The field of the last of ``frames`` frames of the same vectors (a steady camera)."""
    parallax = ParallaxField(config)
    field = None
    for k in range(frames):
        pts, disp, wt = _band_vectors(k, **vectors)
        field = parallax.estimate(pts, disp, wt, PAN, SHAPE)
    return parallax, field


def test_the_epipole_of_residuals_along_one_direction_is_found_among_outliers():
    rng = np.random.default_rng(0)
    anchors = rng.uniform(0, 300, (200, 2))
    residual = np.outer(rng.uniform(1, 3, 200), [0.8, 0.6])
    residual[:50] = rng.normal(0, 2, (50, 2))  # a quarter of them objects
    e, inliers = fit_epipole(anchors, residual, np.ones(200), tolerance=0.2)
    assert abs(abs(e[:2] @ [0.8, 0.6]) - 1) < 1e-3 and e[2] == 0
    assert inliers[50:].all() and inliers[:50].mean() < 0.3


def test_a_translating_camera_past_a_near_band_gives_the_band_its_parallax():
    parallax, field = _field(4)
    assert field is not None and field.shape == SHAPE + (2,) and field.dtype == np.float32
    band, far = field[200:, :, 0], field[:140, :, 0]
    np.testing.assert_allclose(np.median(band), -2.0, atol=0.2)  # twice the far layer's -2
    assert np.abs(far).max() < 0.3


def test_a_planar_scene_has_no_parallax():
    _, field = _field(4, band_speed=1.0, object_box=(40, 40, 100, 100), object_disp=(1.0, 2.0))
    assert field is None


THIN = 0.94  # the bottom two rows of vectors: 7 % of them, less than the `parallax` share


def test_a_thin_band_nearer_than_the_plane_is_parallax():
    _, field = _field(4, band_top=THIN)
    assert field is not None
    np.testing.assert_allclose(np.median(field[232:, :, 0]), -2.0, atol=0.2)


def test_a_thin_band_that_lags_behind_the_plane_for_a_few_frames_is_not_parallax():
    # (what an object the camera follows looks like: still in the image, the plane moving)
    assert _field(4, band_top=THIN, band_speed=0.0)[1] is None
    assert _field(4, band_top=THIN, band_speed=-1.0)[1] is None


def test_a_thin_layer_that_lags_behind_the_plane_frame_after_frame_is_a_farther_layer():
    # (the fit took a near band for the plane; the far layer's towers lag, all by half its step)
    frames = ParallaxConfig().parallax_far + 2
    assert _field(frames - 3, band_top=THIN, band_speed=0.5)[1] is None
    parallax, field = _field(frames, band_top=THIN, band_speed=0.5)
    assert field is not None and parallax.far_run == frames
    np.testing.assert_allclose(np.median(field[232:, :, 0]), 1.0, atol=0.2)  # -1 less -2
    assert _field(frames, ParallaxConfig(parallax_far=0), band_top=THIN, band_speed=0.5)[1] is None


def test_a_lagging_band_whose_vectors_lag_by_many_amounts_is_no_farther_layer():
    # (water round a subject the camera follows lags behind the plane by scattered amounts)
    frames = ParallaxConfig().parallax_far + 2
    assert _field(frames, band_top=THIN, band_speed=0.5, band_ramp=0.2)[1] is not None
    assert _field(frames, band_top=THIN, band_speed=0.5, band_ramp=1.4)[1] is None


def test_a_compact_object_overtaking_the_plane_is_not_parallax():
    box = (120, 40, 216, 136)  # 96 x 96 px: 6 % of the vectors, ahead of the plane
    assert _field(4, band_speed=1.0, object_box=box, object_disp=(-4.0, 0.0))[1] is None


def test_a_compact_subject_the_camera_follows_is_not_parallax():
    # (held still in the image while the plane pans, it lags the plane in one steady direction;
    # over a plain sky its vectors carry much of the weight)
    box = (120, 60, 216, 156)  # 96 x 96 px: 12 % of the vectors, over the `parallax` share
    for frames in (4, ParallaxConfig().parallax_far + 2):
        assert _field(frames, band_speed=1.0, object_box=box, object_disp=(0.0, 0.0))[1] is None


def test_parallax_near_zero_leaves_a_thin_band_to_the_parallax_share():
    assert _field(4, ParallaxConfig(parallax_near=0.0), band_top=THIN)[1] is None
    assert _field(4, ParallaxConfig(parallax_near=0.0, parallax=0.05), band_top=THIN)[1] is not None


def test_parallax_needs_a_steady_camera_path_over_frames():
    assert _field(1)[1] is None and _field(2)[1] is None and _field(3)[1] is not None


def test_a_small_object_moving_along_the_parallax_keeps_its_own_motion():
    box = (150, 60, 182, 92)  # 32 x 32 px on the far layer, moving as the band does
    _, field = _field(4, object_box=box, object_disp=(-4.0, 0.0))
    assert np.abs(field[60:92, 150:182]).max() < 0.5


def test_the_parallax_is_taken_off_the_vectors():
    parallax, field = _field(4)
    pts, disp, wt = _band_vectors(9)
    result = MotionResult(pts.astype(np.float32), disp.astype(np.float32),
                          wt.astype(np.float32), GlobalMotion.identity(len(pts)))
    left = without_parallax(result, field).disp - (PAN[:2, 2])
    assert np.abs(np.median(left[pts[:, 1] >= 0.7 * SHAPE[0]], axis=0)).max() < 0.2
    assert without_parallax(result, None) is result


# ---------------------------------------------------------------------- through the engine

def _run(**params):
    """``(band false-positive share, object recall)`` of grbm on the parallax sample."""
    engine = create_engine("grbm", **params)
    spec = SceneSpec("parallax", seed=2, n_frames=90)
    band_fp, hits, total = [], 0, 0
    for k, (image, gt, _) in enumerate(render_frames(spec)):
        mask = engine.apply(image) > 0
        if k >= spec.warmup_frames + 10:
            bottom = (gt == 0)[-40:]  # the bottom sixth is always the near band
            band_fp.append(mask[-40:][bottom].mean())
            hits += np.count_nonzero(mask & (gt == 255))
            total += np.count_nonzero(gt == 255)
    return float(np.mean(band_fp)), hits / max(total, 1)


@pytest.fixture(scope="module")
def with_and_without():
    return _run(), _run(parallax=0)


def test_the_near_band_of_a_translating_camera_is_background(with_and_without):
    (band_fp, _), (band_fp_plane, _) = with_and_without
    assert band_fp < 0.05
    assert band_fp_plane > 0.3  # one homography calls the band foreground


def test_the_objects_are_still_found_over_a_3d_scene(with_and_without):
    (_, recall), _ = with_and_without
    assert recall > 0.6


def test_bgsub_samples_and_run_end_to_end_on_a_parallax_scene(tmp_path):
    import csv

    from helpers import read_frames

    from bgsub.cli import main

    assert main(["samples", str(tmp_path), "-c", "parallax", "pan", "-s", "2",
                 "--max-frames", "60", "-q"]) == 0
    shares = {}
    for name in ("parallax_s2", "pan_s2"):
        out = tmp_path / name
        assert main(["run", str(tmp_path / name / f"{name}.mp4"), "-o", str(out) + ".mkv",
                     "--stats", str(out) + ".csv", "-q"]) == 0
        with open(str(out) + ".csv", newline="") as f:
            rows = list(csv.DictReader(f))[30:]
        shares[name] = np.mean([float(r["parallax"]) for r in rows])
    masks = read_frames(tmp_path / "parallax_s2.mkv")[30:]
    band = np.mean([m[-40:].mean() / 255 for m in masks])
    assert len(masks) == 30 and band < 0.05
    assert shares["parallax_s2"] > 0.1 and shares["pan_s2"] == 0  # --stats says which


def test_at_the_band_edge_the_score_counts_less_and_the_motion_has_no_opinion():
    parallax, _ = _field(4)
    edges = parallax.edges
    assert edges[168, 160] > 0.5 and edges[40, 160] < 0.1  # the band's top, the far layer
    score, violation = np.ones(SHAPE, np.float32), np.ones(SHAPE, np.float32)
    parallax.discount_edges(score, violation)
    assert score[168, 160] < 0.8 and score[40, 160] > 0.95
    assert abs(violation[168, 160] - 0.5) < 0.25 and violation[40, 160] > 0.9


def test_a_3d_scene_stands_for_parallax_keep_frames_after_its_last_field():
    parallax = ParallaxField(ParallaxConfig(parallax_keep=2))
    assert not parallax.standing()
    for k in range(4):
        parallax.estimate(*_band_vectors(k), PAN, SHAPE)
    assert parallax.standing()
    flat = _band_vectors(9, band_speed=1.0)
    standing = []
    for _ in range(3):
        assert parallax.estimate(*flat, PAN, SHAPE) is None
        standing.append(parallax.standing())
    assert standing == [True, True, False]
    parallax.estimate(*_band_vectors(5), PAN, SHAPE)
    parallax.restart()
    assert not parallax.standing()


def test_a_post_across_the_camera_path_keeps_its_own_parallax():
    # (a 32 px post, nearer than the far layer: 1.8 times its motion, over the frame's height)
    post = dict(object_box=(148, 0, 180, SHAPE[0]), object_disp=(-3.6, 0.0))
    _, field = _field(4, **post)
    _, plain = _field(4, ParallaxConfig(parallax_posts=0), **post)
    assert abs(field[60, 164, 0] + 1.6) < 0.4  # its departure from the plane
    assert abs(plain[60, 164, 0]) < 0.4  # lost in the 5 x 5 median


def test_the_neighbour_warps_hold_each_side_of_a_depth_edge():
    parallax, _ = _field(4)
    plane, least, greatest = parallax.neighbour_warps(PAN, SHAPE)
    assert plane is None  # the plane alone
    # The band's top (row 168): one warp takes the far layer's depth, the other the band's
    # 2 px beyond it; in the far layer (row 40) they agree.
    assert abs(abs(least.map_x[168, 160] - greatest.map_x[168, 160]) - 2.0) < 0.5
    assert abs(least.map_x[40, 160] - greatest.map_x[40, 160]) < 0.1


def test_no_neighbour_warps_without_a_field_or_with_parallax_layers_zero():
    assert ParallaxField(ParallaxConfig()).neighbour_warps(PAN, SHAPE) == []
    off, _ = _field(4, ParallaxConfig(parallax_layers=0))
    assert off.neighbour_warps(PAN, SHAPE) == []
