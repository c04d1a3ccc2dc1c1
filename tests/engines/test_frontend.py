"""The motion front-end interface: a front end of one's own (OpenCV's DIS optical flow) is one
small class and a registration, and runs end to end as a registered engine."""

from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from bgsub.engines import available_engines, create_engine, get_engine_spec, parse_params
from bgsub.engines.frontend import MotionFrontEnd, MotionResult
from bgsub.engines.moving import MovingCameraEngine, register_frontend
from bgsub.samples import SceneSpec, render_frames
from bgsub.settings import check_settings, setting


@dataclass(frozen=True)
class DISConfig:
    step: int = setting(8, "grid step (px) of the flow vectors handed to RANSAC", low=1)

    def __post_init__(self) -> None:
        check_settings(self)


class DISFrontEnd(MotionFrontEnd):
    """OpenCV's dense inverse-search optical flow, sampled on a grid."""

    name = "test-dis"
    description = "moving camera: OpenCV's DIS optical flow + RANSAC camera motion"
    config_type = DISConfig
    stage_defaults = {"flow_damp": 0.5}

    def __init__(self, config=None):
        super().__init__(config)
        self.dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)

    def measure(self, prev, cur, *, prior, fit):
        flow = self.dis.calc(prev, cur, None)
        s = self.config.step
        ys, xs = np.mgrid[s // 2:prev.shape[0]:s, s // 2:prev.shape[1]:s]
        points = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
        disp = flow[ys.ravel(), xs.ravel()]
        weights = np.ones(len(points), np.float32)
        return MotionResult(points, disp, weights, fit(points, disp, weights, cur.shape))


@pytest.fixture(scope="module")
def dis():
    register_frontend(DISFrontEnd)
    return DISFrontEnd.name


def test_a_registered_front_end_is_an_engine_with_generated_parameters(dis):
    spec = get_engine_spec(dis)
    assert spec.params["step"].default == 8 and spec.params["step"].low == 1
    # Every stage setting, with the front end's override of a default.
    assert spec.params["flow_damp"].default == 0.5
    assert spec.params["work_width"].default == get_engine_spec("compensated").params[
        "work_width"].default
    assert parse_params(dis, ["step=4"]) == {"step": 4}
    engine = create_engine(dis, step=4, min_area=10)
    assert isinstance(engine, MovingCameraEngine) and isinstance(engine.frontend, DISFrontEnd)
    assert engine.frontend.config.step == 4 and engine.fusion.config.min_area == 10
    assert engine.fusion.config.flow_damp == 0.5


def test_a_registered_front_end_finds_the_objects_of_a_panning_scene(dis):
    engine = create_engine(dis)
    tp = fp = fn = 0
    statuses = []
    spec = SceneSpec("pan", seed=0, n_frames=30)
    for k, (image, gt, _) in enumerate(render_frames(spec)):
        mask = engine.apply(image) > 0
        statuses.append(engine.last_status)
        if k >= spec.warmup_frames:  # the objects enter after the warm-up
            truth, known = gt == 255, gt != 170
            tp += np.count_nonzero(mask & truth)
            fp += np.count_nonzero(mask & ~truth & known)
            fn += np.count_nonzero(~mask & truth)
    assert statuses.count("ok") >= 25, statuses
    f = 2 * tp / max(2 * tp + fp + fn, 1)
    assert f > 0.9, f


def test_a_front_end_must_measure():
    class Incomplete(MotionFrontEnd):
        name = "incomplete"

    with pytest.raises(TypeError):
        Incomplete()


def test_the_built_in_front_ends_are_registered_engines():
    names = {spec.name for spec in available_engines()}
    assert {"grbm", "compensated"} <= names
