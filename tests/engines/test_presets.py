"""Named presets of the moving-camera engines: what each sets, that explicit parameters win
over them, and the one-line refusal of a preset an engine does not have."""

from __future__ import annotations

import pytest

from bgsub.engines import create_engine, get_engine_spec, register_engine
from bgsub.engines.frontend import MotionFrontEnd
from bgsub.errors import InputError

MOVING = ("grbm", "compensated")


@pytest.mark.parametrize("method", MOVING)
def test_each_moving_engine_has_the_three_presets_of_its_front_end(method):
    presets = get_engine_spec(method).presets
    assert list(presets) == ["fast", "balanced", "accurate"]
    assert presets == MotionFrontEnd.presets


@pytest.mark.parametrize("method", MOVING)
def test_balanced_is_the_defaults(method):
    assert get_engine_spec(method).presets["balanced"] == {}
    assert create_engine(method, preset="balanced").config == create_engine(method).config


@pytest.mark.parametrize("method", MOVING)
@pytest.mark.parametrize("preset, width, radius", [("fast", 160, 0), ("accurate", 480, 8)])
def test_a_preset_builds_the_engine_with_its_values(method, preset, width, radius):
    engine = create_engine(method, preset=preset)
    assert (engine.config.work_width, engine.config.edge_radius) == (width, radius)


def test_an_explicit_parameter_wins_over_the_preset():
    engine = create_engine("grbm", preset="fast", work_width=200)
    assert engine.config.work_width == 200
    assert engine.config.edge_radius == 0  # the preset's other value stays


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
