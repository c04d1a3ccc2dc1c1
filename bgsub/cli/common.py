"""Options and helpers shared by several sub-commands."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Iterable, List, Optional, Tuple

from bgsub.errors import OutputError


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """argparse's help with the description and epilog as written, and an option's value
    named once: ``-m, --method NAME`` rather than ``-m NAME, --method NAME``, so that most
    options take one line of ``--help``."""

    def _format_action_invocation(self, action: argparse.Action) -> str:
        if not action.option_strings or action.nargs == 0:
            return super()._format_action_invocation(action)
        value = self._format_args(action, self._get_default_metavar_for_optional(action))
        short = [name for name in action.option_strings if not name.startswith("--")]
        long = [name for name in action.option_strings if name.startswith("--")][:1]
        return f"{', '.join(short + long)} {value}"  # further long spellings are aliases


def add_source_options(parser: argparse.ArgumentParser) -> None:
    """Frame range and resizing options, passed to :func:`bgsub.io.sources.open_source`."""
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
    group.add_argument("--fps", type=float, default=None, metavar="F",
                       help="the input's frame rate (default: as stated, or 25)")


def add_preset_option(parser: Any, *, more: str = "") -> None:
    """``--preset NAME``: a named set of engine parameters (fast, balanced, accurate);
    ``--param`` and ``--config`` override its values. ``more``: the rest of its help."""
    parser.add_argument("--preset", default=None, metavar="NAME",
                        help=f"named settings: fast, balanced (default), accurate{more}")


def source_kwargs(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`open_source` taken from :func:`add_source_options`."""
    return dict(start=args.start, stop=args.stop, step=args.step, scale=args.scale,
                width=args.width, fps=args.fps)


class _Deprecated(argparse.Action):
    """A hidden old spelling of an option: stores into the new option's ``dest`` and says on
    stderr which spelling to use instead."""

    def __init__(self, option_strings: List[str], dest: str, *, use: str,
                 **kwargs: Any) -> None:
        self.use = use
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser: Any, namespace: argparse.Namespace, values: Any,
                 option_string: Optional[str] = None) -> None:
        print(f"bgsub: warning: {option_string} is deprecated; use {self.use}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_deprecated(parser: Any, *old: str, use: str, dest: str, **kwargs: Any) -> None:
    """Old spellings ``old`` of the option ``use`` (whose value goes to ``dest``), accepted for
    one release without showing in the help; ``kwargs`` as ``use``'s (``type``, ``choices``,
    ``metavar``)."""
    parser.add_argument(*old, dest=dest, action=_Deprecated, use=use, help=argparse.SUPPRESS,
                        default=argparse.SUPPRESS, **kwargs)


def add_output_options(parser: argparse.ArgumentParser, *,
                       quiet_help: str = "no progress bar and no notes on stderr (warnings, "
                                         "errors and the results are still printed)") -> None:
    """``--overwrite`` and ``-q/--quiet``; ``quiet_help`` says what ``-q`` silences."""
    parser.add_argument("--overwrite", action="store_true",
                        help="replace outputs that already exist (refused otherwise)")
    parser.add_argument("-q", "--quiet", action="store_true", help=quiet_help)


def add_codec_option(parser: Any) -> None:
    """``--codec {auto,h264,mp4v}``: the codec of ``.mp4`` / ``.mov`` picture videos."""
    from bgsub.io.h264 import CODEC_CHOICES

    parser.add_argument("--codec", choices=CODEC_CHOICES, default="auto", metavar="CODEC",
                        help="auto (H.264 if PyAV is there, else mp4v), h264, mp4v")


def describe_codec(path: Any, codec: str) -> str:
    """``"overlay.mp4: H.264"``: the one-line note saying what a picture video was written in."""
    from bgsub.io.h264 import H264_EXTRA

    if codec == "h264":
        return f"{path}: H.264 video (plays in web browsers)"
    if codec == "mp4v":
        return (f"{path}: MPEG-4 part 2 video (mp4v; for H.264, which web browsers play: "
                f"{H264_EXTRA})")
    return f"{path}: {codec} video"


def progress(iterable: Iterable[Any], *, total: Optional[int] = None, desc: str = "",
             quiet: bool = False, unit: str = "frame") -> Iterable[Any]:
    """Wrap ``iterable`` in a tqdm bar on stderr, off when ``quiet`` or stderr is no terminal."""
    from tqdm import tqdm  # here: importing it costs a command that shows no bar

    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr,
                disable=quiet or not sys.stderr.isatty(), dynamic_ncols=True, leave=False)


def note(message: str, *, quiet: bool = False) -> None:
    """A one-line notice on stderr (not an error)."""
    if not quiet:
        print(f"bgsub: {message}", file=sys.stderr)


def warn(message: str) -> None:
    """A one-line ``bgsub: warning: ...`` on stderr: the result may not be what was meant.
    Printed with ``--quiet`` too (as the lossy-codec warning of :mod:`bgsub.io.sinks` is)."""
    print(f"bgsub: warning: {message}", file=sys.stderr)


def check_distinct(inputs: Iterable[Any], outputs: List[Tuple[str, Any]], *,
                   input_folders: Iterable[Path] = ()) -> None:
    """Refuse an output that is stdout (``-``), one of the inputs, a folder the input frames
    are listed from, or is given to two options.

    ``outputs`` pairs each option (``"-o"``, ``"--vis"``) with its path; unset paths (None or
    "") are skipped. ``input_folders`` are resolved folders whose images are the input
    (:attr:`bgsub.io.sources.FrameSource.folders`): masks written there would be read as frames
    the next time. Even ``--overwrite`` must not replace or add to what the command is reading.
    """
    sources = {Path(p).resolve() for p in inputs if p}
    folders = set(input_folders)
    seen = {}
    for flag, path in outputs:
        if not path:
            continue
        if str(path) == "-":
            raise OutputError(f"{flag} -: writing to stdout is not supported; give a file or "
                              "folder name")
        resolved = Path(path).resolve()
        if resolved in folders:
            raise OutputError(f"{path}: {flag} is the folder the input frames are read from; "
                              "what is written there would be read as frames next time (give "
                              "another folder)")
        if resolved in sources:
            raise OutputError(f"{path}: {flag} would overwrite an input")
        if resolved in seen:
            raise OutputError(f"{path}: given to both {seen[resolved]} and {flag}")
        seen[resolved] = flag


def model_files(model: str) -> List[str]:
    """``[model]`` when ``--model`` names a file, ``[]`` for a shipped model's name: the inputs
    :func:`check_distinct` must protect."""
    from bgsub.model.rbm import SHIPPED_MODELS

    return [] if model in SHIPPED_MODELS else [model]


def is_binary_model(model: Any) -> bool:
    """The model has binary output units: a random-dot model such as ``dots-rotation``."""
    return getattr(model, "output_units", None) == "binary"


def warn_if_binary_model(model: Any, image: Any, *, what: str = "") -> None:
    """Warn when a model with binary output units (a random-dot model such as
    ``dots-rotation``) is given an image that is not dark with sparse bright dots: it reads
    little motion in photographs or natural video, and what it reads is mostly wrong.

    ``image`` is a gray or BGR frame, uint8 (0-255) or float (0-1); ``what`` names it (a file)
    in the message. Models without ``output_units`` (any other patch-motion model) pass.
    """
    import numpy as np

    if not is_binary_model(model):
        return
    values = np.asarray(image)
    mean = float(values.mean()) / (255.0 if values.dtype == np.uint8 else 1.0)
    if mean > 0.35:  # random dots: mostly black
        where = f"{what}: " if what else ""
        warn(f"{where}a binary (random-dot) model expects dark images with sparse bright dots; "
             "for photographs and natural video use a Gaussian model such as natural")


def warn_if_binary_model_on_source(model: Any, source: Any, *, what: str = "") -> None:
    """:func:`warn_if_binary_model` for the first frame of a :class:`bgsub.io.sources.FrameSource`
    (:meth:`~bgsub.io.sources.FrameSource.first_frame`: a live source is not read again), and
    only when the model is a binary one."""
    if not is_binary_model(model):
        return
    first = source.first_frame()
    if first is not None:
        warn_if_binary_model(model, first, what=what)
