"""The dense read of a flat background (bgsub.camera.flat_read): the camera's motion where the
patches read only the subject it follows."""

import cv2
import numpy as np

from bgsub.camera import CameraConfig, CameraStage, SMALL_REGION
from bgsub.camera.flat_read import FLAT_READ, FlatRead, is_flat, outside
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.result import MotionResult
from helpers import random_texture

SHAPE = (120, 160)  # (h, w)
SUBJECT = (slice(45, 75), slice(60, 100))  # rows, columns of the textured subject


def _fog(seed=0, amplitude=150.0):
    """A wide, faint world (fog, sky): ``(h + 60, w + 60) float32``, far flatter than a patch
    can read."""
    rng = np.random.default_rng(seed)
    noise = rng.normal(0, 1, (SHAPE[0] + 60, SHAPE[1] + 60)).astype(np.float32)
    return 140 + amplitude * cv2.GaussianBlur(noise, (0, 0), 8)


def _frame(world, dx, dy, *, subject=True, seed=0):
    """``(h, w) uint8``: ``world`` seen shifted by (dx, dy) px (the content moves by it), with
    light noise and, fixed in the image, a textured subject (the camera follows it)."""
    m = np.float32([[1, 0, dx - 30], [0, 1, dy - 30]])
    view = cv2.warpAffine(world, m, SHAPE[::-1], flags=cv2.INTER_LINEAR)
    view += np.random.default_rng(seed + 7).normal(0, 1.0, view.shape).astype(np.float32)
    frame = np.clip(view, 0, 255).astype(np.uint8)
    if subject:
        frame[SUBJECT] = random_texture(30, 40, seed=3)[:30, :40]
    return frame


def _on_subject(dx=0.0, dy=0.0):
    """What the patches read: vectors on the subject only, moving by (dx, dy), the fit theirs."""
    ys, xs = np.mgrid[50:75:6, 64:100:6]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    disp = np.tile(np.float32([dx, dy]), (len(pts), 1))
    matrix = np.array([[1.0, 0, dx], [0, 1.0, dy], [0, 0, 1.0]])
    motion = GlobalMotion(matrix, np.ones(len(pts), bool), True)
    return MotionResult(pts, disp, np.ones(len(pts), np.float32), motion)


def _read(previous, current, measured, last_good=None):
    flat = FlatRead(box_share=0.6, least_correlation=0.5, threshold=1.0)
    flat.check(measured, previous, None)
    return flat.check(measured, current, last_good)


def test_a_subject_followed_through_fog_gives_the_fog_s_motion():
    world = _fog()
    result, read = _read(_frame(world, 0, 0), _frame(world, 3.0, -1.0, seed=1), _on_subject())
    assert read and result.motion.ok and result.motion.reason == FLAT_READ
    np.testing.assert_allclose(result.motion.matrix[:2, 2], [3.0, -1.0], atol=0.25)
    assert not result.motion.inliers.any()  # the subject's vectors do not follow the camera


def test_a_fast_pan_is_read_from_the_last_good_motion():
    world = _fog(seed=1)
    last = np.array([[1.0, 0, 7.0], [0, 1.0, 0], [0, 0, 1.0]])
    result, read = _read(_frame(world, 0, 0), _frame(world, 7.5, 0.5, seed=1), _on_subject(),
                         last_good=last)
    assert read
    np.testing.assert_allclose(result.motion.matrix[:2, 2], [7.5, 0.5], atol=0.5)


def test_a_still_camera_over_fog_keeps_the_fit():
    world = _fog()
    measured = _on_subject()
    result, read = _read(_frame(world, 0, 0), _frame(world, 0, 0, seed=1), measured)
    assert not read and result is measured


def test_a_textured_background_keeps_the_fit():
    # Its vectors were read and the fit chose: a dense read there would only second-guess it.
    world = random_texture(SHAPE[0] + 60, SHAPE[1] + 60).astype(np.float32)
    measured = _on_subject()
    result, read = _read(_frame(world, 0, 0), _frame(world, 3.0, 0, seed=1), measured)
    assert not read and result is measured


def test_a_fit_spread_across_the_frame_is_not_read_again():
    world = _fog()
    ys, xs = np.mgrid[10:110:20, 10:150:20]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    measured = MotionResult(pts, np.zeros_like(pts), np.ones(len(pts), np.float32),
                            GlobalMotion(np.eye(3), np.ones(len(pts), bool), True))
    result, read = _read(_frame(world, 0, 0), _frame(world, 3.0, 0, seed=1), measured)
    assert not read and result is measured


def test_a_ramp_of_sky_under_a_still_camera_reads_no_motion():
    # ECC forgives an offset, so along a smooth ramp it reads any shift as well as none; the
    # plain difference of the frames says the ramp did not move.
    ramp = np.tile(np.linspace(60, 190, SHAPE[1] + 60, dtype=np.float32), (SHAPE[0] + 60, 1))
    flat = FlatRead(box_share=0.6, least_correlation=0.5, threshold=1.0)
    last = np.eye(3)
    for k in range(8):  # from the last good motion, a free read would walk along the ramp
        result, read = flat.check(_on_subject(3.0, 0.0), _frame(ramp, 0, 0, seed=k), last)
        if read:
            last = result.motion.matrix
            np.testing.assert_allclose(last[:2, 2], [0.0, 0.0], atol=0.5)


def test_a_blank_background_has_nothing_to_read():
    blank = np.full((SHAPE[0] + 60, SHAPE[1] + 60), 140, np.float32)
    measured = _on_subject()
    result, read = _read(_frame(blank, 0, 0), _frame(blank, 3.0, 0, seed=1), measured)
    assert not read and result is measured


def test_fog_is_flat_and_texture_is_not():
    keep = outside((60, 45, 99, 74), SHAPE)
    assert keep[0, 0] == 1 and keep[60, 80] == 0
    assert is_flat(_frame(_fog(), 0, 0), keep)
    textured = random_texture(SHAPE[0] + 60, SHAPE[1] + 60).astype(np.float32)
    assert not is_flat(_frame(textured, 0, 0), keep)


def test_the_camera_stage_takes_the_read_and_says_so():
    world = _fog()
    stage = CameraStage(CameraConfig())
    stage.restart(None)
    stage.decide(_on_subject(), _frame(world, 0, 0), None, frozen=False)
    seen = stage.decide(_on_subject(), _frame(world, 3.0, 0, seed=1), None, frozen=False)
    assert seen.status == FLAT_READ and not seen.refused
    np.testing.assert_allclose(seen.matrix[:2, 2], [3.0, 0.0], atol=0.25)


def test_without_the_read_the_subject_s_fit_is_refused_as_before():
    world = _fog()
    stage = CameraStage(CameraConfig(flat_read=0.0))
    stage.decide(_on_subject(), _frame(world, 0, 0), None, frozen=False)
    seen = stage.decide(_on_subject(), _frame(world, 3.0, 0, seed=1), None, frozen=False)
    assert seen.refused and seen.status == "fallback: " + SMALL_REGION
