"""One spelling per concept across run, compare, bench, eval and samples; the old spellings
still work for one release, with one warning line."""

from __future__ import annotations

import pytest

from bgsub.cli import build_parser, main
from bgsub.cli.compare import parse_method_params
from bgsub.errors import InputError


def _parse(argv):
    return build_parser().parse_args(argv)


@pytest.mark.parametrize("argv, dest, value, old", [
    (["compare", "in", "-o", "out", "--masks", "mkv"], "mask_format", "mkv", "--masks"),
    (["bench", "--frames", "7"], "max_frames", 7, "--frames"),
    (["samples", "--frames", "7"], "max_frames", 7, "--frames"),
    (["samples", "-n", "7"], "max_frames", 7, "-n"),
])
def test_an_old_spelling_sets_the_new_option_and_warns_once(capsys, argv, dest, value, old):
    args = _parse(argv)
    assert getattr(args, dest) == value
    new = "--mask-format" if dest == "mask_format" else "--max-frames"
    assert capsys.readouterr().err == f"bgsub: warning: {old} is deprecated; use {new}\n"


@pytest.mark.parametrize("argv, dest, value", [
    (["compare", "in", "-o", "out", "--mask-format", "none"], "mask_format", "none"),
    (["bench", "--max-frames", "7"], "max_frames", 7),
    (["samples", "--max-frames", "7"], "max_frames", 7),
    (["compare", "in", "-o", "out", "--max-frames", "7"], "max_frames", 7),
    (["run", "in", "-o", "out", "--max-frames", "7"], "max_frames", 7),
    (["run", "in", "-o", "out", "--mask-format", "png"], "mask_format", "png"),
])
def test_the_new_spellings_parse_without_a_warning(capsys, argv, dest, value):
    assert getattr(_parse(argv), dest) == value
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("command", ["run", "compare", "bench", "samples"])
def test_old_spellings_are_hidden_from_the_help(capsys, command):
    with pytest.raises(SystemExit):
        _parse([command, "--help"])
    text = capsys.readouterr().out
    assert "--masks " not in text and "--frames " not in text and "-n N" not in text


@pytest.mark.parametrize("argv", [["run", "in", "-o", "out"], ["compare", "in", "-o", "out"],
                                  ["eval", "pred", "gt"]])
def test_jobs_defaults_to_one_in_every_command(argv):
    assert _parse(argv).jobs == 1


def test_a_key_without_method_goes_to_every_method_that_has_it():
    params = parse_method_params(["history=30", "knn.dist2_threshold=300"], ["mog2", "knn",
                                                                             "framediff"])
    assert params == {"mog2": {"history": 30}, "knn": {"history": 30, "dist2_threshold": 300.0}}


def test_a_key_no_method_has_is_refused():
    with pytest.raises(InputError, match="none of the methods .* has a parameter 'histry'; "
                                         "did you mean 'history'"):
        parse_method_params(["histry=30"], ["mog2", "knn"])


def test_run_takes_its_own_method_s_prefix(tmp_path, capsys):
    from helpers import write_box_clip

    clip = write_box_clip(tmp_path / "c.mkv", n=3)
    assert main(["run", str(clip), "-o", str(tmp_path / "m"), "-m", "mog2",
                 "-p", "mog2.history=20", "--json", "-q"]) == 0
    assert main(["run", str(clip), "-o", str(tmp_path / "n"), "-m", "mog2",
                 "-p", "knn.history=20"]) == 2
    assert "method 'knn' is not among the methods (mog2)" in capsys.readouterr().err


def test_bench_takes_a_plain_key_for_several_methods(capsys):
    assert main(["bench", "-m", "mog2,framediff", "--size", "32x24", "--max-frames", "2",
                 "--repeats", "1", "-p", "history=20", "-q"]) == 0
    assert "deprecated" not in capsys.readouterr().err


def test_jobs_below_zero_is_refused(tmp_path, bgsub_error):
    assert "--jobs takes" in bgsub_error(["compare", str(tmp_path), "-o", str(tmp_path / "o"),
                                          "--jobs", "-1"])
