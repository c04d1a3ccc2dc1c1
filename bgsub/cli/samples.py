"""``bgsub samples``: write synthetic moving-camera scenes with exact ground truth."""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import List, Optional, Tuple

from bgsub.cli.common import add_deprecated, add_output_options, note, progress
from bgsub.errors import InputError, OutputError
from bgsub.samples import (
    CATEGORIES,
    SceneSpec,
    check_video_size,
    copy_bundled_sample,
    generate_scene,
)

_DESCRIPTION = """\
Write synthetic scenes with exact ground truth, in the CDnet 2014 layout: a textured world seen
through a moving camera, with 2-4 objects that move on their own and enter and leave the view.
Each scene DIR/<category>_s<seed>/ holds input/in000001.jpg ..., groundtruth/gt000001.png ...
(0 background, 255 foreground, 170 the antialiased 1-pixel object rim), temporalROI.txt,
<category>_s<seed>.mp4 (the input as a video) and camera_motion.npy ((n, 3, 3) float64: entry k
maps pixel coordinates of frame k-1 to frame k). The first fifth of the frames (at most 24) show
the background alone, a warm-up outside the temporal ROI as in CDnet. The same seed gives the
same scene."""

_EPILOG = """\
examples:
  bgsub samples                                   every category, seed 0, into bgsub-samples/
  bgsub samples scenes/ --category pan --seed 0   the scene shipped as samples/pan.mp4
  bgsub samples scenes/ --category pan jitter --seed 0 1 2 --max-frames 60
  bgsub samples scenes/ --size 640x480 --overwrite
  bgsub samples --list                            the categories and what their camera does
  bgsub samples --pan                             copy the bundled sample video to samples/pan.mp4
"""


_DEFAULT_DIR = "bgsub-samples"
_PAN_DIR = "samples"


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "samples", help="write synthetic moving-camera scenes with ground truth",
        description=_DESCRIPTION, epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dir", nargs="?", default=None, metavar="DIR",
                        help=f"folder to write the scenes into (default: {_DEFAULT_DIR})")
    parser.add_argument("-c", "--category", action="extend", nargs="+", metavar="NAME",
                        help="scene categories, separated by spaces or commas (default: all; "
                             "see --list); put DIR before this option")
    parser.add_argument("-s", "--seed", action="extend", nargs="+", metavar="S",
                        help="random seeds, one scene per seed and category (default: 0)")
    parser.add_argument("--max-frames", type=int, default=SceneSpec.n_frames, metavar="N",
                        help=f"frames per scene (default: {SceneSpec.n_frames}; the first "
                             "fifth, at most 24, is an object-free warm-up outside the "
                             "temporal ROI)")
    add_deprecated(parser, "-n", "--frames", use="--max-frames", dest="max_frames", type=int,
                   metavar="N")
    parser.add_argument("--size", default="320x240", metavar="WxH",
                        help="frame size, at least 64x48, both even for the scene's .mp4 "
                             "(default: 320x240)")
    parser.add_argument("--list", action="store_true",
                        help="print the categories and exit")
    parser.add_argument("--pan", action="store_true",
                        help=f"only copy the bundled sample video (the pan scene of seed 0) to "
                             f"DIR/pan.mp4 (default DIR: {_PAN_DIR}), the file the examples of "
                             "`bgsub --help` read")
    add_output_options(parser, quiet_help="no progress bar, no list of the scenes written and "
                                          "no notes (warnings and errors are still printed)")
    parser.set_defaults(handler=run)


def _split(values: Optional[List[str]]) -> List[str]:
    return [part.strip() for value in values or [] for part in value.split(",") if part.strip()]


def parse_size(text: str) -> Tuple[int, int]:
    """``"320x240"`` -> ``(320, 240)``; :class:`InputError` for anything else."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not match:
        raise InputError(f"--size takes WIDTHxHEIGHT, e.g. 320x240, not {text!r}")
    return int(match.group(1)), int(match.group(2))


def _dir_hint(value: str, option: str, dir_given: bool) -> str:
    """What to add to the refusal of ``value`` given to ``option`` when it may be DIR: both
    options take several values, so `--category pan scenes/` reads scenes/ as a category."""
    if "/" in value or "\\" in value or not dir_given:
        return (f"; if {value!r} is the output folder, put DIR before {option} "
                f"(bgsub samples {value} {option} ...)")
    return ""


def _seeds(values: Optional[List[str]], dir_given: bool = True) -> List[int]:
    seeds = []
    for part in _split(values) or ["0"]:
        if not part.isdigit():
            raise InputError(f"--seed takes non-negative integers, not {part!r}"
                             + _dir_hint(part, "--seed", dir_given))
        seeds.append(int(part))
    return list(dict.fromkeys(seeds))


def _categories(values: Optional[List[str]], dir_given: bool = True) -> List[str]:
    if values is not None and not _split(values):  # "-c ," names nothing: not "all"
        raise InputError("--category is empty (give names, or leave it out for all)")
    names = _split(values) or list(CATEGORIES)
    for name in names:
        if name not in CATEGORIES:
            raise InputError(f"unknown category {name!r} (available: {', '.join(CATEGORIES)})"
                             + _dir_hint(name, "--category", dir_given))
    return list(dict.fromkeys(names))


def _copy_pan(args: argparse.Namespace) -> int:
    if args.category or args.seed:
        raise InputError("--pan copies the bundled video alone; leave out --category and --seed "
                         "(or --pan, to render scenes)")
    path = copy_bundled_sample(args.dir or _PAN_DIR, overwrite=args.overwrite)
    note(f"wrote {path} (the pan scene of seed 0; try `bgsub run {path} -o pan_masks.mkv`)",
         quiet=args.quiet)
    return 0


def run(args: argparse.Namespace) -> int:
    if args.list:
        width = max(map(len, CATEGORIES))
        for name, description in CATEGORIES.items():
            print(f"{name:<{width}}  {description}")
        return 0
    if args.pan:
        return _copy_pan(args)
    width, height = parse_size(args.size)
    dir_given = args.dir is not None
    specs = [SceneSpec(category, seed=seed, width=width, height=height, n_frames=args.max_frames)
             for category in _categories(args.category, dir_given)
             for seed in _seeds(args.seed, dir_given)]
    check_video_size(width, height)  # before anything is written (generate_scene checks it too)
    out_dir = Path(args.dir if dir_given else _DEFAULT_DIR)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputError(f"{out_dir} exists and is not a folder")
    if not args.overwrite:  # refuse before writing anything
        for spec in specs:
            if (out_dir / spec.name).exists():
                raise OutputError(
                    f"{out_dir / spec.name} already exists (use --overwrite to replace it)")
    bar = progress(None, total=sum(s.n_frames for s in specs), desc="samples",
                   quiet=args.quiet)
    written = []
    try:
        for spec in specs:
            bar.set_postfix_str(spec.name, refresh=False)
            written.append(generate_scene(spec, out_dir, overwrite=args.overwrite,
                                          on_frame=bar.update))
    finally:
        bar.close()
    if not args.quiet:
        for spec, path in zip(specs, written):
            print(f"{path}  {spec.n_frames} frames {spec.width}x{spec.height}, "
                  f"temporal ROI {spec.roi_start}-{spec.n_frames}")
        noun = "scene" if len(written) == 1 else "scenes"
        note(f"wrote {len(written)} {noun} to {out_dir} (each: input/, groundtruth/, "
             "temporalROI.txt, camera_motion.npy, <name>.mp4)")
    return 0
