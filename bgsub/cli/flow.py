"""``bgsub flow``: the optical flow the gated RBM reads between two images, or along a video."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Optional

import numpy as np

from bgsub.cli.common import add_output_options, add_source_options, note, progress, source_kwargs
from bgsub.errors import InputError, OutputError

_DESCRIPTION = """\
Estimate the motion between two images with a gated RBM (default: the shipped `natural` model,
trained on photographs) and write it as a Middlebury .flo file: one (u, v) vector per pixel of
FRAME1 at its full size, u to the right and v down, "unknown" where no textured patch covers the
pixel (flat areas). Read it back with bgsub.flowio.read_flo or any Middlebury tool.
Motion larger than the model's few pixels is handled coarse to fine (an image pyramid whose
camera motion pre-warps the next level).

With one input that is a video, an image folder or a glob, writes a video of the colour-coded
flow of every consecutive frame pair instead.

Colour code (Middlebury): hue = direction (right red, down yellow, left cyan, up blue/violet),
saturation = speed (white = still), black = unknown."""

_EPILOG = """\
examples:
  bgsub flow frame10.png frame11.png -o flow.flo
  bgsub flow frame10.png frame11.png -o flow.flo --vis flow.png
  bgsub flow a.jpg b.jpg -o ab.flo --vis ab_arrows.png --arrows --arrow-step 12
  bgsub flow a.png b.png -o ab.flo --model dots-translation-3px
  bgsub flow clip.mp4 -o clip_flow.mp4 --max-motion 30 --stop 100
"""

_PICTURE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"}


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
                        help="draw arrows over the first frame instead of the colour code")
    parser.add_argument("--arrow-step", type=int, default=16, metavar="PX",
                        help="arrow grid spacing (default 16)")
    parser.add_argument("--max-magnitude", type=float, default=None, metavar="PX",
                        help="speed shown fully saturated (default: the largest in each picture)")
    parser.add_argument("--model", default="natural", metavar="M",
                        help="shipped model name (natural, dots-translation, ...) or a .npz path "
                             "(default: natural)")
    est = parser.add_argument_group("estimation")
    est.add_argument("--max-motion", type=float, default=20.0, metavar="PX",
                     help="largest motion to expect, plans the pyramid (default 20)")
    est.add_argument("--levels", type=int, default=None, metavar="N",
                     help="pyramid levels (default: enough for --max-motion; 1 = no pyramid)")
    est.add_argument("--stride", type=int, default=6, metavar="PX",
                     help="patch grid step (default 6; smaller = finer field, slower)")
    add_source_options(parser)
    add_output_options(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from bgsub.rbm import load_model

    if args.arrow_step < 2:
        raise InputError(f"--arrow-step must be at least 2, not {args.arrow_step}")
    if args.stride < 1:
        raise InputError(f"--stride must be at least 1, not {args.stride}")
    if args.frame2 is None:
        if args.vis is not None:
            raise InputError("--vis is for an image pair; for a video, -o is already the picture video")
        _check_video_output(args.output, overwrite=args.overwrite)
        model = load_model(args.model)
        return _run_video(args, model)
    ignored = [f"--{name}" for name, default in (("start", 0), ("stop", None), ("step", 1),
                                                  ("scale", None), ("width", None))
               if getattr(args, name) != default]
    if ignored:
        raise InputError(f"{', '.join(ignored)}: frame range and resizing apply to a video input, "
                         "not to an image pair")
    _check_pair_outputs(args)
    model = load_model(args.model)
    return _run_pair(args, model)


def _estimate(frame1: np.ndarray, frame2: np.ndarray, model: Any, args: argparse.Namespace,
              prior: Optional[np.ndarray] = None):
    from bgsub.flowfield import estimate_flow

    return estimate_flow(frame1, frame2, model=model, stride=args.stride, levels=args.levels,
                         max_motion=args.max_motion, prior=prior, dense=True)


def _check_pair_outputs(args: argparse.Namespace) -> None:
    out = Path(args.output)
    if out.suffix.lower() != ".flo":
        raise OutputError(f"-o takes a .flo file for an image pair, not {out} (use --vis for a picture)")
    outputs = [out]
    if args.vis is not None:
        vis = Path(args.vis)
        if vis.suffix.lower() not in _PICTURE_SUFFIXES:
            raise OutputError(f"--vis: cannot write a picture with this extension: {vis} "
                              f"(use {', '.join(sorted(_PICTURE_SUFFIXES))})")
        if vis.resolve() == out.resolve():
            raise OutputError(f"--vis and -o are the same file: {vis}")
        outputs.append(vis)
    for path in outputs:
        if path.exists() and not args.overwrite:
            raise OutputError(f"output exists (use --overwrite to replace it): {path}")
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise OutputError(f"cannot write {path}: folder {folder} does not exist")


def _run_pair(args: argparse.Namespace, model: Any) -> int:
    from bgsub.flowio import flow_picture, read_image, write_flo

    frame1, frame2 = read_image(args.input), read_image(args.frame2)
    h, w = frame1.shape[:2]
    if frame2.shape[:2] != (h, w):
        h2, w2 = frame2.shape[:2]
        raise InputError(f"images differ in size: {args.input} is {w}x{h}, {args.frame2} is {w2}x{h2}")
    p = model.patch_size
    if min(h, w) < p:
        raise InputError(f"{args.input} is {w}x{h}, smaller than one {p}x{p} patch")
    estimate = _estimate(frame1, frame2, model, args)
    flow = estimate.dense
    write_flo(args.output, flow, overwrite=args.overwrite)
    if args.vis is not None:
        picture = flow_picture(flow, image=frame1, arrows=args.arrows, step=args.arrow_step,
                               max_magnitude=args.max_magnitude)
        _write_picture(Path(args.vis), picture)
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


def _write_picture(path: Path, picture: np.ndarray) -> None:
    import cv2

    ok, data = cv2.imencode(path.suffix.lower(), picture)
    if not ok:
        raise OutputError(f"cannot encode a picture as {path.suffix}: {path}")
    try:
        data.tofile(str(path))
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror or err}") from None


def _check_video_output(output: str, *, overwrite: bool) -> None:
    from bgsub.sinks import check_video_output

    if Path(output).suffix.lower() == ".flo":
        raise OutputError(f"{output}: a video input gives a picture video (-o clip_flow.mp4); "
                          "give two images for a .flo file")
    check_video_output(output, overwrite=overwrite)


def _run_video(args: argparse.Namespace, model: Any) -> int:
    from bgsub.flowio import flow_picture
    from bgsub.sinks import VideoSink
    from bgsub.sources import open_source

    with open_source(args.input, **source_kwargs(args)) as source:
        info = source.info
        fps = info.fps / max(1, args.step)
        previous = None
        prior = None
        written = 0
        with VideoSink(args.output, fps=fps, width=info.width, height=info.height,
                       overwrite=args.overwrite) as sink:
            for _, frame in progress(source, total=info.frame_count, desc="flow", quiet=args.quiet):
                if previous is not None:
                    estimate = _estimate(previous, frame, model, args, prior=prior)
                    prior = estimate.prewarp  # the camera rarely changes motion abruptly
                    sink.write(flow_picture(estimate.dense, image=previous, arrows=args.arrows,
                                            step=args.arrow_step, max_magnitude=args.max_magnitude))
                    written += 1
                previous = frame
    if written == 0:
        raise InputError(f"{args.input}: needs at least two frames for a flow video")
    note(f"{written} flow pictures (one per consecutive frame pair) written to {args.output}",
         quiet=args.quiet)
    return 0
