"""bgsub.engines.roi: the region of interest, for every engine and in the camera-motion fit.

The scene: the top of the frame pans 5 px a frame to the right; the bottom 64 rows are a
static textured dashboard (more than half the frame, so its zero motion pulls the camera fit)
with a bright block moving over it; an object moves in the panning part. The region of interest
is the top 56 rows."""

import cv2
import numpy as np
import pytest
from helpers import model_path

from bgsub.engines import available_engines, create_engine
from bgsub.engines.roi import RegionOfInterest
from bgsub.errors import InputError
from bgsub.motion.global_motion import apply_homography

H, W, TOP, PAN = 120, 160, 56, 5


def _world(seed, h, w):
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 4, w // 4, 3)).astype(np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def _scene(n=12):
    big = _world(0, H, W + PAN * n + 8)
    dashboard = _world(1, H - TOP, W)
    for k in range(n):
        x0 = PAN * (n - k)
        frame = big[:, x0:x0 + W].copy()
        frame[TOP:] = dashboard
        frame[TOP + 10:TOP + 22, 10 + 4 * k:22 + 4 * k] = 250  # moving overlay, outside
        frame[20:36, 60 + k:76 + k] = (30, 30, 220)  # an object, inside
        yield frame


def _roi(h=H, w=W):
    roi = np.zeros((h, w), np.uint8)
    roi[:TOP * h // H] = 255
    return roi


def _engine(name, **params):
    if name == "grbm":
        params["model"] = model_path()
    return create_engine(name, **params)


BUILT_IN = ["grbm", "compensated", "mog2", "knn", "framediff"]


def test_every_built_in_engine_is_tested():
    assert {spec.name for spec in available_engines()
            if spec.factory.__module__.startswith("bgsub.")} == set(BUILT_IN)


@pytest.mark.parametrize("name", BUILT_IN)
def test_no_foreground_outside_the_region_for_every_engine(name):
    engine = _engine(name, roi=_roi())
    inside = 0
    for frame in _scene():
        mask = engine.apply(frame)
        assert not mask[TOP:].any()
        inside += int(np.count_nonzero(mask[:TOP]))
    assert inside > 0  # the engine still works inside


def _errors_in_region(engine):
    """The median over the frames after the first of the largest distance (px) between the
    engine's camera motion (none, after a scene cut: the identity) and the true pan, over a
    grid of the region of interest."""
    ys, xs = np.mgrid[4:TOP:8, 4:W:8]
    grid = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    errors = []
    for k, frame in enumerate(_scene()):
        engine.apply(frame)
        if k:
            motion = engine.last_motion
            moved = apply_homography(np.eye(3) if motion is None else motion, grid) - grid
            errors.append(float(np.abs(moved - [PAN, 0]).max()))
    return np.median(errors)


@pytest.mark.parametrize("name", ["compensated", "grbm"])
def test_the_camera_fit_leaves_the_motion_outside_the_region_out(name):
    assert _errors_in_region(_engine(name)) > 1.5  # the dashboard pulls the fit
    engine = _engine(name, roi=_roi())
    assert _errors_in_region(engine) < 0.6
    result = engine.last_result
    outside = result.points[:, 1] >= TOP - 0.5
    assert outside.any() and not (result.weights[outside] > 0).any()


def test_a_region_of_the_frames_aspect_is_scaled_to_them(tmp_path):
    path = tmp_path / "roi.png"
    cv2.imwrite(str(path), _roi(H // 2, W // 2))
    by_file = create_engine("mog2", roi=str(path))
    by_array = create_engine("mog2", roi=_roi())
    for frame in _scene(4):
        assert np.array_equal(by_file.apply(frame), by_array.apply(frame))


def test_the_region_is_applied_to_fgmask_too():
    engine = create_engine("framediff", roi=_roi())
    out = np.full((H, W), 7, np.uint8)
    for frame in _scene(3):
        engine.apply(frame, out)
    assert not out[TOP:].any()


@pytest.mark.parametrize("content, words", [
    (None, "no such file"),
    (b"not an image", "cannot read the region of interest"),
    (np.zeros((H, W), np.uint8), "all black"),
])
def test_bad_region_files_are_refused(tmp_path, content, words):
    path = tmp_path / "roi.png"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        cv2.imwrite(str(path), content)
    with pytest.raises(InputError, match=words):
        create_engine("mog2", roi=str(path))


def test_a_region_of_another_aspect_ratio_is_refused_before_the_engine_changes():
    engine = create_engine("mog2", roi=np.full((100, 100), 255, np.uint8))
    with pytest.raises(InputError, match="aspect ratio"):
        engine.apply(next(_scene()))
    assert engine.get_background_image() is None


def test_region_inside_tests_points_of_the_frame():
    region = RegionOfInterest(_roi())
    points = np.array([[5, 5], [5, TOP + 5], [-3, 5], [np.nan, 1]], np.float32)
    assert region.inside(points, (H, W)).tolist() == [True, False, False, False]
