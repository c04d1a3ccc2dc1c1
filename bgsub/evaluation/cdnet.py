"""CDnet 2014 evaluation: confusion counts and the seven metrics, per sequence and per dataset.

Ground truth (one sequence)
    A folder with ``groundtruth/gtNNNNNN.png`` (1-based frame numbers), optionally
    ``temporalROI.txt`` ("first last": the frames that carry valid ground truth) and ``ROI.bmp``
    (the spatial region of interest: non-zero = inside). Labels are CDnet's:

    ======  =======================  ==========
    value   meaning                  counted as
    ======  =======================  ==========
    0       static background        negative
    50      hard shadow              negative
    85      outside the ROI          ignored
    170     unknown / object border  ignored
    255     moving object            positive
    ======  =======================  ==========

    Any other value is an :class:`InputError` naming the file: the real CDnet ground truth uses
    exactly these five values (checked on ``CDnet2014_cameraJitter_traffic``: 0, 50, 85, 170, 255
    only), so another value means the file is not CDnet ground truth (e.g. an anti-aliased or
    JPEG-compressed mask) and guessing a class for it would bias the scores. Colour ground-truth
    images are accepted when their three channels are equal (CDnet's own pngs are stored so).

Ground truth (a dataset)
    A root folder searched at any depth; a folder is a sequence if it holds a ``groundtruth/``
    subfolder (its subfolders are not searched further). A sequence's *category* is the name of
    the folder holding it (``root/cameraJitter/traffic`` -> ``cameraJitter``); a sequence lying
    directly in the root has the family of its name instead: the part before the first ``_``
    (``BMS26_cars1`` -> ``BMS26``, ``static_s1`` -> ``static``, a name without ``_`` is its own
    family).

Predictions
    A folder of ``binNNNNNN.png`` masks (same numbering as the ground truth; ``.bmp``/``.jpg``/
    ``.tif`` are read too) or a mask video, whose frame ``k`` (0-based) is frame number
    ``video_start + k * video_step + 1``; or, from Python, an iterable of ``(frame_number, mask)``
    pairs. A mask video carries no frame numbers, so ``video_start``/``video_step``/``video_stop``
    (``bgsub eval --start/--step/--stop``) say which input frames it holds, with the meaning of
    ``bgsub run``'s options of those names (0-based, ``range(start, stop, step)``; defaults 0, 1,
    the end): the same flags that wrote it. Only the frames they cover are evaluated, and
    ``skip_first`` leaves out the video's first frame. A folder's masks carry their frame
    numbers: there the same options only select the frames `bgsub run` read with them (``--step
    2`` wrote ``bin000001.png``, ``bin000003.png``, ...: only frames 1, 3, ... are evaluated), with
    the same ``skip_first``. Python masks name their frames themselves: giving these options with
    them is an error (ignoring them would hide that the user expected something to shift). A
    prediction longer than the ground truth (a mask video with a frame past its last frame, or
    masks numbered past it) is scored on the frames with ground truth, with a warning in
    :attr:`SequenceResult.warnings`: often the masks of another sequence. Only ground truth with
    a file for every frame from 1 (CDnet's layout) states where the input ends: its last frame,
    or the temporal ROI's end when later (:attr:`GroundTruth.sequence_end`); ground truth with
    gaps (every N-th frame labelled) or starting later (a labelled window) states none, and
    masks past it draw no warning. CDnet numbers frames from 1: a ``bin000000.png`` is
    ignored with a warning (masks numbered from 0 would each be scored against the previous
    frame's ground truth; the warning says so when the masks look shifted that way). A pixel is
    foreground when its value is > 127 (colour masks are converted to gray first). For a
    dataset, the prediction of the sequence at ``GT_ROOT/REL`` (``REL`` = its path relative to
    the root, e.g. ``cameraJitter/traffic``; ``NAME`` = its folder name) is the first that
    exists of
    ``PRED_ROOT/REL/``, ``PRED_ROOT/NAME/``, ``PRED_ROOT/REL.<ext>``, ``PRED_ROOT/NAME.<ext>``
    with ``<ext>`` a video extension (:data:`VIDEO_EXTENSIONS`). A `bgsub compare` report holds
    one mask set per method (``METHOD/`` or ``METHOD.mkv``, inside ``REL/`` for a dataset):
    ``method`` (``bgsub eval --method``) picks one.

Prediction size
    ``bgsub run --width/--scale`` writes masks at the processed size. A prediction whose size is
    a uniform scale of the ground truth's (:func:`is_uniform_scale`: one factor explains both
    sides to within the rounding of :func:`bgsub.io.sources.output_size`) is brought to the ground
    truth's size with nearest-neighbour interpolation (masks stay 0/255), and the result notes
    it once. Any other size is an :class:`InputError` naming both sizes.

Which pixels and frames count
    Frames with a ground-truth png inside the temporal ROI (all of them without
    ``temporalROI.txt``), optionally narrowed by ``first_frame``/``last_frame``/``frames`` and
    ``skip_first`` (leaves out frame 1, the first frame of the video, where a background model
    has seen nothing yet; it changes nothing when the temporal ROI starts later, as in CDnet).
    Pixels inside ``ROI.bmp`` (unless ``ignore_roi_bmp``) whose label is not 85 or 170. An
    ``ROI.bmp`` that cannot be read or whose size differs from the frames is an error (the real
    CDnet ``cameraJitter/traffic`` ROI.bmp is 352x240 for 320x240 frames): pass
    ``ignore_roi_bmp`` to evaluate without it (label 85 still excludes outside-ROI pixels).

Missing predictions
    A frame to evaluate without a prediction (a missing png, or a video that ends early) is an
    :class:`InputError` listing how many and the first ones, unless ``allow_missing``: then each
    missing frame counts as an all-background prediction (so its objects are false negatives;
    missing output is never rewarded) and the result reports the count. When a folder's masks
    among those frames are one evenly spaced run (a part of the sequence, or every N-th frame),
    the error, and :attr:`SequenceResult.missing_hint`, name the options that score just them
    (e.g. ``--first-frame 991 --last-frame 1030``, or ``--step 2``).

Metrics (CDnet 2014; counts summed over all evaluated frames of a sequence)
    Recall = TP/(TP+FN), Specificity = TN/(TN+FP), FPR = FP/(FP+TN), FNR = FN/(TP+FN),
    PWC = 100 (FN+FP)/(TP+FN+FP+TN), Precision = TP/(TP+FP), F-measure = 2 TP/(2 TP+FP+FN)
    (which equals 2 Precision Recall/(Precision+Recall) whenever both are defined).
    A ratio whose denominator is 0 is undefined: ``nan`` (``n/a`` in tables, ``null`` in JSON);
    e.g. Precision of a method that marked nothing, Recall of a sequence without objects. F is
    0 when there are objects and none were found (even if nothing was marked), and undefined
    only when there was nothing to find and nothing was marked.

Averaging (the CDnet way)
    A category's metrics are the mean of its sequences' metrics; the overall metrics are the
    mean of the categories' metrics (each category weighs the same, whatever its size). Means
    skip undefined values (a metric undefined in every member stays undefined).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple

from tqdm import tqdm

from bgsub.errors import InputError, given_path
from bgsub.evaluation.groundtruth import (
    GroundTruth, PathLike, category_of, find_sequences, is_sequence, open_ground_truth,
)
from bgsub.evaluation.metrics import (
    METRIC_NAMES, METRIC_TITLES, Counts, Metrics, classify_labels, count_frame,
    is_uniform_scale, metrics,
)
from bgsub.evaluation.predictions import (
    VIDEO_EXTENSIONS, Prediction, PredictionReader, VideoFrames, find_prediction,
    methods_held, open_prediction,
)
from bgsub.evaluation.results import (
    CSV_COLUMNS, CategoryResult, DatasetResult, SequenceResult, format_csv, format_table,
    result_rows,
)
from bgsub.evaluation.scoring import SequenceScorer

__all__ = [
    "CSV_COLUMNS", "METRIC_NAMES", "METRIC_TITLES", "VIDEO_EXTENSIONS", "CategoryResult",
    "Counts", "DatasetResult", "GroundTruth", "Metrics", "Prediction", "PredictionReader",
    "SequenceResult", "SequenceScorer", "VideoFrames", "category_of", "classify_labels",
    "count_frame", "evaluate", "evaluate_dataset", "evaluate_sequence", "find_prediction",
    "find_sequences", "format_csv", "format_table", "is_sequence", "is_uniform_scale",
    "metrics", "open_ground_truth", "open_prediction", "result_rows",
]

_MAX_LISTED = 5  # sequences named in a message


def evaluate_sequence(
    pred: Optional[Prediction],
    gt_dir: PathLike,
    *,
    name: Optional[str] = None,
    category: Optional[str] = None,
    ignore_roi_bmp: bool = False,
    allow_missing: bool = False,
    skip_first: bool = False,
    first_frame: Optional[int] = None,
    last_frame: Optional[int] = None,
    frames: Optional[Iterable[int]] = None,
    video_start: int = 0,
    video_step: int = 1,
    video_stop: Optional[int] = None,
    quiet: bool = True,
) -> SequenceResult:
    """Evaluate the predicted masks of one sequence against its CDnet ground truth.

    Parameters
    ----------
    pred : path or iterable of (frame_number, (H, W) uint8 mask), or None
        A ``binNNNNNN.png`` folder, a mask video, or masks from Python (a generator works: it is
        consumed once, streaming; a dict ``{frame_number: mask}`` too; frame numbers are CDnet's,
        from 1, so a number below 1 is an error). ``None``: no prediction
        at all (every frame missing).
    gt_dir : path
        CDnet sequence folder (``groundtruth/``, optional ``temporalROI.txt``, ``ROI.bmp``).
    name, category : str, optional
        Defaults: the folder name and :func:`category_of` it.
    ignore_roi_bmp, allow_missing, skip_first, first_frame, last_frame, frames
        See the module docstring and :meth:`GroundTruth.select_frames`.
    video_start, video_step, video_stop : int
        For a mask video: the input frames it holds, as ``bgsub run --start --step --stop``
        (0-based, ``range(video_start, video_stop, video_step)``; see :class:`VideoFrames`).
        Only those frames are evaluated; ``skip_first`` also leaves out the video's first one.
        For a folder, the same frames are selected among its numbered masks. Anything but the
        defaults (0, 1, None) is an error for masks from Python.
    quiet : bool
        No progress bar (it is also off when stderr is not a terminal).

    Returns
    -------
    SequenceResult

    Raises
    ------
    InputError
        Bad ground truth, a prediction of a size that is not a uniform scale of the ground
        truth's, a video frame range for masks from Python, or missing
        predictions without ``allow_missing``.
    """
    video = VideoFrames(video_start, video_step, video_stop)
    gt = open_ground_truth(gt_dir, ignore_roi_bmp=ignore_roi_bmp)
    selected = gt.select_frames(first_frame=first_frame, last_frame=last_frame, frames=frames,
                                skip_first=skip_first)
    reader = open_prediction(pred, video, gt.path)
    numbers = reader.select(gt.path, selected, skip_first=skip_first)
    warnings = reader.inspect(gt)
    # Masks of a contiguous part (or every N-th frame) of the sequence: the options that score
    # just those, rather than --allow-missing, which scores the rest as missed objects.
    hint = reader.range_hint(selected, skip_first=skip_first)
    absent = reader.absent(numbers)
    if absent and not allow_missing:  # fail before reading anything
        raise InputError(reader.missing_error(absent, len(numbers), hint))
    scorer = SequenceScorer(gt)
    missing = _score_frames(reader, scorer, numbers, allow_missing=allow_missing, hint=hint,
                            quiet=quiet)
    warnings += reader.end_warnings(gt)
    rel_name = name or gt.path.resolve().name
    return SequenceResult(
        name=rel_name,
        category=category or category_of(rel_name),
        gt_path=str(gt.path),
        pred_path=reader.label,
        counts=scorer.counts,
        n_frames=len(numbers),
        first_frame=numbers[0],
        last_frame=numbers[-1],
        missing=missing,
        notes=_notes(gt, reader, scorer, numbers, missing, sparse_check=frames is None),
        warnings=warnings,
        missing_hint=hint if missing else "",
    )


def _score_frames(reader: PredictionReader, scorer: SequenceScorer, numbers: Sequence[int], *,
                  allow_missing: bool, hint: str, quiet: bool) -> List[int]:
    """Score the masks ``reader`` has of frames ``numbers``; returns the frames without one
    (scored as all background with ``allow_missing``, else an :class:`InputError`)."""
    seen = set()
    bar = tqdm(total=len(numbers), desc=f"eval {scorer.gt.path.name}", unit="frame",
               file=sys.stderr, disable=quiet or not sys.stderr.isatty(), leave=False,
               dynamic_ncols=True)
    with bar:
        for number, mask in reader.read(numbers):
            if number in seen:
                continue
            seen.add(number)
            scorer.score(number, mask, source=f"{reader.label} ({reader.frame_name(number)})")
            bar.update(1)
        missing = [n for n in numbers if n not in seen]
        if missing and not allow_missing:
            raise InputError(reader.missing_error(missing, len(numbers), hint))
        for number in missing:  # an absent mask is an all-background prediction
            scorer.score_missing(number)
            bar.update(1)
    return missing


def _notes(gt: GroundTruth, reader: PredictionReader, scorer: SequenceScorer,
           numbers: Sequence[int], missing: Sequence[int], *, sparse_check: bool) -> List[str]:
    """The result's notes: ROI use, temporal ROI, missing frames, range, scaling, gaps."""
    notes = list(gt.notes)
    if gt.temporal_roi is not None:
        notes.append(f"temporal ROI {gt.temporal_roi[0]}-{gt.temporal_roi[1]}")
    if missing:
        notes.append(f"{len(missing)} missing frames counted as background")
    if reader.range_note():
        notes.append(reader.range_note())
    if scorer.scaled_from is not None:
        notes.append(f"{scorer.scaled_from} predictions scaled to {gt.width}x{gt.height} "
                     "(nearest neighbour)")
    # A step leaves frames out on purpose: only holes in its grid are gaps.
    gaps = len(range(numbers[0], numbers[-1] + 1, reader.frames.step)) - len(numbers)
    if gaps and sparse_check:
        # Sparse ground truth (labels for some frames only) is legitimate, but say it: the
        # range in the summary would otherwise read as every frame of it.
        notes.append(f"no ground truth for {gaps} of the frames in that range")
    return notes



def evaluate_dataset(
    pred_root: PathLike,
    gt_root: PathLike,
    *,
    allow_missing: bool = False,
    method: Optional[str] = None,
    jobs: int = 1,
    scheduler: Optional[str] = None,
    **options: Any,
) -> DatasetResult:
    """Evaluate every sequence under ``gt_root`` against its prediction in ``pred_root``.

    Parameters
    ----------
    pred_root : path
        One prediction per sequence: ``REL/`` or ``NAME/`` (bin pngs) or ``REL.mkv`` /
        ``NAME.mkv`` (any of :data:`VIDEO_EXTENSIONS`).
    gt_root : path
        Dataset root (sequences at any depth).
    allow_missing : bool
        Count missing frames, and sequences without any prediction, as all background.
    method : str, optional
        Score this method's masks of a `bgsub compare` report (see :func:`find_prediction`).
    jobs, scheduler : int, str, optional
        Sequences scored at once in local processes, or on the Dask cluster at ``scheduler``
        (:func:`bgsub.batch.executors.ordered_map`).
    **options
        Passed to :func:`evaluate_sequence` (``ignore_roi_bmp``, ``skip_first``, ...);
        ``video_start``/``video_step``/``video_stop`` apply to every sequence (mask videos and
        folders alike).

    Returns
    -------
    DatasetResult
    """
    root = Path(gt_root)
    sequences = find_sequences(root)
    if not sequences:
        raise InputError(f"no CDnet sequences (folders with groundtruth/) under {root}")
    if not Path(pred_root).is_dir():
        raise InputError(f"predictions {pred_root} must be a folder when the ground truth is a "
                         "dataset of several sequences")
    rels = [seq.relative_to(root) for seq in sequences]
    preds = {rel: find_prediction(pred_root, rel, method) for rel in rels}
    absent = [rel.as_posix() for rel, p in preds.items() if p is None]
    if method is not None and len(absent) == len(rels):
        # A misspelt method, not missing sequences: --allow-missing would score nothing.
        raise InputError(f"no masks of method {method!r} in {pred_root} for any of its "
                         f"{len(rels)} sequences"
                         f"{methods_held([Path(pred_root) / rel for rel in rels])}")
    if absent and not allow_missing:
        listed = ", ".join(absent[:_MAX_LISTED]) + (", ..." if len(absent) > _MAX_LISTED else "")
        of = f" of method {method!r}" if method is not None else ""
        raise InputError(f"no prediction{of} in {pred_root} for {len(absent)} of {len(rels)} "
                         f"sequences ({listed}); use --allow-missing to count them as background")
    from bgsub.batch.executors import ordered_map

    if scheduler or jobs > 1:
        options["quiet"] = True  # bars of several processes at once would garble the terminal
    calls = [(preds[rel], seq, dict(options, name=rel.name, category=category_of(rel),
                                     allow_missing=allow_missing))
             for seq, rel in zip(sequences, rels)]
    results = ordered_map(_evaluate_call, calls, jobs=jobs, scheduler=scheduler)
    return DatasetResult.from_sequences(results)


def _evaluate_call(call: Tuple[Any, Path, Dict[str, Any]]) -> "SequenceResult":
    """:func:`evaluate_sequence` of ``(pred, gt_dir, keyword arguments)``, for a worker."""
    pred, gt_dir, options = call
    return evaluate_sequence(pred, gt_dir, **options)


def evaluate(pred: PathLike, gt: PathLike, *, method: Optional[str] = None, jobs: int = 1,
             scheduler: Optional[str] = None, **options: Any) -> DatasetResult:
    """Evaluate a sequence or a dataset (whichever ``gt`` is) -> :class:`DatasetResult`.

    A single sequence gives a result with one sequence, one category, and overall = it.
    ``method`` picks one method's masks in a `bgsub compare` report folder ``pred``
    (``METHOD/`` or ``METHOD.mkv``, per sequence for a dataset).
    """
    if isinstance(pred, (str, os.PathLike)):  # not masks handed over from Python
        given_path(pred, what="prediction", hint="a mask folder or a mask video")
    given_path(gt, what="ground truth", hint="a CDnet sequence folder or a dataset root")
    if method is not None:
        _check_method_name(method, pred)
    if not Path(gt).exists():
        raise InputError(f"ground truth {gt} does not exist")
    if is_sequence(gt):
        if method is not None:
            found = find_prediction(pred, method)
            if found is None:
                raise InputError(f"no masks of method {method!r} in {pred} (neither "
                                 f"{method}/ nor {method}.mkv or another video)"
                                 f"{methods_held([Path(pred)])}")
            pred = found
        return DatasetResult.from_sequences([evaluate_sequence(pred, gt, **options)])
    return evaluate_dataset(pred, gt, method=method, jobs=jobs, scheduler=scheduler, **options)


def _check_method_name(method: str, pred: Any) -> None:
    """``method`` names a mask set in a `bgsub compare` report folder ``pred``."""
    if not method.strip():
        raise InputError("method (--method) is empty; give a method's name, e.g. grbm")
    if "/" in method or "\\" in method or method in (".", ".."):
        raise InputError(f"method (--method) takes a method's name, e.g. grbm, not a path: "
                         f"{method!r}")
    if not isinstance(pred, (str, os.PathLike)):
        raise InputError("method (--method) picks one method's masks in a `bgsub compare` "
                         "report folder, not among masks from Python")
    if not Path(pred).is_dir():
        what = "is not a folder" if Path(pred).exists() else "does not exist"
        raise InputError(f"prediction {pred} {what}; method (--method) picks one method's "
                         "masks in a `bgsub compare` report folder")

