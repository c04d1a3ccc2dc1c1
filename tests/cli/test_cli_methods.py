"""``bgsub methods``: the common parameters by default, every one with --all; and the one-line
"did you mean" for a mistyped engine or parameter name."""

from __future__ import annotations

import json

import pytest

from bgsub.cli import main
from bgsub.engines import Param, available_engines, get_engine_spec, register_engine
from bgsub.engines.config import STAGES
from bgsub.samples import bundled_sample


def _listed(out):
    return [line.split()[0].split("=")[0] for line in out.splitlines()
            if line.startswith("    ") and line[4] != " " and "=" in line.split()[0]]


@pytest.mark.parametrize("spec", available_engines(), ids=lambda spec: spec.name)
def test_each_builtin_engine_marks_a_few_parameters_common(spec):
    common = [name for name in spec.params if spec.is_common(name)]
    assert 3 <= len(common) <= 8 or len(spec.params) <= 8


def test_methods_name_lists_only_the_common_parameters(capsys):
    assert main(["methods", "grbm"]) == 0
    out = capsys.readouterr().out
    spec = get_engine_spec("grbm")
    assert set(_listed(out)) == set(spec.common)
    assert "`bgsub methods grbm --all` shows all of them" in out


def test_methods_all_lists_every_parameter_under_its_stage(capsys):
    assert main(["methods", "grbm", "--all"]) == 0
    out = capsys.readouterr().out
    assert _listed(out) == list(get_engine_spec("grbm").params)
    headings = [line.strip() for line in out.splitlines() if line.startswith("  ") and
                not line.startswith("    ") and not line.startswith("  presets")]
    assert headings[0] == "motion front end (grbm):" and headings[-1] == "inputs:"
    assert len(headings) == len(STAGES) + 2
    lines = out.splitlines()
    # a stage's setting is listed under that stage's heading
    assert lines.index("  camera motion (RANSAC fit):") < next(
        i for i, line in enumerate(lines) if line.startswith("    ransac_threshold="))


def test_methods_json_marks_common_and_stage(capsys):
    assert main(["methods", "grbm", "--json"]) == 0
    params = json.loads(capsys.readouterr().out)[0]["params"]
    assert params["stride"]["common"] and not params["coarse_iterations"]["common"]
    assert params["alpha"]["stage"] == "background model"


def test_an_engine_registered_without_common_shows_every_parameter(capsys, own_engines):
    register_engine("_test_plain", "test: no common list",
                    params={"a": Param(1, "one"), "b": Param(2, "two")})(lambda **kw: None)
    assert main(["methods", "_test_plain"]) == 0
    out = capsys.readouterr().out
    assert _listed(out) == ["a", "b", "roi"] and "--all" not in out


def test_common_names_must_be_parameters(own_engines):
    with pytest.raises(ValueError, match="nope"):
        register_engine("_test_bad_common", "test", params={"a": Param(1, "one")},
                        common=("nope",))(lambda **kw: None)


def test_a_mistyped_parameter_gets_one_suggestion(bgsub_error, tmp_path):
    err = bgsub_error(["run", bundled_sample(), "-o", tmp_path / "m.mkv", "--param", "strid=3"])
    assert err.strip() == ("bgsub: error: unknown parameter 'strid' for grbm; did you mean 'stride'? "
                   "(bgsub methods grbm --all lists them)")


def test_a_parameter_like_no_other_gets_no_suggestion():
    message = get_engine_spec("mog2").unknown_param("zzzz")
    assert "did you mean" not in message and "bgsub methods mog2 --all" in message


def test_a_mistyped_method_gets_a_suggestion(bgsub_error, tmp_path):
    err = bgsub_error(["run", bundled_sample(), "-o", tmp_path / "m.mkv", "-m", "grbn"])
    assert "unknown method 'grbn'; did you mean 'grbm'?" in err


@pytest.mark.parametrize("spec", available_engines(), ids=lambda spec: spec.name)
def test_common_parameters_help_texts_stand_alone(spec):
    # `bgsub methods NAME` shows them without the parameter listed above them in --all
    for name in spec.params:
        if spec.is_common(name):
            assert not spec.params[name].help.startswith("..."), name


def test_the_engine_stage_settings_help_texts_stand_alone():
    from bgsub.engines.config import CameraConfig, EngineConfig, ForegroundConfig
    from bgsub.settings import config_params

    for stage in (EngineConfig, CameraConfig, ForegroundConfig):
        for name, param in config_params(stage).items():
            assert not param.help.startswith("..."), name
