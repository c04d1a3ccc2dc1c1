"""``bgsub compare``: several engines on the same frames, timed and scored side by side."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Dict, List

from bgsub.cli import batch
from bgsub.cli.common import (add_codec_option, add_deprecated, add_output_options,
                              add_preset_option, add_source_options, describe_codec, note,
                              source_kwargs, warn)
from bgsub.errors import InputError

_DESCRIPTION = """\
Run several methods on the same frames (each frame is decoded once and fed to every method) and
compare them: processing speed (frames per second inside each engine, decoding excluded) and,
with ground truth, the seven CDnet 2014 metrics (Recall, Specificity, FPR, FNR, PWC, Precision,
F-measure), scored exactly as `bgsub eval` scores the masks written here.

INPUT is a CDnet sequence folder (input/ + groundtruth/; its ground truth is used), a dataset
root holding several such sequences (root/NAME/ or root/CATEGORY/NAME/: one row per sequence and
method, then per-family means and the mean over families; the family of root/NAME is the part of
NAME before its first '_', e.g. BMS26_cars1 -> BMS26), or any video / image folder / glob (with
--gt for scores).

REPORT_DIR receives report.txt (also printed), report.csv and report.json; report.html, one
self-contained page to open in a browser (the table, charts of the F-measure per method, and per
sequence and family for a dataset root, and a few frames of each input: input, ground truth,
each method's mask); the masks of each method (METHOD/binNNNNNN.png, or METHOD.mkv with
--mask-format mkv); and side_by_side.mp4 (input, ground truth when there is one, and one
labelled mask per method). The ground-truth tiles show CDnet's labels as gray levels: 255
(moving) white, 170 (unknown) light grey, 85 (outside the ROI) mid grey, 50 (shadow) dark grey;
dark blue where a frame has no ground truth. For a dataset root, masks and videos go to
REPORT_DIR/SEQUENCE/. An existing REPORT_DIR that is not empty needs --overwrite, which removes
the outputs of the compare run that wrote there before (those its report.json lists or, without
one, the files named as compare names them) once the input is accepted; other files stay.

Only frames inside the temporal ROI are scored; labels 85 and 170 are ignored. ROI.bmp is
used for a single sequence and ignored for dataset roots (the real CDnet traffic ROI.bmp has the
wrong size); --roi-bmp / --no-roi-bmp override that. An input that ends before its ground truth
does is scored up to its last frame, with a warning and a note in the report saying how many of
the ground-truth frames were scored (as `bgsub eval --last-frame` on its masks); --max-frames
and --stop ask for fewer frames on purpose and draw no warning."""

_EPILOG = """\
examples:
  bgsub samples scenes/ --category pan static                  scenes with ground truth
  bgsub compare scenes/pan_s0 -o cmp/ --methods grbm,compensated,mog2,knn
  bgsub compare scenes/ -o cmp_all/ --no-video                 every sequence, category means
  bgsub compare samples/pan.mp4 --gt scenes/pan_s0 -o cmp_pan/ --max-frames 60 \\
      --methods grbm,mog2 -p mog2.history=200                  one method's parameter
  bgsub compare scenes/pan_s0 -o cmp_small/ --width 160 --methods grbm,mog2 \\
      --mask-format none                                       quick look, no masks written

exit status: 0 done, 2 bad input or output (unknown method, missing input, REPORT_DIR exists),
1 failure while processing
"""


_MASK_FORMATS = ("png", "mkv", "none")

_PARAM_HELP = ("engine parameter (repeatable): METHOD.KEY=VALUE sets one method's, e.g. "
               "mog2.history=200; KEY=VALUE sets it for every method that has KEY, e.g. "
               "history=200 (refused when none has it)")


def add_param_option(parser: Any) -> None:
    """``-p/--param`` of the commands that run several methods (see :func:`parse_method_params`)."""
    parser.add_argument("-p", "--param", action="append", default=[],
                        metavar="[METHOD.]KEY=VALUE", help=_PARAM_HELP)


def with_preset(params: Dict[str, Dict[str, Any]], methods: List[str],
                preset: Any) -> Dict[str, Dict[str, Any]]:
    """``params`` over ``preset``'s values for each of ``methods`` that has presets (the others
    as they are); :class:`InputError` for a preset none of them has."""
    from bgsub.engines import get_engine_spec

    if preset is None:
        return params
    specs = [get_engine_spec(m) for m in methods]
    having = [spec for spec in specs if spec.presets]
    if not having:
        specs[0].preset_values(preset)  # the refusal, naming the engines that have presets
    merged = dict(params)
    for spec in having:
        merged[spec.name] = {**spec.preset_values(preset), **params.get(spec.name, {})}
    return merged


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "compare",
        help="run several methods on the same input: speed, CDnet metrics, side-by-side video",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("input", metavar="INPUT",
                        help="CDnet sequence folder, dataset root, video, image folder or glob")
    parser.add_argument("-o", "--output", required=True, metavar="REPORT_DIR",
                        help="folder for the report, masks and videos (must not exist or be "
                             "empty, unless --overwrite: then the previous compare run's outputs "
                             "there are removed, other files stay)")
    parser.add_argument("-m", "--methods", "--method", dest="methods", default=None,
                        metavar="M1,M2,...",
                        help="comma-separated engines (default: all registered; see "
                             "`bgsub methods`)")
    add_param_option(parser)
    add_preset_option(parser, more=" (of the methods that have presets)")
    parser.add_argument("--gt", default=None, metavar="SEQUENCE",
                        help="CDnet sequence folder with the ground truth of INPUT (default: "
                             "INPUT itself when it is one)")
    scoring = parser.add_argument_group("what is scored")
    scoring.add_argument("--skip-first", action="store_true",
                         help="do not score the first processed frame (the engines have seen "
                              "nothing before it; the project's benchmark rule); frames later "
                              "in the input, e.g. the start of a temporal ROI, are scored")
    roi = scoring.add_mutually_exclusive_group()
    roi.add_argument("--roi-bmp", dest="roi_bmp", action="store_const", const=True,
                     default=None, help="use ROI.bmp even for a dataset root")
    roi.add_argument("--no-roi-bmp", dest="roi_bmp", action="store_const", const=False,
                     help="ignore ROI.bmp even for a single sequence")
    outputs = parser.add_argument_group("outputs")
    outputs.add_argument("--mask-format", choices=_MASK_FORMATS, default="png",
                         help="masks per method: binNNNNNN.png folder, lossless .mkv video, or "
                              "none (default: png)")
    add_deprecated(outputs, "--masks", use="--mask-format", dest="mask_format",
                   choices=_MASK_FORMATS)
    outputs.add_argument("--no-video", action="store_true",
                         help="do not write side_by_side.mp4 (faster on datasets)")
    add_codec_option(outputs)
    outputs.add_argument("--no-report", action="store_true",
                         help="do not write report.html (the page with charts and frames)")
    outputs.add_argument("--tile-height", type=int, default=180, metavar="PX",
                         help="height of each tile of side_by_side.mp4; frames are never "
                              "enlarged and the file size grows with it (default: 180)")
    add_output_options(parser, quiet_help="no progress bar and no notes on stderr (the report "
                                          "table, warnings and errors are still printed)")
    add_source_options(parser)
    parser.add_argument(
        "--max-frames", type=int, default=None, metavar="N",
        help="process at most N frames per sequence (quick runs; note a temporal ROI may start "
             "later, e.g. frame 900 for CDnet traffic)")
    batch.add_parallel_options(parser)  # the sequences of a dataset at once
    parser.set_defaults(handler=run)


def parse_methods(text: str) -> List[str]:
    """``"grbm, mog2"`` -> ``["grbm", "mog2"]``; empty lists and duplicates are refused."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    if not names:
        raise InputError("--methods is empty")
    for k, name in enumerate(names):
        if name in names[:k]:
            raise InputError(f"--methods names {name!r} twice")
    return names


def parse_method_params(pairs: List[str], methods: List[str]) -> Dict[str, Dict[str, Any]]:
    """``["mog2.history=200", "threshold=20"]`` -> ``{"mog2": {"history": 200}, ...}``, typed
    by the engines' params: ``METHOD.KEY=VALUE`` sets one method's parameter, ``KEY=VALUE``
    that of every method in ``methods`` that has ``KEY``.

    Raises :class:`InputError` for a malformed pair, a method not in ``methods``, a ``KEY`` no
    method has, or a parameter the engine does not have.
    """
    from bgsub.engines import get_engine_spec, parse_params
    from bgsub.engines.base import did_you_mean

    grouped: Dict[str, List[str]] = {}
    for pair in pairs:
        key, equals, value = pair.partition("=")
        method, dot, name = key.strip().partition(".")
        if not equals or not key.strip() or (dot and not (method and name)):
            raise InputError(f"--param takes KEY=VALUE or METHOD.KEY=VALUE, e.g. history=200 "
                             f"or mog2.history=200, not {pair!r}")
        if dot and method not in methods:
            raise InputError(f"--param {pair!r}: method {method!r} is not among the methods "
                             f"({', '.join(methods)})")
        targets = [method] if dot else [m for m in methods
                                         if method in get_engine_spec(m).params]
        if not targets and len(methods) > 1:
            names = {n for m in methods for n in get_engine_spec(m).params}
            raise InputError(f"--param {pair!r}: none of the methods ({', '.join(methods)}) "
                             f"has a parameter {method!r}{did_you_mean(method, sorted(names))} "
                             "(see `bgsub methods`)")
        for target in targets or methods:  # (one method: its own error names its parameters)
            grouped.setdefault(target, []).append(f"{name if dot else method}={value}")
    return {method: parse_params(method, rest) for method, rest in grouped.items()}


def run(args: argparse.Namespace) -> int:
    from bgsub.evaluation.compare import compare_methods
    from bgsub.engines import available_engines, get_engine_spec

    if args.methods is not None:  # -m "" is a mistake, not "all"
        methods = parse_methods(args.methods)
        for name in methods:
            get_engine_spec(name)  # unknown names: one line listing the available ones
    else:
        methods = [spec.name for spec in available_engines()]
    params = with_preset(parse_method_params(args.param, methods), methods, args.preset)
    if args.max_frames is not None and args.max_frames < 1:
        raise InputError(f"--max-frames takes a number >= 1, not {args.max_frames}")
    batch.for_workers(args, "input", "output", "gt")
    try:
        report = compare_methods(
            args.input, methods=methods, report_dir=args.output, gt=args.gt, params=params,
            skip_first=args.skip_first,
            ignore_roi_bmp=None if args.roi_bmp is None else not args.roi_bmp,
            max_frames=args.max_frames, masks=args.mask_format, video=not args.no_video,
            html=not args.no_report, video_codec=args.codec,
            tile_height=args.tile_height,
            overwrite=args.overwrite, quiet=args.quiet, **source_kwargs(args),
            workers=batch.jobs_and_threads(args)[0], scheduler=args.scheduler,
        )
    except KeyboardInterrupt as stop:
        partial = getattr(stop, "report", None)
        if partial is not None:  # the frames done before Ctrl-C were scored and reported
            _show(partial, args, "partial report")
        raise
    _show(report, args, "report")
    return 0


def _show(report: Any, args: argparse.Namespace, what: str) -> None:
    print(report.to_text())  # the result itself: printed with --quiet too
    for warning in report.warnings:  # e.g. an input shorter than its ground truth
        warn(warning)
    also = ".csv, .json" if args.no_report else ".csv, .json, .html"
    note(f"{what} written to {Path(args.output) / 'report.txt'} ({also})", quiet=args.quiet)
    codec = report.settings.get("video_codec")
    if codec:
        note(describe_codec("side_by_side.mp4", codec), quiet=args.quiet)
