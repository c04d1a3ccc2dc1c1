"""``bgsub flow``: the optical flow the gated RBM reads between two images, or along a video."""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any, List, Optional, Tuple

import numpy as np

from bgsub.cli.common import (add_codec_option, add_output_options, add_source_options,
                              check_distinct, describe_codec, is_binary_model, model_files, note,
                              progress, source_kwargs, warn, warn_if_binary_model,
                              warn_if_binary_model_on_source)
from bgsub.errors import InputError, OutputError
from bgsub.motion.config import FlowConfig

_DESCRIPTION = """\
Estimate the motion between two images with a gated RBM (default: the shipped `natural` model,
trained on photographs) and write it as a Middlebury .flo file: one (u, v) vector per pixel of
FRAME1 at its full size, u to the right and v down, "unknown" where no textured patch covers the
pixel (flat areas). Read it back with bgsub.io.flowio.read_flo or any Middlebury tool.
Motion larger than the model's few pixels is handled coarse to fine (an image pyramid whose
camera motion pre-warps the next level).

With one input that is a video, an image folder or a glob, writes a video of the colour-coded
flow of every consecutive frame pair instead.

Two readouts (--readout): "patch" reads one displacement per patch on an image pyramid (camera
motion fitted coarse to fine), for photographs and video; "max-flow" is the paper's max-flow
field (Algorithm 2): each pixel's strongest outgoing connection in the patch pair around it,
one level, no fitting. The random-dot models (dots-translation, dots-rotation, ...) read
random-dot images with max-flow by default, as the paper does; other models with patch.

Colour code (Middlebury): hue = direction (right red, down yellow, left cyan, up blue/violet),
saturation = speed (white = still), black = unknown. Each colour picture carries its legend in
the bottom-right corner (unless --no-legend): the colour wheel, whose rim moves at the speed
written beside it (--max-magnitude, or the picture's largest)."""

_EPILOG = """\
examples:
  bgsub samples scenes/ --category pan                          frames to read
  bgsub flow scenes/pan_s0/input/in000010.jpg scenes/pan_s0/input/in000011.jpg -o f.flo
  bgsub flow scenes/pan_s0/input/in000010.jpg scenes/pan_s0/input/in000011.jpg -o a.flo \\
      --vis arrows.png --arrows --arrow-step 12                 arrows, as in the paper
  bgsub flow samples/pan.mp4 -o pan_flow.mp4 --max-motion 30 --stop 40
"""

_PICTURE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}
_ARROW_STEP = 16  # default of --arrow-step
# The reader's settings are the grbm engine's (FlowConfig's defaults); the options replace some.
_FLOW = FlowConfig()
_READOUTS = ("patch", "max-flow")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "flow",
        help="optical flow between two images (.flo) or along a video (colour-coded video)",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("input", metavar="FRAME1|VIDEO", help="first image, or a video / image folder / glob")
    parser.add_argument("frame2", metavar="FRAME2", nargs="?", default=None,
                        help="second image (same size as FRAME1); omit for a video")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="flow.flo for an image pair; a video (.mp4, .avi, .mkv) for a video")
    parser.add_argument("--vis", metavar="PICTURE", default=None,
                        help="image pair: also write a picture of the flow (.png, .jpg, ...)")
    parser.add_argument("--arrows", action="store_true",
                        help="draw arrows over the first frame instead of the colour code "
                             "(in the --vis picture, or in the video)")
    parser.add_argument("--arrow-step", type=int, default=_ARROW_STEP, metavar="PX",
                        help=f"arrow grid spacing, at least 2 (default {_ARROW_STEP})")
    parser.add_argument("--max-magnitude", type=float, default=None, metavar="PX",
                        help="speed shown fully saturated, above 0 (default: the largest in each "
                             "picture)")
    parser.add_argument("--no-legend", action="store_true",
                        help="no colour wheel and speed scale in the corner of colour pictures")
    parser.add_argument("--model", default="natural", metavar="M",
                        help="shipped model name (natural, dots-translation, ...) or a .npz path "
                             "(default: natural)")
    est = parser.add_argument_group("estimation")
    est.add_argument("--readout", choices=_READOUTS, default=None,
                     help="patch: patch displacements on an image pyramid; max-flow: the "
                          "paper's per-pixel max-flow field, one level (default: max-flow for "
                          "random-dot models, else patch)")
    est.add_argument("--max-motion", type=float, default=None, metavar="PX",
                     help="largest motion to expect, above 0; plans the pyramid and, on frames "
                          "too small for the levels it needs, widens the coarsest search "
                          f"(slower) (default {_FLOW.max_motion:g}; patch readout)")
    est.add_argument("--levels", type=int, default=None, metavar="N",
                     help="pyramid levels, at least 1 (default: enough for --max-motion; "
                          "1 = no pyramid; patch readout)")
    est.add_argument("--stride", type=int, default=None, metavar="PX",
                     help="patch grid step, at least 1 (at most the patch size with max-flow) "
                          f"(default {_FLOW.stride}, or the patch size if smaller; smaller = finer "
                          "field, slower)")
    add_codec_option(parser)
    add_source_options(parser)
    add_output_options(parser, quiet_help="no progress bar and no notes on stderr (warnings "
                                          "and errors are still printed)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from bgsub.model.rbm import load_model

    _check_options(args)
    if args.frame2 is None:
        _check_video_output(args)
    else:
        _check_pair_outputs(args)
    model = load_model(args.model)
    _choose_readout(args, model)
    return _run_video(args, model) if args.frame2 is None else _run_pair(args, model)


def _choose_readout(args: argparse.Namespace, model: Any) -> None:
    """Settle ``args.readout`` for ``model`` and refuse the options it would ignore.

    A random-dot model (binary output units) is read with max-flow by default: the paper's
    readout, and the only one it was made for. Its pyramid levels would be blurred dots, gray
    values such a model never saw, and its range is a pixel or so, at the edge of which the
    patch readout takes a reading for a larger motion clipped."""
    if args.readout is None:
        args.readout = "max-flow" if is_binary_model(model) else "patch"
    if args.stride is None:
        args.stride = min(_FLOW.stride, int(model.patch_size))
    if args.readout == "patch":
        if is_binary_model(model):
            # One level, and motions within the model's range (readings at its edge kept).
            from bgsub.motion.flowfield import model_range

            args.levels = 1 if args.levels is None else args.levels
            if args.max_motion is None:
                args.max_motion = float(model_range(model))
        elif args.max_motion is None:
            args.max_motion = _FLOW.max_motion
        return
    planned = [flag for flag, value in (("--max-motion", args.max_motion),
                                        ("--levels", args.levels)) if value is not None]
    if planned:
        raise InputError(f"{', '.join(planned)}: plan the pyramid of --readout patch; "
                         "--readout max-flow reads one level")
    if args.stride > model.patch_size:
        raise InputError(f"--stride {args.stride}: --readout max-flow needs a step of at most "
                         f"the model's patch size {model.patch_size} (every pixel in a patch)")


# The checks below raise InputError rather than using argparse `type=` functions: argparse would
# print its usage block and exit itself, where the project wants one `bgsub: error:` line.

def _check_options(args: argparse.Namespace) -> None:
    """Refuse option values and combinations that would fail late or be silently ignored."""
    if args.arrow_step < 2:
        raise InputError(f"--arrow-step must be at least 2, not {args.arrow_step}")
    if args.stride is not None and args.stride < 1:
        raise InputError(f"--stride must be at least 1, not {args.stride}")
    if args.levels is not None and args.levels < 1:
        raise InputError(f"--levels must be at least 1 (1 = no pyramid), not {args.levels}")
    if args.max_motion is not None:
        _check_positive("--max-motion", args.max_motion)
    if args.max_magnitude is not None:
        _check_positive("--max-magnitude", args.max_magnitude)
    if args.frame2 is None:
        if args.vis is not None:
            raise InputError("--vis is for an image pair; for a video, -o is already the picture video")
    else:
        ignored = _given(args, (*_VIDEO_ONLY, ("codec", "auto")))
        if ignored:
            raise InputError(f"{', '.join(ignored)}: frame range, resizing and the video "
                             "codec apply to a video input, not to an image pair")
        # For a pair the .flo file holds no picture: without --vis these would silently do nothing.
        unused = _given(args, _PICTURE_ONLY) if args.vis is None else []
        if unused:
            raise InputError(f"{', '.join(unused)}: for an image pair, picture options need "
                             "--vis PICTURE (the .flo file holds no picture)")
    # The colour code has no grid: without --arrows the spacing would silently do nothing.
    if args.arrow_step != _ARROW_STEP and not args.arrows:
        raise InputError("--arrow-step needs --arrows (it spaces the arrows; the colour code "
                         "has none)")


# Options (with their defaults) that only a video input uses, and that only a picture uses.
_VIDEO_ONLY = (("start", 0), ("stop", None), ("step", 1), ("scale", None), ("width", None))
_PICTURE_ONLY = (("arrows", False), ("arrow_step", _ARROW_STEP), ("max_magnitude", None),
                 ("no_legend", False))


def _given(args: argparse.Namespace, options: Tuple[Tuple[str, Any], ...]) -> List[str]:
    """The flags among ``options`` whose value is not the default, as typed (``--arrow-step``)."""
    return [f"--{name.replace('_', '-')}" for name, default in options
            if getattr(args, name) != default]


def _check_positive(flag: str, value: float) -> None:
    # float() accepts "nan" and "inf", which pass every comparison check or none: refuse them.
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"{flag} must be a number above 0 (pixels), not {value:g}")


def _check_patch_fits(model: Any, width: int, height: int, what: str) -> None:
    """The same refusal for an image pair and a video: no patch fits, so there is no flow."""
    p = model.patch_size
    if min(width, height) < p:
        raise InputError(f"{what} {width}x{height}, smaller than one {p}x{p} patch of the model")


def _input_paths(args: argparse.Namespace) -> List[str]:
    """What the command reads: the frames, and the model when it is a file, not a shipped name."""
    return [args.input, args.frame2 or ""] + model_files(args.model)


# The widest grid of coarsest-level starts --max-motion may ask for ((2 s + 1)^2 readouts there).
_MAX_SEARCH = 8


def _search_for(shape: Tuple[int, int], model: Any, args: argparse.Namespace) -> int:
    """The grid of coarsest-level starts that lets the pyramid a frame of ``shape`` (H, W)
    allows read --max-motion: small frames allow fewer levels than it needs (FlowConfig's
    default when the levels reach it alone, or with --levels; 0 with one level)."""
    from bgsub.motion.flowfield import model_range, pyramid_reach

    if args.levels is not None:
        return _FLOW.search
    # The pyramid estimate_flow plans for the same frame, model and --max-motion.
    pyramid = pyramid_reach(shape, max_motion=args.max_motion, model_disp=model_range(model),
                            patch_size=int(model.patch_size))
    search = pyramid.search_for(args.max_motion, limit=_MAX_SEARCH)
    if pyramid.levels > 1:  # (one level reads no grid of starts)
        search = max(_FLOW.search, search)
    reach = pyramid.reach(search)
    if reach < args.max_motion and not getattr(args, "reach_warned", False):
        warn(f"--max-motion {args.max_motion:g} is beyond what {shape[1]}x{shape[0]} frames "
             f"allow: motions above about {reach} px are misread")
        args.reach_warned = True  # once per run
    return search


def _estimate(frame1: np.ndarray, frame2: np.ndarray, model: Any, args: argparse.Namespace,
              prior: Optional[np.ndarray] = None) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """The flow from ``frame1`` to ``frame2`` with ``args.readout``: ``(dense, prewarp)``, the
    ``(H, W, 2) float32`` field (NaN unknown) and the camera motion to start the next pair
    from (None with max-flow, which fits none)."""
    if args.readout == "max-flow":
        from bgsub.model.readout import max_flow_image

        return max_flow_image(model, frame1, frame2, stride=args.stride), None
    from bgsub.motion.flowfield import estimate_flow

    search = _search_for(frame1.shape[:2], model, args)  # (says it in CLI words: warn_range off)
    config = dataclasses.replace(_FLOW, stride=args.stride, levels=args.levels or 0,
                                 max_motion=args.max_motion, search=search, dense=True,
                                 warn_range=False)
    estimate = estimate_flow(frame1, frame2, config, model=model, prior=prior)
    return estimate.dense, estimate.prewarp


def _check_pair_outputs(args: argparse.Namespace) -> None:
    from bgsub.io.sinks import check_file_output

    check_distinct(_input_paths(args), [("-o", args.output), ("--vis", args.vis)])
    out = Path(args.output)
    if out.suffix.lower() != ".flo":
        raise OutputError(f"-o takes a .flo file for an image pair, not {out} (use --vis for a picture)")
    check_file_output(out, overwrite=args.overwrite)
    if args.vis is not None:
        vis = Path(args.vis)
        if vis.suffix.lower() not in _PICTURE_SUFFIXES:
            raise OutputError(f"--vis: cannot write a picture with this extension: {vis} "
                              f"(use {', '.join(sorted(_PICTURE_SUFFIXES))})")
        check_file_output(vis, overwrite=args.overwrite)


def _run_pair(args: argparse.Namespace, model: Any) -> int:
    from bgsub.io.flowio import flow_picture, read_image, write_flo, write_image

    frame1, frame2 = read_image(args.input), read_image(args.frame2)
    h, w = frame1.shape[:2]
    if frame2.shape[:2] != (h, w):
        h2, w2 = frame2.shape[:2]
        raise InputError(f"images differ in size: {args.input} is {w}x{h}, {args.frame2} is {w2}x{h2}")
    _check_patch_fits(model, w, h, f"{args.input} is")
    warn_if_binary_model(model, frame1, what=args.input)
    flow, _ = _estimate(frame1, frame2, model, args)
    write_flo(args.output, flow, overwrite=args.overwrite)
    if args.vis is not None:
        picture = flow_picture(flow, image=frame1, arrows=args.arrows, step=args.arrow_step,
                               max_magnitude=args.max_magnitude, legend=not args.no_legend)
        write_image(args.vis, picture)
    known = np.isfinite(flow).all(axis=2)
    if known.any():
        speed = np.hypot(flow[known, 0], flow[known, 1])
        summary = (f"flow of {w}x{h} written to {args.output}: {100 * known.mean():.0f}% of pixels "
                   f"known, median motion {np.median(speed):.2f} px, largest {speed.max():.2f} px")
    else:
        summary = (f"flow of {w}x{h} written to {args.output}: no pixel has an estimate "
                   "(no textured patch: flat images?)")
    note(summary, quiet=args.quiet)
    return 0


def _check_video_output(args: argparse.Namespace) -> None:
    from bgsub.io.sinks import check_video_output

    check_distinct(_input_paths(args), [("-o", args.output)])
    if Path(args.output).suffix.lower() == ".flo":
        from bgsub.io.sources import IMAGE_EXTENSIONS

        if Path(args.input).suffix.lower() in IMAGE_EXTENSIONS:
            raise InputError(f"{args.input} is one image: a .flo file needs the pair "
                             f"(bgsub flow FRAME1 FRAME2 -o {args.output})")
        raise OutputError(f"{args.output}: a video input gives a picture video (-o clip_flow.mp4); "
                          "give two images for a .flo file")
    check_video_output(args.output, overwrite=args.overwrite)


def _run_video(args: argparse.Namespace, model: Any) -> int:
    from bgsub.io.flowio import flow_picture
    from bgsub.io.sinks import VideoSink
    from bgsub.io.sources import open_source

    with open_source(args.input, **source_kwargs(args)) as source:
        info = source.info
        _check_patch_fits(model, info.width, info.height, f"frames of {args.input} are")
        warn_if_binary_model_on_source(model, source, what=args.input)
        fps = info.fps / max(1, args.step)
        previous = None
        prior = None
        written = 0
        with VideoSink(args.output, fps=fps, width=info.width, height=info.height,
                       overwrite=args.overwrite, codec=args.codec) as sink:
            for _, frame in progress(source, total=info.frame_count, desc="flow", quiet=args.quiet):
                if previous is not None:
                    # The camera rarely changes motion abruptly: the next pair starts from it.
                    dense, prior = _estimate(previous, frame, model, args, prior=prior)
                    sink.write(flow_picture(dense, image=previous, arrows=args.arrows,
                                            step=args.arrow_step, max_magnitude=args.max_magnitude,
                                            legend=not args.no_legend))
                    written += 1
                previous = frame
    short = source.truncation()  # decoding ended well before the end the video declares
    if short:
        warn(short)
    if written == 0:
        raise InputError(f"{args.input}: needs at least two frames for a flow video")
    note(f"{written} flow pictures (one per consecutive frame pair) written to {args.output}",
         quiet=args.quiet)
    note(describe_codec(args.output, sink.codec), quiet=args.quiet)
    return 0
