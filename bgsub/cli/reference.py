"""The command reference ``docs/cli.md``: each command's ``--help`` as the parsers print it,
between hand-written topic sections.

In ``docs/cli.md`` a block between ``<!-- help: COMMAND -->`` and ``<!-- end help -->`` is
generated (``COMMAND`` is ``bgsub`` or a sub-command); everything else is written by hand.
Regenerate the blocks after changing an option or an epilog::

    python -m bgsub.cli.reference            # rewrites docs/cli.md
    python -m bgsub.cli.reference --check    # exit status 1 when docs/cli.md is stale

The examples of each command's epilog (:func:`examples`) are what the tests parse with the
command's own parser.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shlex
import sys
from pathlib import Path
from typing import Dict, Iterator, List, Optional

#: The width the reference's help text is formatted at (argparse wraps to the terminal's).
WIDTH = 100

#: ``docs/cli.md`` of a checkout (this module is ``bgsub/cli/reference.py``).
DEFAULT_PATH = Path(__file__).resolve().parents[2] / "docs" / "cli.md"

_BLOCK = re.compile(r"(<!-- help: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- end help -->)",
                    re.DOTALL)


def parsers() -> Dict[str, argparse.ArgumentParser]:
    """``{"bgsub": the top-level parser, "run": its parser, ...}`` in ``bgsub --help``'s
    order."""
    from bgsub.cli import _commands, build_parser

    top = build_parser()
    return {"bgsub": top, **{name: p for name, p in _commands(top).items()}}


@contextlib.contextmanager
def _columns(width: int) -> Iterator[None]:
    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)
    try:
        yield
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


def help_text(parser: argparse.ArgumentParser, *, width: int = WIDTH) -> str:
    """``parser``'s ``--help`` as printed on a terminal ``width`` columns wide."""
    with _columns(width):
        return parser.format_help()


def examples(parser: argparse.ArgumentParser) -> List[List[str]]:
    """The commands of ``parser``'s epilog after ``examples:``: one word list per command
    (starting with ``bgsub``; a leading ``NAME=value`` and a trailing comment, set off by two
    or more spaces, left out; lines ending in ``\\`` continued)."""
    text = (parser.epilog or "").split("examples:\n", 1)
    commands: List[List[str]] = []
    pending = ""
    for line in (text[1] if len(text) > 1 else "").splitlines():
        if not line.strip():
            break
        if pending:
            line = pending + " " + line.strip()
            pending = ""
        elif "bgsub " not in line:
            continue  # a comment line of the example above
        command = re.split(r"\s{2,}", line.strip())[0]
        if command.endswith("\\"):
            pending = command[:-1].strip()
            continue
        words = shlex.split(command)
        while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):
            words = words[1:]
        commands.append(words)
    return commands


def render(text: str) -> str:
    """``text`` (``docs/cli.md``) with every generated block replaced by the current help."""
    found = parsers()

    def block(match: "re.Match[str]") -> str:
        name = match.group("name")
        if name not in found:
            raise KeyError(f"docs/cli.md: no command {name!r}")
        body = help_text(found[name]).rstrip("\n")
        return f"{match.group(1)}```text\n{body}\n```\n{match.group(4)}"

    return _BLOCK.sub(block, text)


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bgsub.cli.reference",
                                     description="Regenerate the help blocks of docs/cli.md.")
    parser.add_argument("path", nargs="?", type=Path, default=DEFAULT_PATH)
    parser.add_argument("--check", action="store_true",
                        help="only say whether the file is up to date (exit status 1 if not)")
    args = parser.parse_args(argv)
    current = args.path.read_text(encoding="utf-8")
    fresh = render(current)
    if args.check:
        if fresh != current:
            print(f"{args.path} is stale: run python -m bgsub.cli.reference", file=sys.stderr)
            return 1
        return 0
    if fresh != current:
        args.path.write_text(fresh, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
