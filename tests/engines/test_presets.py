"""Named presets of the moving-camera engines: what each sets, that explicit parameters win
over them, and the one-line refusal of a preset an engine does not have."""

from __future__ import annotations

import pytest

from bgsub.engines import create_engine, get_engine_spec, register_engine
from bgsub.engines.frontend import MotionFrontEnd
from bgsub.engines.frontends.grbm import GrbmFrontEnd
from bgsub.engines.frontends.lucas_kanade import LucasKanadeFrontEnd
from bgsub.errors import InputError

MOVING = ("grbm", "compensated")
FRONT_ENDS = {"grbm": GrbmFrontEnd, "compensated": LucasKanadeFrontEnd}


@pytest.mark.parametrize("method", MOVING)
def test_each_moving_engine_has_the_three_presets_of_its_front_end(method):
    presets = get_engine_spec(method).presets
    assert list(presets) == ["fast", "balanced", "accurate"]
    assert presets == FRONT_ENDS[method].presets


def test_the_gated_rbm_has_fast_and_accurate_presets_of_its_own():
    assert GrbmFrontEnd.presets["fast"] == {"work_width": 160, "stride": 16, "overlay": 0,
                                            "edge_radius": 4, "ransac_threshold": 0.5,
                                            "violation_threshold": 0.375, "overlap": 0,
                                            "still_pause": 1, "flow_boost": 1.0,
                                            "grow_above": 0.8, "lookback": 45}
    assert GrbmFrontEnd.presets["accurate"] == {"edge_step": 1, "colour_cut": 9}
    assert GrbmFrontEnd.presets["balanced"] == MotionFrontEnd.presets["balanced"]
    assert LucasKanadeFrontEnd.presets == MotionFrontEnd.presets


@pytest.mark.parametrize("method", MOVING)
def test_balanced_is_the_defaults(method):
    assert get_engine_spec(method).presets["balanced"] == {}
    assert create_engine(method, preset="balanced").config == create_engine(method).config


@pytest.mark.parametrize("method, preset, width, radius, step, cut", [
    ("grbm", "fast", 160, 4, 2, 0), ("compensated", "fast", 160, 0, 2, 0),
    ("grbm", "accurate", 320, 8, 1, 9), ("compensated", "accurate", 480, 8, 2, 0)])
def test_a_preset_builds_the_engine_with_its_values(method, preset, width, radius, step, cut):
    config = create_engine(method, preset=preset).config
    assert (config.work_width, config.edge_radius, config.edge_step,
            config.colour_cut) == (width, radius, step, cut)


def test_the_gated_rbm_fast_preset_reaches_its_stages():
    engine = create_engine("grbm", preset="fast")
    assert engine.frontend.flow.stride == 16
    assert engine.overlays.config.overlay == 0
    assert engine.camera.config.ransac_threshold == 0.5
    assert engine.fusion.config.violation_threshold == 0.375
    assert engine.fusion.config.flow_boost == 1.0
    assert engine.foreground.object_colours.above == 0.8
    assert engine.lookback == 45
    assert engine.still_switch.pause and not create_engine("grbm").still_switch.pause


def test_an_explicit_parameter_wins_over_the_preset():
    engine = create_engine("grbm", preset="fast", work_width=200)
    assert engine.config.work_width == 200
    assert engine.config.edge_radius == 4  # the preset's other values stay
    assert engine.frontend.flow.stride == 16


def test_an_unknown_preset_is_one_line_naming_the_presets():
    with pytest.raises(InputError) as err:
        create_engine("grbm", preset="fsat")
    message = str(err.value)
    assert "\n" not in message
    assert "did you mean 'fast'?" in message and "fast, balanced, accurate" in message


def test_a_preset_for_an_engine_without_presets_is_refused():
    with pytest.raises(InputError, match="'mog2' has no presets .*grbm"):
        create_engine("mog2", preset="fast")


def test_a_preset_naming_no_parameter_is_refused_at_registration(own_engines):
    with pytest.raises(ValueError, match="preset 'fast' sets no parameter 'speed'"):
        register_engine("presetted", "test engine", {}, presets={"fast": {"speed": 2}})(
            lambda **_: None)
