"""Frame-fixed overlays (a logo burnt into the frames) are background, and leave the camera fit
to the scene: bgsub.background.overlay through the moving-camera engine."""

import cv2
import numpy as np
import pytest

from bgsub import create_engine
from bgsub.background.overlay import OverlayConfig, OverlayDetector
from bgsub.samples import SceneSpec, render_frames

from helpers import write_pan_clip

# The logo: an opaque box with a word in it, fixed in the frame's top-left corner.
BOX = (8, 8, 96, 40)  # x, y, w, h


def with_logo(image: np.ndarray) -> np.ndarray:
    x, y, w, h = BOX
    out = image.copy()
    cv2.rectangle(out, (x, y), (x + w, y + h), (150, 40, 60), -1)
    cv2.putText(out, "NEWS", (x + 8, y + 30), cv2.FONT_HERSHEY_SIMPLEX, 0.9, (255, 255, 255), 2)
    return out


def run(category: str, *, n_frames: int = 60, seed: int = 1, **params):
    """``(engine, masks, groundtruths)`` of the engine over a sample scene with the logo."""
    engine = create_engine("grbm", **params)
    masks, gts = [], []
    for image, gt, _ in render_frames(SceneSpec(category, seed=seed, n_frames=n_frames)):
        masks.append(engine.apply(with_logo(image)))
        gts.append(gt)
    return engine, masks, gts


def f_measure(masks, gts) -> float:
    tp = fp = fn = 0
    for m, g in zip(masks, gts):
        fg, known = m > 0, g != 170
        tp += np.count_nonzero(fg & (g == 255))
        fp += np.count_nonzero(fg & (g == 0) & known)
        fn += np.count_nonzero(~fg & (g == 255))
    return 2 * tp / max(2 * tp + fp + fn, 1)


def logo_region(shape) -> np.ndarray:
    x, y, w, h = BOX
    region = np.zeros(shape, bool)
    region[y:y + h, x:x + w] = True
    return region


@pytest.fixture(scope="module")
def panning():
    return run("pan")


def test_a_logo_over_a_panning_scene_is_found_as_an_overlay(panning):
    engine, _, _ = panning
    assert engine.overlays.mask is not None
    region = logo_region(engine.overlays.mask.shape)
    assert engine.overlays.mask[region].mean() > 0.9
    # ... and nothing far from it
    far = ~cv2.dilate(region.view(np.uint8), np.ones((25, 25), np.uint8)).astype(bool)
    assert engine.overlays.mask[far].mean() < 0.01


def test_a_logo_over_a_panning_scene_stays_background(panning):
    _, masks, gts = panning
    region = logo_region(masks[0].shape)
    assert all(np.count_nonzero(m[region]) == 0 for m in masks[-20:])
    assert f_measure(masks[-20:], gts[-20:]) > 0.8  # and the objects are still found


def test_with_overlays_off_the_logo_is_called_foreground():
    # The failure the detector exists for: without it the logo is found as a moving object.
    _, masks, _ = run("pan", overlay=0)
    region = logo_region(masks[0].shape)
    assert np.mean([np.count_nonzero(m[region]) > 0 for m in masks[-20:]]) > 0.5


def test_a_still_camera_finds_no_overlay():
    # Every textured pixel of a still camera's background holds still: none is an overlay.
    engine, _, _ = run("static")
    assert engine.overlays.mask is None


def test_a_region_of_interest_turns_the_detection_off():
    roi = np.full((240, 320), 255, np.uint8)
    engine, _, _ = run("pan", n_frames=40, roi=roi)
    assert engine.overlays.mask is None


def test_the_detector_needs_a_moving_scene():
    # Frames that all hold still (a still camera, a paused stream) teach the detector nothing.
    detector = OverlayDetector(OverlayConfig(overlay_frames=2, overlay_lag=1))
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, (48, 64), np.uint8)
    points = np.stack(np.meshgrid(np.arange(8, 64, 8), np.arange(8, 48, 8)), -1).reshape(-1, 2)
    for _ in range(10):
        detector.observe(frame, points.astype(np.float32), np.zeros_like(points, np.float32),
                         np.ones(len(points), np.float32))
    assert detector.mask is None


def test_bgsub_run_reports_the_overlay_once(tmp_path, capsys):
    from bgsub.cli import main

    clip = write_pan_clip(tmp_path / "logo.avi", seed=1, n=50, fourcc="FFV1", burn_in=with_logo)
    assert main(["run", str(clip), "-o", str(tmp_path / "masks.mkv")]) == 0
    err = capsys.readouterr().err
    assert err.count("frame-fixed overlays") == 1
    assert "taken as background" in err
