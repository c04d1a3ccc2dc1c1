"""The ``bgsub`` command line before the sub-command: options there are bgsub's own only
(``--help``, ``--version``); any other is named as such, in one line with exit status 2."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from bgsub.cli import main


def _usage_error(argv, capsys) -> str:
    """Run ``bgsub argv``, check that it stopped with exit status 2 and one line on stderr."""
    with pytest.raises(SystemExit) as stop:
        main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert stop.value.code == 2, err
    assert err.count("\n") == 1, err
    return err


@pytest.mark.parametrize("argv, option", [
    (["--bogus", "run", "in.mp4", "-o", "out"], "--bogus"),
    (["--bogus=3", "run", "in.mp4", "-o", "out"], "--bogus"),
    (["-z", "flow", "a.png", "b.png", "-o", "f.flo"], "-z"),
    (["--version", "--bogus", "methods"], "--bogus"),
    (["--bogus"], "--bogus"),
    (["--bogus", "nosuch"], "--bogus"),
])
def test_an_unknown_option_before_the_command_is_not_a_bgsub_option(argv, option, capsys):
    err = _usage_error(argv, capsys)
    assert err == f"bgsub: error: {option} is not a bgsub option (see `bgsub --help`)\n"


@pytest.mark.parametrize("argv, option, command", [
    (["--quiet", "run", "in.mp4", "-o", "out"], "--quiet", "run"),
    (["-q", "run", "in.mp4", "-o", "out"], "-q", "run"),
    (["--overwrite", "flow", "a.png", "b.png", "-o", "f.flo"], "--overwrite", "flow"),
    # An option's value must not be taken for the command (argparse: "invalid choice: 'natural'").
    (["--model", "natural", "flow", "a.png", "b.png", "-o", "f.flo"], "--model", "flow"),
    (["--max-motion=30", "flow", "a.png", "b.png", "-o", "f.flo"], "--max-motion", "flow"),
    (["--over", "flow", "a.png", "b.png", "-o", "f.flo"], "--over", "flow"),  # abbreviated
])
def test_a_command_option_before_its_command_says_to_put_it_after(argv, option, command,
                                                                   capsys):
    err = _usage_error(argv, capsys)
    assert err == (f"bgsub: error: {option} is an option of `bgsub {command}`, not of bgsub: "
                   f"put it after `{command}` (see `bgsub {command} --help`)\n")


def test_an_option_of_another_command_is_not_a_bgsub_option(capsys):
    # --vis is an option of `bgsub run`, not of `bgsub methods`: putting it after would not help.
    err = _usage_error(["--vis", "v.mp4", "methods"], capsys)
    assert err == "bgsub: error: --vis is not a bgsub option (see `bgsub --help`)\n"


@pytest.mark.parametrize("argv, words", [
    # After the command an unknown option is still that command's to name.
    (["run", "in.mp4", "-o", "out", "--bogus"],
     "unrecognized arguments: --bogus (see `bgsub run --help`)"),
    # An unknown command first is named as the command (its options are not looked at).
    (["nosuch", "--bogus"], "argument COMMAND: invalid choice: 'nosuch'"),
])
def test_errors_after_the_command_are_unchanged(argv, words, capsys):
    assert _usage_error(argv, capsys).startswith(f"bgsub: error: {words}")


@pytest.mark.parametrize("argv", [["--version", "methods"], ["--vers", "methods"]])
def test_bgsub_options_before_the_command_still_work(argv, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 0
    assert capsys.readouterr().out.startswith("bgsub ")


def test_subprocess_misplaced_option_is_one_line_exit_2():
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-m", "bgsub", "--bogus", "run", "x", "-o", "y"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr == "bgsub: error: --bogus is not a bgsub option (see `bgsub --help`)\n"
