"""bgsub.motion.FlowConfig: the reader's settings with their defaults, bounds and meaning."""

import dataclasses

import pytest

from bgsub.errors import InputError
from bgsub.motion import FlowConfig
from bgsub.camera import CameraConfig
from bgsub.settings import config_params


@pytest.mark.parametrize("change, words", [
    (dict(stride=0), "FlowConfig: parameter 'stride' must be at least 1, not 0"),
    (dict(levels=-1), "parameter 'levels' must be at least 0"),
    (dict(max_motion=0.0), "parameter 'max_motion' must be greater than 0"),
    (dict(max_motion=float("nan")), "parameter 'max_motion' must be a finite number"),
    (dict(min_texture=1.5), "parameter 'min_texture' must be at most 1"),
    (dict(search=9), "parameter 'search' must be at most 8"),
    (dict(stride=6.5), "parameter 'stride' takes an integer"),
    (dict(coarse_model="spline"), "parameter 'coarse_model' must be one of homography"),
    (dict(dense="yes"), "parameter 'dense' takes yes/no"),
])
def test_out_of_range_settings_are_refused(change, words):
    with pytest.raises(InputError, match=words.replace("(", r"\(")):
        FlowConfig(**change)


def test_replace_checks_the_new_values_too():
    with pytest.raises(InputError, match="'texture_scale' must be greater than 0"):
        dataclasses.replace(FlowConfig(), texture_scale=0.0)


def test_every_field_is_a_setting_with_its_default_and_meaning():
    params = config_params(FlowConfig)
    config = FlowConfig()
    assert list(params) == [f.name for f in dataclasses.fields(FlowConfig)]
    for name, param in params.items():
        assert param.default == getattr(config, name) and param.help, name


def test_config_params_picks_names_in_order_and_replaces_defaults():
    params = config_params(FlowConfig, ["search", "stride"], stride=6)
    assert list(params) == ["search", "stride"]
    assert params["stride"].default == 6 and params["stride"].low == 1
    assert params["search"].high == 8


def test_camera_config_is_checked():
    assert CameraConfig().motion_model == "auto"
    with pytest.raises(InputError, match="CameraConfig: parameter 'ransac_threshold'"):
        CameraConfig(ransac_threshold=0.0)
