"""Options and helpers shared by several sub-commands."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Iterable, List, Optional, Tuple

from tqdm import tqdm

from bgsub.errors import OutputError


def add_source_options(parser: argparse.ArgumentParser) -> None:
    """Frame range and resizing options, passed to :func:`bgsub.sources.open_source`."""
    group = parser.add_argument_group("input frames")
    group.add_argument("--start", type=int, default=0, metavar="N",
                       help="first frame to read, 0-based (default: 0)")
    group.add_argument("--stop", type=int, default=None, metavar="N",
                       help="stop before this frame, 0-based (default: the end)")
    group.add_argument("--step", type=int, default=1, metavar="N",
                       help="read every N-th frame (default: 1)")
    size = group.add_mutually_exclusive_group()
    size.add_argument("--scale", type=float, default=None, metavar="F",
                      help="resize frames by this factor, e.g. 0.5")
    size.add_argument("--width", type=int, default=None, metavar="PX",
                      help="resize frames to this width, keeping the aspect ratio")


def source_kwargs(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`open_source` taken from :func:`add_source_options`."""
    return dict(start=args.start, stop=args.stop, step=args.step, scale=args.scale,
                width=args.width)


def add_output_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help="replace outputs that already exist (refused otherwise)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar and no notes on stderr (results such as "
                             "a report table are still printed)")


def progress(iterable: Iterable[Any], *, total: Optional[int] = None, desc: str = "",
             quiet: bool = False, unit: str = "frame") -> Iterable[Any]:
    """Wrap ``iterable`` in a tqdm bar on stderr, off when ``quiet`` or stderr is no terminal."""
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr,
                disable=quiet or not sys.stderr.isatty(), dynamic_ncols=True, leave=False)


def note(message: str, *, quiet: bool = False) -> None:
    """A one-line notice on stderr (not an error)."""
    if not quiet:
        print(f"bgsub: {message}", file=sys.stderr)


def check_distinct(inputs: Iterable[Any], outputs: List[Tuple[str, Any]]) -> None:
    """Refuse an output that is one of the inputs or is given to two options.

    ``outputs`` pairs each option (``"-o"``, ``"--vis"``) with its path; unset paths (None or
    "") are skipped. Even ``--overwrite`` must not replace what the command is reading.
    """
    sources = {Path(p).resolve() for p in inputs if p}
    seen = {}
    for flag, path in outputs:
        if not path:
            continue
        resolved = Path(path).resolve()
        if resolved in sources:
            raise OutputError(f"{path}: {flag} would overwrite an input")
        if resolved in seen:
            raise OutputError(f"{path}: given to both {seen[resolved]} and {flag}")
        seen[resolved] = flag


def model_files(model: str) -> List[str]:
    """``[model]`` when ``--model`` names a file, ``[]`` for a shipped model's name: the inputs
    :func:`check_distinct` must protect."""
    from bgsub.rbm import SHIPPED_MODELS

    return [] if model in SHIPPED_MODELS else [model]
