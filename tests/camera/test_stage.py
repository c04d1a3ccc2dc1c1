"""The camera stage (bgsub.camera.CameraStage): the motion a frame's background model is warped
by, from what the front end measured, and the fit and prior it hands the front end."""

import numpy as np

from bgsub.camera import SMALL_REGION, CameraConfig, CameraStage, KnownMotion
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.result import MotionResult

SHAPE = (100, 200)  # (h, w)
GRAY = np.zeros(SHAPE, np.uint8)


def _shift(dx, dy=0.0):
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _measured(matrix, points, ok=True, reason="ok"):
    pts = np.asarray(points, np.float32)
    motion = GlobalMotion(matrix, np.ones(len(pts), bool), ok, reason)
    return MotionResult(pts, np.zeros_like(pts), np.ones(len(pts), np.float32), motion)


ACROSS = [[0, 50], [100, 50], [199, 50]]  # inliers across the whole width
CORNER = [[10, 10], [20, 15], [25, 20]]  # inliers on a small region


def test_a_good_fit_is_applied_and_becomes_the_next_prior():
    stage = CameraStage(CameraConfig())
    seen = stage.decide(_measured(_shift(3.0), ACROSS), GRAY, None, frozen=False)
    assert seen.status == "ok" and not seen.refused
    np.testing.assert_array_equal(seen.applied, _shift(3.0))
    fit, prior = stage.fit_for((100, 200), SHAPE)
    assert fit is stage.fit
    np.testing.assert_array_equal(prior, _shift(3.0))


def test_a_fit_on_a_small_region_is_refused_and_the_camera_taken_as_still():
    stage = CameraStage(CameraConfig())
    stage.decide(_measured(_shift(3.0), ACROSS), GRAY, None, frozen=False)
    seen = stage.decide(_measured(_shift(6.0), CORNER), GRAY, None, frozen=False)
    assert seen.refused and seen.status == "fallback: " + SMALL_REGION
    np.testing.assert_array_equal(seen.applied, np.eye(3))


def test_a_failed_fit_is_replaced_by_the_last_good_one():
    stage = CameraStage(CameraConfig())
    stage.decide(_measured(_shift(3.0), ACROSS), GRAY, None, frozen=False)
    failed = _measured(np.eye(3), ACROSS, ok=False, reason="too few inliers")
    seen = stage.decide(failed, GRAY, None, frozen=False)
    assert seen.status == "fallback: too few inliers" and not seen.refused
    np.testing.assert_array_equal(seen.applied, _shift(3.0))


def test_small_motion_is_held_back_until_it_adds_up():
    stage = CameraStage(CameraConfig(still_below=0.25))
    first = stage.decide(_measured(_shift(0.15), ACROSS), GRAY, None, frozen=False)
    second = stage.decide(_measured(_shift(0.15), ACROSS), GRAY, None, frozen=False)
    np.testing.assert_array_equal(first.applied, np.eye(3))
    np.testing.assert_allclose(second.applied, _shift(0.3))


def test_a_restart_forgets_the_prior_and_what_was_held_back():
    stage = CameraStage(CameraConfig(still_below=0.25))
    stage.decide(_measured(_shift(0.15), ACROSS), GRAY, None, frozen=False)
    stage.restart(GRAY)
    assert stage.fit_for((100, 200), SHAPE)[1] is None
    seen = stage.decide(_measured(_shift(0.15), ACROSS), GRAY, None, frozen=False)
    np.testing.assert_array_equal(seen.applied, np.eye(3))  # 0.15 px alone: still held back


def test_a_known_motion_is_the_fit_and_the_prior():
    given = np.stack([np.eye(3), _shift(4.0)])
    stage = CameraStage(CameraConfig(), KnownMotion(given))
    for _ in range(2):
        stage.known.next_frame()
    fit, prior = stage.fit_for((100, 200, 3), SHAPE)
    np.testing.assert_allclose(prior, _shift(4.0))
    pts = np.asarray(ACROSS, np.float32)
    motion = fit(pts, np.tile([4.0, 0.0], (3, 1)).astype(np.float32),
                 np.ones(3, np.float32), SHAPE)
    assert motion.ok and motion.inliers.all()
    np.testing.assert_allclose(motion.matrix, _shift(4.0))


def test_without_a_known_motion_every_frame_is_fitted():
    stage = CameraStage(CameraConfig())
    stage.known.next_frame()
    assert stage.known.frames_past_end == 0
    assert stage.fit_for((100, 200), SHAPE) == (stage.fit, None)


def _two_layers(near_share, seed=0):
    """``(points, disp, weights)`` over a 200 x 100 frame: a far layer moving 2 px left and,
    on ``near_share`` of the vectors (a band along the bottom), a near one moving 5 px left;
    0.05 px of noise."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[2:100:4, 2:200:4]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    near = pts[:, 1] >= (1 - near_share) * 100
    disp = np.where(near[:, None], [-5.0, 0.0], [-2.0, 0.0]).astype(np.float32)
    disp += rng.normal(0, 0.05, disp.shape).astype(np.float32)
    return pts, disp, np.ones(len(pts), np.float32), near


def test_in_a_3d_scene_the_fit_keeps_the_plane_it_had():
    # The far layer has the most vectors and wins a plain fit; the last frame's plane was the
    # near band's, whose vectors are nearly as many: held, the fit stays on the band.
    stage = CameraStage(CameraConfig(motion_model="translation"))
    stage.decide(_measured(_shift(-5.0), ACROSS), GRAY, None, frozen=False)
    pts, disp, wt, near = _two_layers(0.45)
    plain = stage.fit(pts, disp, wt, SHAPE)
    np.testing.assert_allclose(plain.matrix[0, 2], -2.0, atol=0.1)
    fit, prior = stage.fit_for((100, 200), SHAPE, hold=0.7)
    held = fit(pts, disp, wt, SHAPE)
    assert held.ok
    np.testing.assert_allclose(held.matrix[0, 2], -5.0, atol=0.1)
    assert held.inliers[near].all() and not held.inliers[~near].any()
    np.testing.assert_array_equal(prior, _shift(-5.0))


def test_a_plane_with_too_few_vectors_is_not_kept():
    stage = CameraStage(CameraConfig(motion_model="translation"))
    stage.decide(_measured(_shift(-5.0), ACROSS), GRAY, None, frozen=False)
    pts, disp, wt, _ = _two_layers(0.3)  # the band's vectors: 0.43 of the far layer's
    held = stage.fit_for((100, 200), SHAPE, hold=0.7)[0](pts, disp, wt, SHAPE)
    np.testing.assert_allclose(held.matrix[0, 2], -2.0, atol=0.1)


def test_without_hold_the_fit_is_the_plain_one():
    stage = CameraStage(CameraConfig())
    stage.decide(_measured(_shift(-5.0), ACROSS), GRAY, None, frozen=False)
    assert stage.fit_for((100, 200), SHAPE)[0] is stage.fit
    assert stage.fit_for((100, 200), SHAPE, hold=0.0)[0] is stage.fit
