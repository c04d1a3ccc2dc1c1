"""``bgsub run``: foreground masks of a video, an image folder or a glob pattern.

A thin layer: :func:`bgsub.io.sources.open_source` reads, an engine from :mod:`bgsub.engines` makes
the masks, :class:`bgsub.io.loop.FrameLoop` hands them to the writers of :mod:`bgsub.io.writers`.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import shlex
from typing import Any, List, Optional

from bgsub import engines
from bgsub.batch.plan import OPTIONS
from bgsub.cli import batch, common, run_extras, run_inputs
from bgsub.errors import InputError
from bgsub.io.loop import FrameLoop, RunStats
from bgsub.io.pipeline import OutputRequest, open_outputs
from bgsub.io.sinks import is_video_path
from bgsub.io.sources import FrameSource, VideoInfo, open_source
from bgsub.io.writers import ProgressBar

_DESCRIPTION = """\
Find the moving objects in a video: one mask per frame (0 background, 255 foreground), as a
lossless video (.mkv, .avi) or, for a name without an extension, a folder of binNNNNNN.png
numbered by position in INPUT. Ctrl-C leaves valid, partial outputs."""

_EPILOG = """\
examples:
  bgsub run samples/pan.mp4 -o pan_masks.mkv                    masks as a lossless video
  bgsub run samples/pan.mp4 -o pan_masks/                       binNNNNNN.png, for bgsub eval
  bgsub run samples/pan.mp4 -o m1.mkv --vis overlay.mp4 --objects objects.jsonl
  bgsub run samples/pan.mp4 -o m2.mkv -m mog2 -p history=200    another engine and parameter
  bgsub run samples/pan.mp4 -o m3.mkv --motion cam.npy --max-frames 60
  bgsub run samples/pan.mp4 -o m4.mkv --motion-in cam.npy --max-frames 60
  bgsub run samples/pan.mp4 -o m5.mkv --stats stats.csv         per-frame figures, for tuning
  bgsub run samples/ -o batch/ --summary batch.json             every video of a folder

Numbering, formats, live sources, batches, exit statuses: docs/cli.md; engines: bgsub methods"""


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "run", help="foreground masks of a video or image folder", description=_DESCRIPTION,
        epilog=_EPILOG, formatter_class=common.HelpFormatter,
        usage="bgsub run INPUT [INPUT ...] -o OUTPUT [options]",
    )
    parser.add_argument("input", metavar="INPUT", nargs="+",
                        help="video, folder, glob, camera or URL (several: a batch)")
    parser.add_argument("-o", "--output", required=True, metavar="OUTPUT",
                        help="mask video (.mkv/.avi lossless) or folder of PNG masks")
    parser.add_argument("-m", "--method", "--methods", dest="method", default=None,
                        metavar="NAME", help=f"engine (default: {engines.DEFAULT_METHOD}; "
                                             f"see `bgsub methods`)")
    parser.add_argument("-p", "--param", action="append", default=[], metavar="KEY=VAL",
                        help="an engine parameter, e.g. -p stride=12 (repeatable)")
    common.add_preset_option(parser)
    parser.add_argument("--vis", metavar="VIDEO", default=None,
                        help="also the masks over the input, as a video")
    parser.add_argument("--flow-vis", metavar="VIDEO", default=None,
                        help="also the motion field and camera fit (grbm)")
    common.add_codec_option(parser)
    parser.add_argument("--motion", metavar="FILE.npy", default=None,
                        help="also the camera motion, (N, 3, 3) homographies")
    parser.add_argument("--stats", metavar="FILE.csv", default=None,
                        help="also per-frame figures for tuning, as CSV")
    run_extras.add_options(parser)
    common.add_source_options(parser)
    run_inputs.add_options(parser)
    common.add_output_options(parser, quiet_help="no progress bar and no notes on stderr")
    batch.add_batch_options(parser)
    parser.set_defaults(handler=run)


def _method(name: Optional[str]) -> str:
    if name is None:
        return engines.default_method()
    if not name.strip():  # --method "" is a mistake, not "the default"
        raise InputError("--method is empty (give an engine name, or leave it out for "
                         f"{engines.default_method()}; see `bgsub methods`)")
    if "," in name:
        raise InputError(f"--method {name}: run takes one method (`bgsub compare --methods "
                         "a,b` runs several on the same input)")
    return name


def _request(args: argparse.Namespace) -> OutputRequest:
    """The outputs asked for, as the output pipeline takes them."""
    return OutputRequest(masks=args.output, vis=args.vis, flow_vis=args.flow_vis,
                         motion=args.motion, objects=args.objects, stats=args.stats,
                         codec=args.codec, min_object_area=args.min_object_area,
                         overwrite=args.overwrite)


def _check_outputs(args: argparse.Namespace, source: FrameSource, reads: list) -> None:
    """Refuse bad outputs before any frame is processed; ``reads``: the files the run reads
    besides its input (:func:`run_inputs.input_files`)."""
    request = _request(args)
    outputs = [(OPTIONS[kind], path) for kind, path in request.paths().items()]
    # First: "-", an input and the input's own folder are refused whether or not they look
    # writable, --overwrite or not.
    common.check_distinct([args.input] + reads, outputs, input_folders=source.folders)
    request.check()


def _plural(count: int, noun: str) -> str:
    return f"{count} {noun}{'s' * (count != 1)}"


def _summary(stats: RunStats, method: str, outputs: List[str]) -> str:
    text = (f"{_plural(stats.frames, 'frame')} in {stats.seconds:.1f} s ({stats.fps:.1f} fps) "
            f"with {method} -> {', '.join(outputs)}")
    if stats.has_status and stats.frames:
        if stats.not_ok:
            status, count = stats.statuses.most_common(1)[0]
            text += (f"; {_plural(stats.not_ok, 'frame')} not ok (most often {status!r}: "
                     f"{count})")
        else:
            text += "; all frames ok" if stats.frames > 1 else "; frame ok"
    return text


def _smooth_notice(stats: RunStats, method: str, params: dict) -> Optional[str]:
    """A hint when most frames were taken for scene cuts by an engine that can smooth but did
    not: grainy or heavily compressed footage makes most pixels differ from any model."""
    spec = engines.get_engine_spec(method).params.get("smooth")
    if spec is None or params.get("smooth", spec.default) > 0:
        return None
    from bgsub.engines.moving import SCENE_CUT  # (an engine that can smooth is one of these)

    cuts = stats.statuses.get(SCENE_CUT, 0) if stats.has_status else 0
    if 2 * cuts <= stats.frames:
        return None
    return (f"{cuts} of {_plural(stats.frames, 'frame')} were taken for scene cuts (the model "
            "restarted, the mask empty); if the footage is grainy or heavily compressed, "
            "--param smooth=1 blurs each frame before it is compared")


def _fps_notice(info: VideoInfo, args: argparse.Namespace) -> Optional[str]:
    writes_video = is_video_path(args.output) or args.vis or args.flow_vis
    if info.fps_is_default and writes_video:
        return (f"{args.input} states no frame rate; videos are written at {info.fps:g} fps "
                "(--fps sets it)")
    return None


def _numbering_notice(source: Any, args: argparse.Namespace) -> Optional[str]:
    """Masks are numbered by position in the input: say so when the first image read carries
    another number in its name (a folder or glob of part of a sequence)."""
    name = source.file_name(args.start)
    found = re.search(r"(\d+)\D*$", name or "")
    if found is None or int(found.group(1)) <= args.start + 1:  # (0-based names: no news)
        return None
    return (f"masks are numbered by position in the input: the mask of {name} is number "
            f"{args.start + 1} (bin{args.start + 1:06d}.png), not {int(found.group(1))}; give "
            f"the whole folder with --start to keep the file names' numbers")


def _eval_notice(args: argparse.Namespace, renumbered: bool) -> Optional[str]:
    """How to score a mask video that does not hold every input frame from the first.

    A video carries no frame numbers, so `bgsub eval` takes its k-th frame as frame k (1-based)
    unless given the range the masks were made from; a png folder's names carry the numbers.
    ``renumbered``: the input's positions are not its files' numbers (part of a sequence, see
    :func:`_numbering_notice`), so no range of positions names ground-truth frames.
    """
    if not is_video_path(args.output) or (args.start, args.step) == (0, 1) or renumbered:
        return None
    from bgsub.evaluation.cdnet import VideoFrames  # the scoring code, only for this notice

    flags = VideoFrames(args.start, args.step, args.stop).flags()
    return (f"{args.output} holds no frame numbers: score it with `bgsub eval "
            f"{shlex.quote(str(args.output))} GROUNDTRUTH {flags}`")


def _outputs(args: argparse.Namespace) -> dict:
    """The outputs asked for, by kind."""
    return _request(args).paths()


def _open_input(args: argparse.Namespace, params: dict) -> tuple:
    """``(source, params)``: the input opened, the outputs checked and the parameters' files
    (``--roi``, ``--motion-in``) read; a refusal closes the source (a camera stays open
    otherwise)."""
    source = open_source(args.input, **common.source_kwargs(args),
                         stall_seconds=args.stall_timeout)
    try:
        _check_outputs(args, source, run_inputs.input_files(args, params))
        params = run_inputs.check_inputs(params, width=source.info.width,
                                         height=source.info.height)
    except BaseException:
        source.close()
        raise
    return source, params


def _input_notes(args: argparse.Namespace, source: FrameSource, engine: Any) -> None:
    """What the run should say of its input once it ended: a video or stream that ended
    early (a warning), a known camera motion shorter than the input."""
    short = source.truncation()  # a video ended well before its declared end, a stream stalled
    if short:
        common.warn(short)
    motion = run_inputs.motion_note(engine)
    if motion:
        common.note(motion, quiet=args.quiet)
    box = getattr(engine, "overlay_box", None)
    if box:
        x, y, w, h = box
        common.note(f"frame-fixed overlays (a logo, a watermark, a timestamp, black bars) "
                    f"found within {w}x{h} at ({x}, {y}): taken as background; --roi chooses "
                    "the watched region instead", quiet=args.quiet)
    box = getattr(engine, "see_through_box", None)
    if box:
        x, y, w, h = box
        common.note(f"a semi-transparent overlay (a watermark) found within {w}x{h} at ({x}, "
                    f"{y}): seen through, the scene and objects under it still watched",
                    quiet=args.quiet)


def run(args: argparse.Namespace) -> int:
    method = _method(args.method)
    args.preset, given = run_extras.engine_settings(args, method)  # (a batch reads args.preset)
    params = run_inputs.engine_params(args, method, given)
    engines.get_engine_spec(method).preset_values(args.preset)  # (refused before any input)
    run_inputs.apply_max_frames(args)
    run_extras.tracker_config(args)  # (refused before any input is opened)
    if args.motion_in and batch.is_batch(args):
        raise InputError("--motion-in is for a single input (a camera motion is one video's)")
    status = batch.dispatch(args, method=method, params=params,  # several inputs
                            reads=run_inputs.input_files(args, params))
    if status is not None:
        return status
    source, params = _open_input(args, params)
    info = source.info
    engine = engines.create_engine(method, args.preset, **params)
    if args.flow_vis and not engines.supports(engine, "debug_image"):
        raise InputError(f"--flow-vis: method {method!r} cannot draw its motion (it has no "
                         "debug_image); use a moving-camera method such as grbm")
    if args.motion and not engines.supports(engine, "last_motion"):
        raise InputError(f"--motion: method {method!r} estimates no camera motion; use a "
                         "moving-camera method such as grbm or compensated")
    # What `bgsub analogy` and `bgsub flow` say of a random-dot model on natural images.
    common.warn_if_binary_model_on_source(getattr(engine, "model", None), source,
                                          what=args.input)
    renumbered = _numbering_notice(source, args)
    for notice in (_fps_notice(info, args), renumbered):
        if notice:
            common.note(notice, quiet=args.quiet)

    with contextlib.ExitStack() as stack:
        stack.enter_context(source)
        if callable(getattr(engine, "close", None)):  # (a plugin may not subclass Engine)
            stack.callback(engine.close)  # its worker thread ends with the command, not after
        consumers, codecs = open_outputs(stack, _request(args), width=info.width,
                                         height=info.height, fps=info.fps)
        consumers.append(ProgressBar(total=info.frame_count, desc=method,
                                     enabled=not args.quiet))
        loop = FrameLoop({method: engine}, consumers)
        try:
            stats = loop.run(source)
        except KeyboardInterrupt:
            if args.json:  # what the partial outputs hold
                run_extras.print_summary(loop.stats, method=method, outputs=_outputs(args),
                                         codecs=codecs)
            raise

    _input_notes(args, source, engine)
    written = list(_outputs(args).values())
    common.note(_summary(stats, method, written), quiet=args.quiet)
    smooth = _smooth_notice(stats, method, params)
    if smooth:
        common.note(smooth, quiet=args.quiet)
    for kind, codec in codecs.items():  # which picture videos browsers play
        common.note(common.describe_codec(_outputs(args)[kind], codec), quiet=args.quiet)
    if args.json:
        run_extras.print_summary(stats, method=method, outputs=_outputs(args), codecs=codecs)
    eval_notice = _eval_notice(args, bool(renumbered))  # how to score what was written
    if eval_notice and stats.frames:
        common.note(eval_notice, quiet=args.quiet)
    return 0
