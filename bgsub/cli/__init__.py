"""The ``bgsub`` command line: a thin layer over the :mod:`bgsub` Python API.

Each sub-command lives in its own module of this package and exposes
``register(subparsers) -> None``, which adds its parser and sets ``handler=fn(args) -> int``.
This module only dispatches and turns errors into one line on stderr:

* a usage error (a missing argument, an unknown option) -> argparse's message, exit status 2;
  an option before the sub-command that ``bgsub`` itself does not take is named as such;

* :class:`bgsub.errors.BgsubError` -> its message, exit status ``err.exit_code`` (2 bad input, 1
  failure while processing);
* Ctrl-C -> exit status 130 (sinks have already closed their partial output and said so), also
  while the parser is built (the sub-commands' imports); ``kill`` (SIGTERM) and a closed
  terminal (SIGHUP) take the same path while the command runs, exit status 128 + signal; a
  signal after the first one is ignored (the command is already stopping);
* an OSError that reaches here (a full disk or a closed stdout while printing) -> its reason,
  exit status 1;
* anything else is a bug: one line naming it, exit status 1 (``BGSUB_DEBUG=1`` shows the traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import itertools
import os
import signal
import sys
from typing import Dict, Iterator, List, NoReturn, Optional

from bgsub.errors import BgsubError

# Sub-commands and their modules, in the order `bgsub --help` lists them.
_COMMANDS = {
    "run": "run",
    "methods": "methods",
    "eval": "evaluate",
    "compare": "compare",
    "samples": "samples",
    "train": "train",
    "flow": "flow",
    "analogy": "analogy",
    "bench": "bench",
}

_EPILOG = """\
examples:
  bgsub samples --pan                                 copy the bundled sample to samples/pan.mp4
  bgsub run samples/pan.mp4 -o pan_masks.mkv          foreground masks of the bundled sample
  bgsub run clip.mp4 -o masks/ --method mog2          CDnet-style binNNNNNN.png masks, OpenCV MOG2
  bgsub eval masks/ path/to/cdnet/sequence            the seven CDnet 2014 metrics
  bgsub samples scenes/ --seed 1                      synthetic moving-camera scenes with ground truth
  bgsub methods                                       engines and their parameters

Run `bgsub COMMAND --help` for each command's options.
"""


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line like every other error (argparse's own prints
    the usage block first, which `--help` shows anyway). Sub-command parsers inherit it."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"bgsub: error: {message} (see `{self.prog} --help`)\n")


def build_parser(command: Optional[str] = None) -> argparse.ArgumentParser:
    """The ``bgsub`` parser with every sub-command, or only ``command``'s when it names one:
    a command imports only what it needs (a short run's start-up is mostly imports)."""
    parser = _Parser(
        prog="bgsub",
        description=(
            "Find moving objects in video from a moving camera: a gated RBM learns how patches "
            "move, RANSAC fits the camera motion, and what violates it is foreground."
        ),
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    from bgsub import __version__

    parser.add_argument("--version", action="version", version=f"bgsub {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    names = [command] if command in _COMMANDS else list(_COMMANDS)
    for name in names:
        importlib.import_module(f"bgsub.cli.{_COMMANDS[name]}").register(subparsers)
    return parser


def _command_word(argv: List[str]) -> Optional[str]:
    """The first word of ``argv`` that is not an option (the sub-command, if it names one)."""
    return next((token for token in argv if not token.startswith("-")), None)


def _command_parser(parser: argparse.ArgumentParser,
                    args: argparse.Namespace) -> argparse.ArgumentParser:
    """The sub-command's parser of ``args`` (``parser`` itself when there is none)."""
    return _commands(parser).get(getattr(args, "command", None), parser)


def _commands(parser: argparse.ArgumentParser) -> Dict[str, argparse.ArgumentParser]:
    """The sub-command parsers of ``parser`` by name (aliases included)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def _option_name(token: str) -> str:
    """The option a command-line word names: ``--name`` of ``--name=value``, ``-x`` of
    ``-xVALUE``."""
    return token.split("=", 1)[0] if token.startswith("--") else token[:2]


def _has_option(parser: argparse.ArgumentParser, token: str) -> bool:
    """Whether ``parser`` takes the option of the word ``token`` (see :func:`_option_name`),
    also as a prefix of a long option (argparse's abbreviations)."""
    names = [name for action in parser._actions for name in action.option_strings]
    typed = _option_name(token)
    if typed.startswith("--"):
        return any(name.startswith(typed) for name in names)
    return typed in names


def _check_leading_options(parser: argparse.ArgumentParser, argv: List[str]) -> None:
    """Refuse an option before the sub-command that ``bgsub`` itself does not take.

    argparse sets such an option aside and has the sub-command's parser report it, as if it
    were that command's unknown option (``bgsub --quiet run ...``: "unrecognized arguments:
    --quiet (see `bgsub run --help`)", which lists --quiet); one with a value even makes the
    value the command (``--model natural flow ...``: "invalid choice: 'natural'").
    """
    commands = _commands(parser)
    before = list(itertools.takewhile(lambda token: token not in commands, argv))
    command = argv[len(before)] if len(before) < len(argv) else None
    if command is None:  # the first word that is no option is an unknown command, which
        # argparse names: only the options before it are looked at here
        before = list(itertools.takewhile(lambda token: token.startswith("-"), argv))
    for token in itertools.takewhile(lambda token: token != "--", before):
        if not token.startswith("-") or token == "-" or _has_option(parser, token):
            continue
        name = _option_name(token)
        if command is not None and _has_option(commands[command], token):
            commands[command].error(f"{name} is an option of `bgsub {command}`, not of bgsub: "
                                    f"put it after `{command}`")
        parser.error(f"{name} is not a bgsub option")


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the program is so that outputs close as on Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _StopOnce:
    """Handler of Ctrl-C, SIGTERM and SIGHUP while a command runs: the first signal raises
    (``KeyboardInterrupt``, or :class:`Terminated`) where the program is, so that outputs close
    as on Ctrl-C; every later one is ignored, so a second Ctrl-C (or a ``kill`` right after
    one) cannot cut the finishing of an output short."""

    def __init__(self) -> None:
        self.fired = False

    def __call__(self, signum: int, frame: object) -> None:
        if self.fired:
            return
        self.fired = True
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise Terminated(signum)


@contextlib.contextmanager
def _stop_once(*, keep: bool) -> Iterator[None]:
    """Ctrl-C, SIGTERM and SIGHUP go to a :class:`_StopOnce` while the command runs. Without
    this SIGTERM and SIGHUP end the process on the spot and leave only hidden, unplayable
    ``.partial`` files. ``keep``: once a signal has stopped the command, leave the handler in
    place (the process is about to exit; a signal then would print a traceback)."""
    handler = _StopOnce()
    wanted = [getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
              if hasattr(signal, name)]
    saved = {}
    try:
        for signum in wanted:
            saved[signum] = signal.signal(signum, handler)
    except ValueError:  # not the main thread (main() called from a thread): leave them be
        pass
    try:
        yield
    finally:
        if not (keep and handler.fired):
            for signum, previous in saved.items():
                signal.signal(signum, previous)


def main(argv: Optional[List[str]] = None) -> int:
    """Entry point of the ``bgsub`` console script; returns the exit status."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        # Ctrl-C outside the command itself: while the parser imports the sub-commands (the
        # first fraction of a second), or while an error above is being printed.
        print("bgsub: interrupted", file=sys.stderr)
        return 130


#: The modules every command needs, and the distributions that install them.
_DEPENDENCIES = {"cv2": "opencv-python-headless", "numpy": "numpy", "tqdm": "tqdm"}


def _dependency_error() -> Optional[str]:
    """The one-line message for a dependency that is missing or fails to import (an OpenCV
    wheel for another platform, a missing system library), or None when every one imports."""
    for module, distribution in _DEPENDENCIES.items():
        try:
            importlib.import_module(module)
        except Exception as err:  # a broken install raises anything at import
            reason = str(err).splitlines()[0] if str(err) else type(err).__name__
            return (f"cannot import {module} ({reason}): bgsub needs {distribution}; install "
                    f"or reinstall it with `python -m pip install --force-reinstall "
                    f"{distribution}`")
    return None


def _silence_stdout(*, final: bool) -> None:
    """Point the process's stdout at devnull, so that the interpreter's last flush of a stdout
    that cannot be written does not fail again; only when the process ends after this command
    (``final``: the console script): a caller of :func:`main` keeps its stdout (under pytest,
    ``sys.stdout`` is its capture file)."""
    if final:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def _main(argv: Optional[List[str]]) -> int:
    from bgsub.cli.opencv_wheels import warn_once

    warn_once()  # (package metadata only: no OpenCV import yet)
    argv_list = sys.argv[1:] if argv is None else list(argv)
    try:
        # Imports the sub-command (every one for `bgsub --help`), and so numpy and OpenCV.
        parser = build_parser(_command_word(argv_list))
    except ImportError:
        message = _dependency_error()
        if message is None:
            raise
        print(f"bgsub: error: {message}", file=sys.stderr)
        return 1
    _check_leading_options(parser, argv_list)
    args, extra = parser.parse_known_args(argv)
    if extra:  # named by the command's parser, whose --help lists what it takes
        _command_parser(parser, args).error(f"unrecognized arguments: {' '.join(extra)}")
    if not getattr(args, "handler", None):
        parser.print_help(sys.stderr)
        return 2
    if argv is None:
        # The console script's own process: its reading and writing threads free frames as
        # fast as the engine does (bgsub.engines.threads.reuse_freed_memory).
        from bgsub.engines.threads import reuse_freed_memory

        reuse_freed_memory()
    try:
        # The console script (argv None) exits after this: a stop by a signal is final.
        with _stop_once(keep=argv is None):
            return int(args.handler(args) or 0)
    except BgsubError as err:
        print(f"bgsub: error: {err}", file=sys.stderr)
        return err.exit_code
    except Terminated as err:
        print(f"bgsub: stopped by {err}", file=sys.stderr)
        return 128 + err.signum
    except KeyboardInterrupt:
        print("bgsub: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Output piped into `head` and the like: the reader left, which is not an error of ours.
        # Point stdout at devnull so the interpreter's final flush does not complain again.
        _silence_stdout(final=argv is None)
        return 0
    except OSError as err:
        # The environment, not a bug: a full disk, a stdout that cannot be written. A name
        # longer than the file system takes is the user's to shorten: exit 2, as for OutputError.
        where = f" ({err.filename})" if err.filename else ""
        print(f"bgsub: error: {err.strerror or err}{where}", file=sys.stderr)
        with contextlib.suppress(OSError):  # the final flush of a full stdout must not fail again
            _silence_stdout(final=argv is None)
        return 2 if err.errno == errno.ENAMETOOLONG else 1
    except Exception as err:  # a bug: say so in one line unless asked for the traceback
        if os.environ.get("BGSUB_DEBUG"):
            raise
        print(
            f"bgsub: internal error: {type(err).__name__}: {err} "
            "(set BGSUB_DEBUG=1 for the traceback)",
            file=sys.stderr,
        )
        return 1
