"""``bgsub eval``: CDnet 2014 metrics of predicted masks against ground truth."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from bgsub.cli import batch
from bgsub.cli.common import warn
from bgsub.errors import InputError, OutputError
from bgsub.io.sinks import check_file_output

_DESCRIPTION = """\
Score predicted foreground masks against CDnet 2014 ground truth: Recall, Specificity, FPR,
FNR, PWC, Precision and F-measure, with the TP/FP/FN/TN pixel counts.

PRED is a folder of binNNNNNN.png masks or a mask video (frame 1 = bin000001.png = gt000001.png);
a pixel is foreground when > 127. GROUNDTRUTH is a CDnet sequence folder (groundtruth/gtNNNNNN.png,
optional temporalROI.txt and ROI.bmp), or a dataset root holding several sequences at any depth;
then PRED is a folder holding one prediction per sequence (NAME/ or NAME.mkv, or the same
relative path as in the dataset, e.g. cameraJitter/traffic/), and the results are averaged the
CDnet way: a category is the mean of its sequences, overall is the mean of the categories.
The category of root/CATEGORY/NAME is CATEGORY; of root/NAME, the part of NAME before its first
'_' (BMS26_cars1 -> BMS26). A `bgsub compare` report folder holds one mask set per method
(METHOD/ or METHOD.mkv, in SEQUENCE/ for a dataset): --method METHOD scores one of them.

Only frames inside the temporal ROI count, and only pixels inside ROI.bmp whose label is 0 or 50
(negative) or 255 (positive); 85 (outside ROI) and 170 (unknown) are ignored; other labels are an
error. A frame to evaluate without a prediction is an error unless --allow-missing (which counts
it as all background); when the masks there are one run of frames, the error names the options
that score just those. Metrics with a zero denominator are undefined (n/a, JSON null). A mask
video longer than the ground truth, or masks numbered past its last frame, are warned about
(often masks of another sequence) when the ground truth has a file for every frame from 1, as
CDnet's (or past its temporal ROI's end when that is later): labels for every N-th frame, or
for a window of frames, say nothing of where the input ends. A bin000000.png is ignored with a
warning: CDnet numbers frames from 1 (masks numbered from 0 would be scored one frame off).

A mask video has no frame numbers: its first frame is taken as frame 1 and the next as frame 2.
For a video that `bgsub run` wrote with --start/--step (and --stop), give eval the same flags
(same meaning: 0-based input indices); only the frames the run read are then evaluated.
binNNNNNN.png names carry their frame numbers: for a folder, the same flags select the frames
the run read (--step 2: bin000001.png, bin000003.png, ...) and only those are evaluated.
Masks smaller or larger than the ground truth by one scale factor (`bgsub run --width/--scale`)
are scaled to the ground truth's size (nearest neighbour); other sizes are an error."""

_EPILOG = """\
examples:
  bgsub eval masks/ data/cameraJitter/traffic --no-roi-bmp     one sequence
  bgsub eval masks.mkv scenes/static_s1 --skip-first           a mask video, frame 1 left out
  bgsub eval masks.mkv scenes/pan_s1 --start 30 --step 2       from `run --start 30 --step 2`
  bgsub eval masks/ scenes/pan_s1 --step 2                     from `run --step 2 -o masks`
  bgsub eval results/ scenes/ --csv scores.csv                 every sequence under scenes/
  bgsub eval results/ scenes/ --json > scores.json             machine-readable
  bgsub eval cmp_all/ scenes/ --method grbm                    grbm's masks of a compare report

exit status: 0 evaluated, 2 bad input (missing frames, size mismatch, bad ground truth)
"""


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "eval",
        help="CDnet 2014 metrics of masks against ground truth",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("pred", metavar="PRED",
                        help="folder of binNNNNNN.png masks or mask video (a folder of those "
                             "for a dataset)")
    parser.add_argument("groundtruth", metavar="GROUNDTRUTH",
                        help="CDnet sequence folder or dataset root")
    parser.add_argument("-m", "--method", default=None, metavar="METHOD",
                        help="PRED is a `bgsub compare` report folder: score the masks of "
                             "METHOD (METHOD/ or METHOD.mkv in it, or in each sequence's "
                             "folder of it)")
    out = parser.add_argument_group("output")
    out.add_argument("--json", action="store_true", help="print the results as JSON")
    out.add_argument("--csv", metavar="FILE", default=None,
                     help="also write one CSV row per sequence, category and overall ('-': "
                          "print the CSV instead of the table)")
    out.add_argument("--overwrite", action="store_true", help="replace an existing --csv file")
    out.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    frames = parser.add_argument_group("what counts")
    frames.add_argument("--no-roi-bmp", action="store_true",
                        help="ignore ROI.bmp (e.g. CDnet traffic's, which has the wrong size); "
                             "label 85 still marks outside-ROI pixels")
    frames.add_argument("--skip-first", action="store_true",
                        help="leave out frame 1, or the masks' first frame with --start "
                             "(a background model has seen nothing before it); no effect when "
                             "the temporal ROI starts later")
    frames.add_argument("--first-frame", type=int, default=None, metavar="N",
                        help="evaluate frames numbered N and later (1-based, like gtNNNNNN)")
    frames.add_argument("--last-frame", type=int, default=None, metavar="N",
                        help="evaluate frames numbered up to N (1-based, inclusive)")
    frames.add_argument("--allow-missing", action="store_true",
                        help="count frames (or sequences) without a prediction as all "
                             "background instead of failing")
    # The names, types and meaning of `bgsub run`'s (cli.common.add_source_options), so the
    # flags that wrote a mask video can be repeated here word for word.
    video = parser.add_argument_group(
        "frames bgsub run read",
        "the --start/--step/--stop `bgsub run` wrote the masks with: they place a mask video's "
        "frames, and select a mask folder's")
    video.add_argument("--start", type=int, default=0, metavar="N",
                       help="the masks start at input frame N, 0-based (default: 0)")
    video.add_argument("--stop", type=int, default=None, metavar="N",
                       help="the masks stop before input frame N, 0-based (default: the end)")
    video.add_argument("--step", type=int, default=1, metavar="N",
                       help="the masks are of every N-th input frame (default: 1)")
    batch.add_parallel_options(parser)  # the sequences of a dataset at once
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from bgsub.evaluation.cdnet import evaluate, format_csv, format_table

    if args.json and args.csv == "-":
        raise InputError("--json and --csv - both print to stdout: choose one")
    for option in ("first_frame", "last_frame"):
        value = getattr(args, option)
        if value is not None and value < 1:
            raise InputError(f"--{option.replace('_', '-')} takes a frame number >= 1, "
                             f"not {value}")
    jobs, _ = batch.jobs_and_threads(args)
    batch.for_workers(args, "pred", "groundtruth")
    csv_path = None
    if args.csv not in (None, "-"):
        csv_path = check_file_output(args.csv, overwrite=args.overwrite)

    result = evaluate(
        args.pred, args.groundtruth,
        ignore_roi_bmp=args.no_roi_bmp, allow_missing=args.allow_missing,
        method=args.method,
        skip_first=args.skip_first, first_frame=args.first_frame, last_frame=args.last_frame,
        video_start=args.start, video_step=args.step, video_stop=args.stop, quiet=args.quiet,
        jobs=jobs, scheduler=args.scheduler,
    )

    if csv_path is not None:
        try:
            csv_path.write_text(format_csv(result))
        except OSError as err:
            raise OutputError(f"cannot write {csv_path}: {err.strerror}") from None
    if args.json:
        print(json.dumps(result.to_dict(), indent=2))
    elif args.csv == "-":
        sys.stdout.write(format_csv(result))
    else:
        print(format_table(result))
    for seq in result.sequences:
        for message in seq.warnings:
            warn(f"{seq.name}: {message}")
        if seq.missing:
            # A video read from the wrong start scores about 0 with most frames "missing".
            hint = ""
            if seq.missing_hint:  # a folder whose masks are one run of frames
                hint = f"; {seq.missing_hint}"
            elif Path(seq.pred_path).is_file():
                given = (args.start, args.step, args.stop) != (0, 1, None)
                hint = ("; check that --start/--step/--stop are those bgsub run wrote the mask "
                        "video with" if given else "; if bgsub run wrote the mask video with "
                        "--start/--step/--stop, give eval the same flags")
            warn(f"{seq.name}: {len(seq.missing)} frames had no prediction and were counted as "
                 f"background{hint}")
    return 0
