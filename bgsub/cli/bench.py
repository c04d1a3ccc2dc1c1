"""``bgsub bench``: frames per second of each engine on a generated clip."""

from __future__ import annotations

import argparse
import json
import re
from typing import Any, Tuple

from bgsub.cli.common import add_deprecated, add_preset_option
from bgsub.cli.compare import add_param_option, parse_method_params, parse_methods, with_preset
from bgsub.errors import InputError

_DESCRIPTION = """\
Measure how many frames per second each engine processes. A synthetic moving-camera clip is
generated in memory first, so only the engine's per-frame step (apply) is timed: decoding and
writing are excluded. Each method runs --repeats times on a fresh engine (after one untimed
warm-up frame) and the median is reported, with the machine described (CPU, cores, numpy/OpenCV
versions, BLAS threads, date). For figures you will publish, close other programs and set the
thread count you mean to use (e.g. OMP_NUM_THREADS=1)."""

_EPILOG = """\
examples:
  bgsub bench                                      all engines, 320x240, 50 frames, 3 repeats
  bgsub bench --methods grbm,mog2 --size 640x480 --max-frames 100 --repeats 1
  bgsub bench --methods mog2 --memory --json       also peak memory, as JSON
  OMP_NUM_THREADS=1 bgsub bench --methods grbm     single-threaded figure
  bgsub bench --presets --accuracy real.json --accuracy gen.json   each preset of grbm vs MOG2
"""


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "bench",
        help="frames per second of each engine on a generated clip",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--size", default="320x240", metavar="WxH",
                        help="frame size, at least 16x16, odd sizes too: nothing is written "
                             "(default: 320x240; below 64x48, the smallest sample scene, the "
                             "clip is a panning random texture)")
    parser.add_argument("-m", "--methods", "--method", dest="methods", default=None,
                        metavar="M1,M2",
                        help="comma-separated engines (default: all registered; see "
                             "`bgsub methods`)")
    parser.add_argument("--max-frames", type=int, default=50, metavar="N",
                        help="timed frames per run (default: 50)")
    add_deprecated(parser, "--frames", use="--max-frames", dest="max_frames", type=int,
                   metavar="N")
    parser.add_argument("--repeats", type=int, default=3, metavar="R",
                        help="runs per method; the median is reported (default: 3)")
    add_param_option(parser)
    add_preset_option(parser, more=" (of the methods that have presets)")
    parser.add_argument("--presets", action="store_true",
                        help="one table: each preset of grbm (or of the one -m method), its fps "
                             "and its fps as a multiple of MOG2's, timed alternating in one "
                             "process, and its development F from --accuracy")
    parser.add_argument("--accuracy", action="append", default=[], metavar="FILE",
                        help="with --presets: the real and generated development F of the "
                             "presets, from files `benchmarks/accuracy.py --set SET --preset NAME "
                             "--json FILE` writes (repeatable; default: shown as -)")
    parser.add_argument("--memory", action="store_true",
                        help="also report peak memory (ru_maxrss), each method in its own process")
    parser.add_argument("--seed", type=int, default=0, help="seed of the generated clip")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar (the report is still printed)")
    parser.set_defaults(handler=run)


def parse_size(text: str) -> Tuple[int, int]:
    """``"320x240"`` -> ``(320, 240)``; :class:`InputError` otherwise."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match:
        raise InputError(f"--size takes WIDTHxHEIGHT, e.g. 320x240, not {text!r}")
    return int(match.group(1)), int(match.group(2))


def run(args: argparse.Namespace) -> int:
    from bgsub.evaluation.bench import bench_methods
    from bgsub.cli.common import progress
    from bgsub.engines import available_engines

    width, height = parse_size(args.size)
    if args.presets:
        return _run_presets(args, width, height)
    if args.accuracy:
        raise InputError("--accuracy is for --presets")
    # -m "" is a mistake, not "all" (as in `bgsub compare`)
    methods = (parse_methods(args.methods) if args.methods is not None
               else [spec.name for spec in available_engines()])
    params = with_preset(parse_method_params(args.param, methods), methods, args.preset)
    report = bench_methods(
        methods=methods, width=width, height=height, frames=args.max_frames, repeats=args.repeats,
        params=params, memory=args.memory, seed=args.seed,
        progress=lambda it, total, desc: progress(it, total=total, desc=desc, quiet=args.quiet,
                                                  unit="method"),
    )
    _print(report, args)
    return 0


def _run_presets(args: argparse.Namespace, width: int, height: int) -> int:
    """``bgsub bench --presets``: every preset of one engine beside MOG2."""
    from bgsub.engines import default_method
    from bgsub.evaluation.bench_presets import bench_presets, read_accuracy

    methods = parse_methods(args.methods) if args.methods is not None else [default_method()]
    if len(methods) != 1 or args.preset or args.memory:
        raise InputError("--presets times every preset of one method (-m NAME) beside mog2; "
                         "it takes no --preset or --memory")
    params = parse_method_params(args.param, methods).get(methods[0], {})
    report = bench_presets(method=methods[0], width=width, height=height,
                           frames=args.max_frames, repeats=args.repeats, params=params,
                           seed=args.seed, accuracy=read_accuracy(args.accuracy))
    _print(report, args)
    return 0


def _print(report: Any, args: argparse.Namespace) -> None:
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(report.to_text())
