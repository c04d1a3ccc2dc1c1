"""The still-camera switch: bgsub.background.still_switch.motion_snr and the engines' choice
between the compensated and the sample background model (bgsub.background.sample)."""

import cv2
import numpy as np
import pytest

from bgsub.engines import create_engine
from bgsub.motion.global_motion import GlobalMotion
from bgsub.engines.frontend import MotionResult
from bgsub.background.still_switch import motion_snr
from bgsub.samples import SceneSpec, render_frames
from helpers import model_path as _model_path


# ------------------------------------------------------------------ motion_snr


def _result(disp, ok=True, matrix=None, weights=None):
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 200, (len(disp), 2)).astype(np.float32)
    m = np.eye(3) if matrix is None else matrix
    motion = GlobalMotion(m, np.ones(len(disp), bool), ok)
    weights = np.ones(len(disp)) if weights is None else weights
    return MotionResult(pts, np.asarray(disp, np.float32), np.asarray(weights, np.float32), motion)


def test_a_rigid_pan_stands_out_of_its_vectors_noise():
    rng = np.random.default_rng(1)
    disp = np.array([3.0, 0.0]) + rng.normal(0, 0.1, (60, 2))
    pan = np.array([[1, 0, 3.0], [0, 1, 0], [0, 0, 1]])
    assert motion_snr(_result(disp, matrix=pan)) > 20


def test_a_drift_scattered_like_waves_does_not():
    rng = np.random.default_rng(2)
    disp = np.array([2.0, 0.0]) + rng.normal(0, 1.5, (60, 2))
    drift = np.array([[1, 0, 2.0], [0, 1, 0], [0, 0, 1]])
    assert motion_snr(_result(disp, matrix=drift)) < 2


def test_a_pan_over_a_plain_sky_stands_out_of_its_reliable_vectors_noise():
    # (the sky's patches read noise at a fiftieth of the weight of the textured ones)
    rng = np.random.default_rng(3)
    disp = np.array([2.0, 0.0]) + rng.normal(0, 0.1, (60, 2))
    disp[:40] = rng.normal(0, 1.5, (40, 2))
    weights = np.r_[np.full(40, 0.02), np.full(20, 0.8)]
    pan = np.array([[1, 0, 2.0], [0, 1, 0], [0, 0, 1]])
    assert motion_snr(_result(disp, matrix=pan, weights=weights)) > 4
    assert motion_snr(_result(disp, matrix=pan)) < 2  # (every vector counted alike)


def test_no_fit_or_too_few_vectors_has_no_motion_to_stand_out():
    assert motion_snr(_result(np.ones((60, 2)), ok=False)) == 0.0
    assert motion_snr(_result(np.ones((5, 2)))) == 0.0


# ------------------------------------------------------------------ the engines' switch


def _engine(method, **kw):
    if method == "grbm":
        kw["model"] = _model_path()
    return create_engine(method, **kw)


def _still_frames(category, seed=0, n=24):
    eng = _engine("grbm")
    still = []
    for img, _, _ in render_frames(SceneSpec(category, seed=seed, n_frames=n)):
        eng.apply(img)
        still.append(eng.camera_still)
    return still


def test_a_tripod_camera_is_taken_as_still():
    still = _still_frames("static")
    assert all(still[3:])


@pytest.mark.parametrize("category", ["pan", "jitter"])
def test_a_panning_or_shaking_camera_is_not(category):
    # A shaking camera's small motion is rigid: the sample model alone would explain most of
    # the frame, the motion's signal-to-noise ratio tells it is a camera's.
    assert not any(_still_frames(category))


def _flicker(n=40, h=120, w=160, seed=0):
    """A still camera; in a region, pixels flip between gray 60 and 180 (leaves, glints); an
    object of the middle gray (120) crosses it."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 4, w // 4)).astype(np.uint8)
    world = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC).astype(np.float32)
    phase = rng.random((h, w)) < 0.5
    for k in range(n):
        f = world.copy()
        on = phase ^ (rng.random((h, w)) < 0.5)
        f[20:100, 40:140] = np.where(on[20:100, 40:140], 60, 180)
        f += rng.normal(0, 2, f.shape)
        gt = np.zeros((h, w), np.uint8)
        f[45:75, 50 + k:80 + k] = 120
        gt[45:75, 50 + k:80 + k] = 255
        yield cv2.cvtColor(np.clip(f, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR), gt


def _f_on_flicker(method, still_model):
    eng = _engine(method, still_model=still_model)
    tp = fp = fn = 0
    for k, (img, gt) in enumerate(_flicker()):
        pred, truth = eng.apply(img) > 127, gt > 0
        if k >= 12:
            tp += np.count_nonzero(pred & truth)
            fp += np.count_nonzero(pred & ~truth)
            fn += np.count_nonzero(~pred & truth)
    return 2 * tp / max(2 * tp + fp + fn, 1), eng


@pytest.mark.parametrize("method", ["grbm", "compensated"])
def test_a_multimodal_background_needs_the_sample_model(method):
    # A mean and a variance put the object's gray inside the flicker's spread; two samples
    # of 60 and 180 do not (F: grbm 0.36, compensated 0.65; without: 0.00 both).
    with_samples, eng = _f_on_flicker(method, 0.15)
    without, plain = _f_on_flicker(method, 0.0)
    assert eng.camera_still and not plain.camera_still and not plain.still_switch.camera_still
    assert with_samples > 0.25 and without < 0.05


def test_the_background_image_is_the_still_models_while_the_camera_is_still():
    eng = _engine("compensated")
    for img, _ in _flicker(n=14):
        eng.apply(img)
    assert eng.camera_still
    assert np.array_equal(eng.get_background_image(),
                          eng.still_switch.model.background_image())


# ------------------------------------------------------------------ a steady fit is a pan

def _switch_after(steps, **kw):
    """The still-camera switch after frames of one unchanging image whose vectors scatter like
    water (no rigid motion stands out) while the fit moves the frame by each of ``steps``."""
    from bgsub.background.still_switch import StillCameraSwitch
    frame = np.full((60, 80, 3), 120, np.uint8)
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=9, **kw)
    switch.reset(frame)
    rng = np.random.default_rng(3)
    for dx, dy in steps:
        fit = np.array([[1, 0, dx], [0, 1, dy], [0, 0, 1]], float)
        disp = np.array([dx, dy]) + rng.normal(0, 1.5, (60, 2))
        switch.judge(frame, _result(disp, matrix=fit))
    return switch


def test_a_fit_that_keeps_one_step_is_a_pan_however_the_vectors_scatter():
    rng = np.random.default_rng(4)
    steps = np.array([1.2, 0.2]) * (1 + rng.normal(0, 0.01, (12, 1)))
    assert not _switch_after(steps, steady=0.04).camera_still
    assert _switch_after(steps, steady=0.0).camera_still  # (the test off)


def test_a_flow_that_varies_from_frame_to_frame_is_no_pan():
    rng = np.random.default_rng(5)
    steps = np.array([2.3, -0.5]) * (1 + rng.normal(0, 0.25, (12, 1)))
    assert _switch_after(steps, steady=0.04).camera_still


def test_a_steady_step_under_half_a_pixel_is_not_judged():
    assert _switch_after([(0.3, 0.0)] * 12, steady=0.04).camera_still


def test_with_still_pause_the_still_model_learns_nothing_while_the_camera_moves_rigidly():
    from bgsub.background.still_switch import StillCameraSwitch
    rng = np.random.default_rng(6)
    first, second = (rng.integers(0, 256, (60, 80, 3), dtype=np.uint8) for _ in range(2))
    pan = np.array([[1, 0, 3.0], [0, 1, 0], [0, 0, 1]])
    rigid = _result(np.array([3.0, 0.0]) + rng.normal(0, 0.1, (60, 2)), matrix=pan)
    still = _result(rng.normal(0, 1.5, (60, 2)))
    learnt = []
    for result, pause in ((rigid, True), (still, True), (rigid, False)):
        switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=1, pause=pause)
        switch.reset(first)
        switch.judge(second, result)
        before = switch.model.s.copy()
        for _ in range(4):
            switch.update(second, None, 0.5)  # (half the pixels renew a sample each time)
        learnt.append(not np.array_equal(before, switch.model.s))
    assert learnt == [False, True, True]  # (paused only while moving; no pause: learnt)
