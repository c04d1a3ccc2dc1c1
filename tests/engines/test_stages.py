"""The moving-camera engine's parts (the camera stage's rules, bgsub.camera; the foreground
policies, bgsub.background), its second thread (bgsub.engines.threads) and its stage settings
(bgsub.engines.config), each on its own."""

import dataclasses
import pickle
import threading

import cv2
import numpy as np
import pytest

from bgsub.background.compensated import BackgroundConfig
from bgsub.background.fusion import FusionConfig
from bgsub.engines import get_engine_spec
from bgsub.background.compensated import CompensatedBackground
from bgsub.background.exposure import SATURATED, match_exposure, same_exposure
from bgsub.background.foreground import ForegroundConfig
from bgsub.background.persistence import BlobPersistence
from bgsub.background.scene_cut import SceneCut
from bgsub.background.still_switch import NoStillSwitch, StillCameraSwitch
from bgsub.camera import SMALL_REGION, CameraConfig, MotionHoldBack, SmallRegionRule
from bgsub.engines.config import STAGES, EngineConfig, stage_configs
from bgsub.engines.frontend import NO_MOTION, MotionResult
from bgsub.engines.frontends.lucas_kanade import LucasKanadeFrontEnd
from bgsub.engines.moving import MovingCameraEngine
from bgsub.engines.threads import SecondThread
from bgsub.errors import InputError
from bgsub.motion.global_motion import GlobalMotion
from bgsub.settings import config_params


def _shift(dx, dy=0.0):
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _result(points, matrix=None, disp=None, ok=True):
    pts = np.asarray(points, np.float32)
    d = np.zeros_like(pts) if disp is None else np.asarray(disp, np.float32)
    motion = GlobalMotion(np.eye(3) if matrix is None else matrix, np.ones(len(pts), bool), ok)
    return MotionResult(pts, d, np.ones(len(pts), np.float32), motion)


# ------------------------------------------------------------------ small-region rule

def test_a_fit_on_a_small_region_is_refused_and_one_across_the_frame_kept():
    rule = SmallRegionRule(0.33)
    compact = _result([[10, 10], [30, 20], [20, 40]])
    refused, was = rule.check(compact, (100, 200))
    assert was and not refused.motion.ok and refused.motion.reason == SMALL_REGION
    across = _result([[0, 10], [150, 20]])
    kept, was = rule.check(across, (100, 200))
    assert not was and kept is across


def test_the_small_region_rule_at_zero_never_refuses():
    compact = _result([[10, 10], [12, 12]])
    assert SmallRegionRule(0.0).check(compact, (100, 200)) == (compact, False)


# ------------------------------------------------------------------ motion hold-back

def test_small_motions_are_held_back_until_their_total_reaches_the_limit():
    hold = MotionHoldBack(0.25)
    first = hold.release(hold.total(_shift(0.15)), (100, 100))
    np.testing.assert_array_equal(first, np.eye(3))
    second = hold.release(hold.total(_shift(0.15)), (100, 100))
    np.testing.assert_allclose(second, _shift(0.3))
    np.testing.assert_array_equal(hold.unapplied, np.eye(3))


def test_without_a_limit_every_motion_is_applied():
    hold = MotionHoldBack(0.0)
    np.testing.assert_allclose(hold.release(hold.total(_shift(0.01)), (100, 100)), _shift(0.01))


def test_a_reset_forgets_the_held_back_motion():
    hold = MotionHoldBack(0.25)
    hold.release(hold.total(_shift(0.2)), (100, 100))
    hold.reset()
    np.testing.assert_array_equal(hold.total(_shift(0.1)), _shift(0.1))


# ------------------------------------------------------------------ scene cut

def test_a_changed_frame_with_unsupported_motion_is_a_cut():
    cut = SceneCut(0.5, 0.35)
    score = np.full((20, 20), 2.0, np.float32)
    young = np.zeros((20, 20), bool)
    assert cut.is_cut(score, young, _result([[1, 1]] * 10, ok=False))
    assert not cut.is_cut(np.zeros_like(score), young, _result([[1, 1]] * 10, ok=False))


def test_pixels_without_history_never_count_towards_a_scene_cut():
    # After a restart every pixel is young: counted, a young score above 1 would restart the
    # model on every frame.
    cut = SceneCut(0.5, 0.35)
    score = np.full((20, 20), 1.5, np.float32)
    young = np.ones((20, 20), bool)
    young[:2] = False
    score[:2] = 0.0
    assert not cut.is_cut(score, young, _result([[1, 1]] * 10, ok=False))


def test_a_repeated_frame_is_no_new_shot():
    cut = SceneCut(0.5, 0.35)
    score = np.zeros((20, 20), np.float32)
    score[:12] = 2.0  # 60 % differ: a cut unless the motion is supported
    young = np.zeros((20, 20), bool)
    assert not cut.is_cut(score, young, NO_MOTION)
    assert cut.is_cut(score, young, _result(np.zeros((0, 2)), ok=False))


# ------------------------------------------------------------------ still-camera switch

def _textured(seed=0):
    return np.random.default_rng(seed).integers(0, 255, (40, 50), dtype=np.uint8)


def test_the_sample_model_serves_while_no_rigid_motion_stands_out():
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=3)
    frame = _textured()
    switch.reset(frame)
    score = switch.judge(frame, NO_MOTION)  # no fit: nothing stands out
    assert switch.camera_still and score is not None and score.shape == frame.shape


def _compensated(frame, spread=6.0):
    """A compensated model of ``frame`` whose standard deviation is ``spread`` everywhere."""
    model = CompensatedBackground()
    model.reset(frame)
    model.var[...] = spread ** 2
    return model


def _with_rows(frame, rows, value=200):
    """``frame`` with its first ``rows`` rows set to ``value``: what the sample model calls
    new."""
    out = frame.copy()
    out[:rows] = value
    return out


def _judge_rows(compensated_rows, *, spread=6.0, versus=1.5):
    """Whether the switch takes the camera as still when the sample model calls 4 rows of 40
    (10 %) new and the compensated model ``compensated_rows``."""
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=1, still_versus=versus)
    frame = np.full((40, 50), 60, np.uint8)
    switch.reset(frame)
    score = np.zeros(frame.shape, np.float32)
    score[:compensated_rows] = 2.0
    out = switch.judge(_with_rows(frame, 4), NO_MOTION, compensated=_compensated(frame, spread),
                       compensated_score=score)
    assert (out is not None) is switch.camera_still
    return switch.camera_still


@pytest.mark.parametrize("compensated_rows, still", [(2, False), (4, True)])
def test_the_sample_model_is_not_used_where_it_calls_many_times_the_compensated_foreground(
        compensated_rows, still):
    # 10 % against 2 rows (5 %) is beyond still_versus 1.5 (7.5 %, + 0.5 %): not used;
    # against 4 rows it is within: used.
    assert _judge_rows(compensated_rows) is still


def test_a_blind_compensated_model_does_not_veto_the_sample_model():
    # A spread of 40 gray levels (threshold 80 at k_sigma 2: water, flicker) sees nothing;
    # that it calls nothing is no sign that the sample model is wrong.
    assert _judge_rows(0, spread=40.0)
    assert not _judge_rows(0, spread=6.0)


def test_a_young_compensated_model_that_calls_nothing_does_not_veto_the_sample_model():
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=1, still_versus=4.0)
    frame = np.full((40, 50), 60, np.uint8)
    switch.reset(frame)
    one = frame.copy()
    one[0, 0] = 200  # one pixel of 2,000 (0.05 %): within the slack
    nothing = np.zeros(frame.shape, np.float32)
    assert switch.judge(one, NO_MOTION, compensated=_compensated(frame),
                        compensated_score=nothing) is not None


def test_a_rigid_motion_switches_the_sample_model_off():
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=1)
    frame = _textured()
    switch.reset(frame)
    points = np.random.default_rng(1).uniform(0, 40, (50, 2))
    pan = _result(points, matrix=_shift(3.0), disp=np.tile([3.0, 0.0], (50, 1)))
    assert switch.judge(frame, pan) is None and not switch.camera_still


def test_a_frame_the_sample_model_does_not_explain_is_no_still_camera():
    switch = StillCameraSwitch(still_model=0.15, still_snr=4.0, window=1)
    switch.reset(_textured(0))
    assert switch.judge(_textured(1), NO_MOTION) is None and not switch.camera_still


# ------------------------------------------------------------------ the second thread

@pytest.mark.parametrize("overlap", [0, 1])
def test_jobs_are_done_when_the_block_ends(overlap):
    thread = SecondThread(overlap=overlap, name="test")
    seen = []
    with thread.alongside(lambda: seen.append(threading.current_thread().name)):
        pass
    thread.close()
    assert len(seen) == 1
    assert seen[0].startswith("bgsub-test") == (overlap == 1)


def test_a_jobs_error_reaches_the_caller_and_the_thread_pickles():
    thread = SecondThread(overlap=1, name="test")

    def boom():
        raise RuntimeError("job failed")

    with pytest.raises(RuntimeError, match="job failed"):
        with thread.alongside(boom):
            pass
    twin = pickle.loads(pickle.dumps(thread))
    with twin.alongside(lambda: None):
        pass
    twin.close()
    thread.close()


# ------------------------------------------------------------------ stage settings

@pytest.mark.parametrize("config, words", [
    (lambda: EngineConfig(work_width=5), "'work_width' must be 0 .* or at least 32"),
    (lambda: FusionConfig(flow_damp=2.0), "'flow_damp' must be at most 1"),
    (lambda: CameraConfig(motion_model="spline"), "'motion_model' must be one of"),
    (lambda: BackgroundConfig(envelope=1.5), "'envelope' takes an integer"),
])
def test_a_stage_setting_out_of_range_is_refused(config, words):
    with pytest.raises(InputError, match=words):
        config()


def test_stage_settings_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        FusionConfig().threshold = 2.0


@pytest.mark.parametrize("name, overrides", [("grbm", {}),
                                             ("compensated", LucasKanadeFrontEnd.stage_defaults)])
def test_the_engines_parameters_are_the_stage_settings(name, overrides):
    params = get_engine_spec(name).params
    for stage in STAGES:
        for key, param in config_params(stage).items():
            expected = dataclasses.replace(param, default=overrides.get(key, param.default))
            assert params[key] == expected, (name, key)


def test_stage_configs_take_values_then_a_front_ends_defaults():
    stages = stage_configs({"threshold": 2.0, "unrelated": 1}, {"flow_boost": 1.5})
    assert stages[FusionConfig] == FusionConfig(threshold=2.0, flow_boost=1.5)
    assert stages[EngineConfig] == EngineConfig()


def test_the_foreground_policies_are_built_from_their_stage_settings():
    eng = MovingCameraEngine(LucasKanadeFrontEnd(), foreground=ForegroundConfig(
        match_exposure=False, scene_cut=0.3, cut_support=0.2, still_model=0))
    policies = eng.foreground
    assert policies.exposure is same_exposure
    assert (policies.scene_cut.scene_cut, policies.scene_cut.cut_support) == (0.3, 0.2)
    assert isinstance(policies.still_switch, NoStillSwitch)


def test_the_still_camera_switch_takes_its_stage_settings():
    switch = MovingCameraEngine(LucasKanadeFrontEnd(), foreground=ForegroundConfig(
        still_snr=2.5, still_versus=1.5, still_window=4)).still_switch
    assert (switch.still_snr, switch.still_versus, switch.window) == (2.5, 1.5, 4)


def test_the_still_camera_models_radius_per_pixel_takes_its_stage_settings():
    model = MovingCameraEngine(LucasKanadeFrontEnd(), foreground=ForegroundConfig(
        still_radius=7, still_spread=2)).still_switch.model
    assert (model.radius_min, model.radius_gain, model.radius) == (7, 2, 20)
    flat = MovingCameraEngine(LucasKanadeFrontEnd(), foreground=ForegroundConfig(
        still_spread=0)).still_switch.model
    assert flat.radius_min == flat.radius == 20  # one radius for every pixel


def _square_at(x, shape=(50, 60)):
    mask = np.zeros(shape, np.uint8)
    mask[20:30, x:x + 10] = 255
    return mask


def test_blob_persistence_keeps_the_first_mask_and_what_stays():
    part = BlobPersistence(3)
    first = _square_at(5)
    assert np.array_equal(part.filter(first, np.eye(3)), first)  # nothing to overlap yet
    assert np.array_equal(part.filter(_square_at(7), np.eye(3)), _square_at(7))
    assert not part.filter(_square_at(40), np.eye(3)).any()  # far from the last mask: new
    part.reset()
    assert np.array_equal(part.filter(_square_at(40), np.eye(3)), _square_at(40))


def test_blob_persistence_keeps_the_first_mask_with_foreground_after_empty_ones():
    part = BlobPersistence(3)
    empty = np.zeros((50, 60), np.uint8)
    assert not part.filter(empty, np.eye(3)).any()  # a young model that found nothing yet
    assert np.array_equal(part.filter(_square_at(40), np.eye(3)), _square_at(40))
    assert not part.filter(empty, np.eye(3)).any()
    assert not part.filter(_square_at(5), np.eye(3)).any()  # after a find, a new blob waits


def test_blob_persistence_radius_0_changes_nothing():
    part = BlobPersistence(0)
    part.filter(_square_at(5), np.eye(3))
    assert np.array_equal(part.filter(_square_at(40), np.eye(3)), _square_at(40))


def test_blob_persistence_is_not_changed_by_the_caller_drawing_on_a_mask():
    part = BlobPersistence(3)
    returned = part.filter(_square_at(5), np.eye(3))
    returned[:] = 0  # the caller's array, as apply() returns it at the working size
    assert np.array_equal(part.filter(_square_at(7), np.eye(3)), _square_at(7))


def test_a_frame_brought_to_the_models_exposure_keeps_the_model_where_it_was_clipped():
    rng = np.random.default_rng(0)
    scene = rng.integers(60, 120, (60, 80, 3)).astype(np.uint8)
    scene[:, 40:] = 230  # a bright wall, clipped once the exposure rises by a fifth
    model = CompensatedBackground()
    model.update(scene)
    brighter = cv2.convertScaleAbs(scene, alpha=1.2)
    assert (brighter[:, 40:] >= SATURATED).all()
    exposed, gain = match_exposure(brighter, model)
    assert gain == pytest.approx(1.2, abs=0.01)
    assert np.abs(exposed[:, :40].astype(int) - scene[:, :40]).max() <= 1
    assert (exposed[:, 40:] == 230).all()  # not 255 / 1.2 = 212: the wall is at least that bright


def test_a_frame_at_the_models_exposure_is_left_as_it_came():
    scene = np.random.default_rng(1).integers(30, 200, (60, 80, 3)).astype(np.uint8)
    model = CompensatedBackground()
    model.update(scene)
    exposed, gain = match_exposure(scene, model)
    assert exposed is scene and gain == 1.0
