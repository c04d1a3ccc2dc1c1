"""Every command's ``--help``: short enough to read on a screen, and examples that parse."""

from __future__ import annotations

import pytest

from bgsub.cli import reference

PARSERS = reference.parsers()


def _actions(parser):
    return [a for a in parser._actions if a.help and a.help != "==SUPPRESS=="]


def test_run_help_fits_on_a_screen():
    lines = reference.help_text(PARSERS["run"], width=80).splitlines()
    assert len(lines) <= 60, len(lines)


@pytest.mark.parametrize("name", list(PARSERS))
def test_every_command_has_examples(name):
    assert len(reference.examples(PARSERS[name])) >= 1


@pytest.mark.parametrize("name", list(PARSERS))
def test_the_examples_parse_with_their_commands_parser(name):
    top = PARSERS["bgsub"]
    for words in reference.examples(PARSERS[name]):
        assert words[0] == "bgsub", words
        args = top.parse_args(words[1:])  # a usage error exits (and fails the test)
        assert callable(args.handler)


@pytest.mark.parametrize("name", list(PARSERS))
def test_the_examples_need_nothing_but_the_sample(name):
    # Placeholders such as clip.mp4 or path/to/cdnet would not run as written.
    for words in reference.examples(PARSERS[name]):
        for word in words:
            assert not word.startswith(("clip", "path/to", "data/", "../")), (name, words)


@pytest.mark.parametrize("name", list(PARSERS))
def test_no_help_text_begins_with_an_ellipsis(name):
    for action in _actions(PARSERS[name]):
        assert not action.help.lstrip().startswith("..."), (name, action.dest)


def test_examples_follow_continued_lines_and_drop_comments():
    import argparse

    parser = argparse.ArgumentParser(epilog="""examples:
  bgsub run a.mp4 -o m.mkv      a comment
        a comment on a line of its own
  OMP_NUM_THREADS=1 bgsub run a.mp4 \\
      -o 'b c.mkv' --step 2     another

not an example: bgsub run x
""")
    assert reference.examples(parser) == [["bgsub", "run", "a.mp4", "-o", "m.mkv"],
                                          ["bgsub", "run", "a.mp4", "-o", "b c.mkv", "--step",
                                           "2"]]


def test_an_option_with_several_spellings_shows_its_value_once():
    text = reference.help_text(PARSERS["run"], width=80)
    assert "-m, --method NAME" in text and "-m NAME, --method NAME" not in text
