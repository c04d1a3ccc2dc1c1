"""Run several engines on the same frames and compare their speed and CDnet 2014 scores.

Every frame is decoded once and fed to every engine in turn (streaming: memory does not grow
with the length of the input). Only ``engine.apply`` is timed, so each method's frames per
second exclude decoding, scoring and writing. With ground truth, each mask is scored as it is
produced, with :mod:`bgsub.evaluation.cdnet`'s rules (temporal ROI, labels 85/170 ignored, optional
``ROI.bmp``), so the figures equal ``bgsub eval`` run on the masks written here.

The input is one of

* a CDnet sequence folder (``input/`` + ``groundtruth/``): its own ground truth is used;
* a dataset root holding several such sequences (``root/NAME/`` or ``root/CATEGORY/NAME/``):
  one row per sequence and method, then per-family means and the mean over families, averaged
  the CDnet way (:class:`bgsub.evaluation.cdnet.DatasetResult`); the family of ``root/NAME`` is the
  part of ``NAME`` before its first ``_`` (``BMS26_cars1`` -> ``BMS26``), of
  ``root/CATEGORY/NAME`` it is ``CATEGORY``;
* anything :func:`bgsub.io.sources.open_source` reads (video, image folder, glob), with optional
  ground truth given separately.

Outputs in ``report_dir`` (per sequence in ``report_dir/<sequence>/`` for a dataset root):
``<method>/binNNNNNN.png`` masks (or ``<method>.mkv``), ``side_by_side.mp4`` (input | one mask
per method, labelled), and ``report.txt`` / ``report.csv`` / ``report.json`` at the top;
``report.json`` lists these outputs, and a later run with ``overwrite=True`` removes them (and
nothing else) before writing its own.

An input that ends before its ground truth does is scored up to its last frame (as
``bgsub eval --last-frame <end>`` scores its masks); the report's notes and
:attr:`ComparisonReport.warnings` say how many of the ground-truth frames asked for were scored.

Example::

    from bgsub.evaluation.compare import compare_methods
    report = compare_methods("data/real/BMS26_cars1", methods=["grbm", "mog2"],
                             report_dir="cmp", skip_first=True)
    for row in report.rows:
        print(row.method, row.fps, row.metrics.f_measure)
"""

from __future__ import annotations

import contextlib
import glob
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import cv2
import numpy as np

from bgsub.cli.common import progress
from bgsub.engines import available_engines, create_engine, get_engine_spec
from bgsub.errors import BgsubError, InputError, OutputError, ProcessingError
from bgsub.evaluation.compare_report import (
    REPORT_FILES, TIMING_NOTE, ComparisonReport, ComparisonRow, mean_rows,
)
from bgsub.evaluation.groundtruth import (
    GroundTruth, category_of, find_sequences, is_sequence, open_ground_truth,
)
from bgsub.evaluation.metrics import Counts, count_frame
from bgsub.evaluation.report_dir import (
    SIDE_BY_SIDE, RunOutputs, check_report_dir, remove_if_no_files, remove_previous_outputs,
)
from bgsub.evaluation.side_by_side import TILE_HEIGHT, TileLayout
from bgsub.io.sinks import VideoSink, hold_interrupts, open_mask_sink
from bgsub.io.sources import VideoInfo, open_source

__all__ = ["MASK_FORMATS", "REPORT_FILES", "SIDE_BY_SIDE", "TILE_HEIGHT", "TIMING_NOTE",
           "ComparisonReport", "ComparisonRow", "TileLayout", "compare_methods",
           "remove_previous_outputs"]

PathLike = Union[str, "Path"]

#: Mask outputs: a folder of CDnet binNNNNNN.png, a lossless FFV1 video, or nothing.
MASK_FORMATS = ("png", "mkv", "none")



# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Job:
    """One input to process: its frames, its ground truth (if any) and where outputs go."""

    name: str
    family: str
    frames: str  # passed to open_source
    gt: Optional[Path]
    out: Optional[Path]  # folder for this input's masks and video, None = write nothing


def _has_glob(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def _is_cdnet_sequence(path: Path) -> bool:
    return (path / "input").is_dir() and is_sequence(path)


def _plan(input_path: str, gt: Optional[PathLike], report_dir: Optional[Path]) -> Tuple[
        List[_Job], bool, List[str]]:
    """Resolve the input to jobs; returns ``(jobs, is_dataset, notes)``."""
    path = Path(input_path)
    if not path.exists() and not _has_glob(input_path):
        raise InputError(f"input {input_path} does not exist")
    if gt is not None and not is_sequence(gt):
        raise InputError(f"--gt {gt} is not a CDnet sequence folder (it has no groundtruth/)")

    if path.is_dir() and not (path / "input").is_dir():
        sequences = find_sequences(path)
        usable = [s for s in sequences if (s / "input").is_dir()]
        if usable and gt is not None:
            raise InputError(f"{path} is a dataset root whose sequences carry their own ground "
                             "truth: --gt only applies to a single input")
        if usable:
            notes = [f"{s.relative_to(path).as_posix()}: skipped (groundtruth/ but no input/)"
                     for s in sequences if s not in usable]
            jobs = []
            for seq in usable:
                rel = seq.relative_to(path)
                jobs.append(_Job(name=rel.name, family=category_of(rel), frames=str(seq),
                                 gt=seq, out=report_dir / rel if report_dir else None))
            names = [j.name for j in jobs]
            if len(set(names)) != len(names):  # root/a/x and root/b/x: keep the paths apart
                jobs = [_Job(name=s.relative_to(path).as_posix(), family=j.family,
                             frames=j.frames, gt=j.gt, out=j.out) for s, j in zip(usable, jobs)]
            return jobs, True, notes

    seq_gt = Path(gt) if gt is not None else (path if _is_cdnet_sequence(path) else None)
    name = path.resolve().name if path.exists() else path.name  # a glob keeps its pattern
    family = category_of(seq_gt.resolve().name) if seq_gt is not None else ""
    return [_Job(name=name, family=family, frames=input_path, gt=seq_gt, out=report_dir)], \
        False, []




def _read_paths(jobs: Sequence[_Job]) -> List[Path]:
    """What the jobs read: their frames (a sequence's input/, a glob's matches) and their
    ground truth's files; outputs of an earlier run found among them are not removed."""
    paths: List[Path] = []
    for job in jobs:
        frames = Path(job.frames)
        if (frames / "input").is_dir():
            paths.append(frames / "input")
        elif frames.exists():
            paths.append(frames)
        elif _has_glob(job.frames):
            paths += [Path(p) for p in glob.glob(job.frames)]
        if job.gt is not None:
            paths += [job.gt / "groundtruth", job.gt / "temporalROI.txt", job.gt / "ROI.bmp"]
    return paths


# --------------------------------------------------------------------------------------------
# Running one input
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _RunOptions:
    """How every input of one compare run is read, processed, scored and written (the
    arguments of :func:`compare_methods` of those names)."""

    source: Dict[str, Any]  # open_source's start, stop, step, scale, width, fps
    max_frames: Optional[int]
    skip_first: bool
    ignore_roi_bmp: bool
    masks: str
    video: bool
    tile_height: int
    overwrite: bool
    quiet: bool
    tolerate_empty: bool  # a dataset: an input with nothing to score is noted, not refused


@dataclass
class _Scoring:
    """Ground truth of one input and the frame numbers (1-based) to score."""

    gt: GroundTruth
    numbers: List[int]
    resize: Optional[Tuple[int, int]]  # (w, h) to bring masks to the ground truth's size
    # What this run would score were the input long enough (frame range, --max-frames and
    # skip_first applied, but not the input's end): ``numbers`` falls short of it when the
    # input ends before its ground truth does.
    requested: List[int] = field(default_factory=list)


def _frame_span(numbers: Sequence[int]) -> str:
    return f"{numbers[0]}-{numbers[-1]}" if len(numbers) > 1 else f"{numbers[0]}"


def _short_input_note(scored: int, requested: Sequence[int], input_end: int) -> str:
    """``"scored 16 of 276 ground-truth frames (25-300): the input ends at frame 40"``."""
    return (f"scored {scored} of {len(requested)} ground-truth frames ({_frame_span(requested)}): "
            f"the input ends at frame {input_end}")


def _scoring(job: _Job, info: VideoInfo, *, start: int, stop: Optional[int], step: int,
             skip_first: bool, ignore_roi_bmp: bool, resized: bool,
             tolerate_empty: bool) -> Tuple[Optional[_Scoring], List[str], List[str]]:
    """Which frames of ``job`` get scored: ``(scoring, notes, warnings)``, ``scoring`` None when
    none can be."""
    if job.gt is None:
        return None, [], []
    gt = open_ground_truth(job.gt, ignore_roi_bmp=ignore_roi_bmp)
    if (info.width, info.height) != (gt.width, gt.height) and not resized:
        raise InputError(f"frames of {job.frames} are {info.width}x{info.height} but the ground "
                         f"truth in {job.gt} is {gt.width}x{gt.height}")
    # Frame numbers (1-based) this run asks for, then those it processes: the input's end,
    # when known up front, may cut the request short.
    limit = max(gt.frames)
    if stop is not None:
        limit = min(limit, stop)
    asked = range(start + 1, limit + 1, step)
    last = limit
    if info.frame_count is not None:
        last = min(last, start + (info.frame_count - 1) * step + 1)
    processed = range(start + 1, last + 1, step)
    if skip_first:
        # The first frame the engines see has no history; a frame later in the input (say the
        # start of CDnet traffic's temporal ROI, frame 900) has plenty and is scored.
        asked, processed = asked[1:], processed[1:]
    try:
        requested = gt.select_frames(frames=asked)
    except InputError as err:
        if not tolerate_empty:
            raise
        return None, [f"not scored: {err}"], []
    try:
        numbers = gt.select_frames(frames=processed)
    except InputError:
        # The input ends before the first frame to score, e.g. before a temporal ROI opens.
        message = (f"{job.frames} ends at frame {last}, before the first ground-truth frame to "
                   f"score ({requested[0]}; {len(requested)} frames, "
                   f"{_frame_span(requested)}, in {job.gt})")
        if not tolerate_empty:
            raise InputError(message) from None
        return None, [f"not scored: {message}"], [f"{job.name}: not scored: {message}"]
    resize = (gt.width, gt.height) if (info.width, info.height) != (gt.width, gt.height) \
        else None
    warnings = []
    input_end = (start + (info.frame_count - 1) * step + 1 if info.frame_count is not None
                 else None)
    gt_end = gt.sequence_end  # None: sparse ground truth, or a window; it states no end
    if stop is None and input_end is not None and gt_end is not None and input_end > gt_end:
        # As `bgsub eval` says of masks past the ground truth: often another clip's frames.
        warnings.append(f"{job.name}: {job.frames} holds frames up to {input_end}, past the "
                        f"ground truth's last ({max(gt.frames)} in {job.gt}): check that the "
                        "ground truth belongs to this input; only frames with ground truth "
                        "are scored")
    return _Scoring(gt, numbers, resize, requested), list(gt.notes), warnings


def _run_job(job: _Job, methods: Sequence[str], params: Mapping[str, Mapping[str, Any]],
             run: _RunOptions, written: RunOutputs) -> Tuple[List[ComparisonRow], List[str]]:
    """Run ``methods`` on one input; returns its rows and the warnings for stderr."""
    max_frames, skip_first, ignore_roi_bmp = run.max_frames, run.skip_first, run.ignore_roi_bmp
    masks, video, tile_height, overwrite = run.masks, run.video, run.tile_height, run.overwrite
    quiet, tolerate_empty = run.quiet, run.tolerate_empty
    options = dict(run.source)
    start, step = options["start"], options["step"]
    if max_frames is not None:
        limit = start + max_frames * step
        options["stop"] = limit if options["stop"] is None else min(options["stop"], limit)
    resized = options.get("scale") is not None or options.get("width") is not None

    with open_source(job.frames, **options) as source:
        info = source.info
        scoring, notes, warnings = _scoring(
            job, info, start=start, stop=options["stop"], step=step, skip_first=skip_first,
            ignore_roi_bmp=ignore_roi_bmp, resized=resized, tolerate_empty=tolerate_empty)
        to_score = set(scoring.numbers) if scoring else set()
        mask_size = scoring.resize if scoring and scoring.resize else (info.width, info.height)
        engines = {m: create_engine(m, **params.get(m, {})) for m in methods}
        seconds = dict.fromkeys(methods, 0.0)
        not_ok = dict.fromkeys(methods, 0)
        counts = {m: Counts() for m in methods}
        scored: List[int] = []
        n_frames = 0

        # The input and its ground truth are accepted: a previous run's results may go.
        written.clear_previous()
        if job.out is not None and (video or masks != "none"):
            # A dataset root's per-sequence folder (video sinks need their folder to exist).
            try:
                job.out.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise OutputError(f"cannot create {job.out}: {err.strerror}") from None
        stopped: Optional[KeyboardInterrupt] = None
        try:
            with contextlib.ExitStack() as stack:
                sinks = _open_mask_sinks(stack, job.out, methods, masks, size=mask_size,
                                         fps=info.fps, overwrite=overwrite, written=written)
                layout = TileLayout.for_frames(info.width, info.height, ["input", *methods],
                                               tile_height=tile_height)
                picture = None
                if video and job.out is not None:
                    written.add(job.out / SIDE_BY_SIDE)
                    picture = stack.enter_context(VideoSink(
                        job.out / SIDE_BY_SIDE, fps=info.fps, width=layout.width,
                        height=layout.height, overwrite=overwrite))
                frames = progress(source, total=info.frame_count, desc=job.name, quiet=quiet)
                for index, frame in frames:
                    number = index + 1
                    labels = scoring.gt.labels(number) if number in to_score else None
                    outputs, took, frame_counts, trouble = [], {}, {}, set()
                    for method, engine in engines.items():
                        t0 = time.perf_counter()
                        mask = engine.apply(frame)
                        took[method] = time.perf_counter() - t0
                        mask = _checked_mask(mask, method, info)
                        status = getattr(engine, "last_status", "ok")
                        if status is not None and status != "ok":
                            trouble.add(method)
                        if mask_size != (info.width, info.height):
                            mask = cv2.resize(mask, mask_size, interpolation=cv2.INTER_NEAREST)
                        if labels is not None:
                            try:
                                frame_counts[method] = count_frame(mask, labels,
                                                                   scoring.gt.roi)
                            except InputError as err:
                                raise InputError(f"{scoring.gt.frames[number]}: {err}") from None
                        outputs.append(mask)
                    tiles = layout.compose(frame, outputs) if picture is not None else None
                    # A frame goes to every output and into the figures or, when interrupted,
                    # to none: a partial report describes exactly the masks written.
                    with hold_interrupts():
                        for method, mask in zip(engines, outputs):
                            if method in sinks:
                                sinks[method].write(mask, index)
                        if picture is not None:
                            picture.write(tiles)
                        for method in engines:
                            seconds[method] += took[method]
                            not_ok[method] += method in trouble
                            if labels is not None:
                                counts[method] += frame_counts[method]
                        if labels is not None:
                            scored.append(number)
                        n_frames += 1
        except KeyboardInterrupt as stop:  # the sinks have closed their partial outputs
            stopped = stop
    if n_frames == 0:
        if stopped is not None:
            raise stopped
        raise InputError(f"{job.frames}: no frames in the requested range")

    # (Decoding ended well before the end the video declares; not asked when interrupted.)
    short = source.truncation() if stopped is None else None
    if short:
        notes.append(short)
        warnings.append(short)
    if stopped is not None:
        notes.append(f"stopped by {str(stopped) or 'Ctrl-C'} after {n_frames} frames: the "
                     "figures cover those")
        warnings.append(f"{job.name}: {notes[-1]}")
    if scoring is not None:
        # `number` is now the last frame read. Frames the source promised but never delivered
        # (a video that states the wrong length, or none) are not scored, like those past an
        # end known up front: the figures are those of `bgsub eval --last-frame <end>` on the
        # masks written here.
        if not scored:
            notes.append(f"not scored: {job.frames} ends at frame {number}, before the first "
                         f"ground-truth frame to score ({scoring.requested[0]})")
            warnings.append(f"{job.name}: {notes[-1]}")
            scoring = None
        else:
            notes.append(f"scored frames {_frame_span(scored)} ({len(scored)} frames)")
            if len(scored) < len(scoring.requested) and stopped is None:
                notes.append(_short_input_note(len(scored), scoring.requested, number))
                warnings.append(f"{job.name}: {notes[-1]}")
    rows = []
    for method in methods:
        metrics = counts[method].metrics() if scoring is not None else None
        rows.append(ComparisonRow(
            level="sequence", name=job.name, family=job.family, method=method,
            frames=n_frames, seconds=seconds[method],
            eval_frames=len(scored) if scoring else 0,
            counts=counts[method] if scoring else None, metrics=metrics,
            not_ok=not_ok[method], notes=tuple(notes)))
    if stopped is not None:
        raise _Partial(rows, warnings, stopped)
    return rows, warnings


class _Partial(Exception):
    """Ctrl-C (or SIGTERM) stopped a job after some frames: its rows so far, and the interrupt
    to raise again once they are in the report."""

    def __init__(self, rows: List[ComparisonRow], warnings: List[str],
                 stop: KeyboardInterrupt) -> None:
        super().__init__("interrupted")
        self.rows, self.warnings, self.stop = rows, warnings, stop


def _checked_mask(mask: Any, method: str, info: VideoInfo) -> np.ndarray:
    if not isinstance(mask, np.ndarray) or mask.shape != (info.height, info.width) \
            or mask.dtype != np.uint8:
        shape = getattr(mask, "shape", None)
        raise ProcessingError(f"method {method!r} returned a mask of shape {shape}, expected "
                              f"({info.height}, {info.width}) uint8")
    return mask


def _open_mask_sinks(stack: contextlib.ExitStack, out: Optional[Path], methods: Sequence[str],
                     masks: str, *, size: Tuple[int, int], fps: float, overwrite: bool,
                     written: "RunOutputs") -> Dict[str, Any]:
    if out is None or masks == "none":
        return {}
    sinks = {}
    for method in methods:
        target = out / (method if masks == "png" else f"{method}.mkv")
        written.add(target)
        sinks[method] = stack.enter_context(open_mask_sink(
            target, width=size[0], height=size[1], fps=fps, overwrite=overwrite))
    return sinks



# --------------------------------------------------------------------------------------------
# The entry point
# --------------------------------------------------------------------------------------------


def compare_methods(
    input_path: PathLike,
    *,
    methods: Optional[Sequence[str]] = None,
    report_dir: Optional[PathLike] = None,
    gt: Optional[PathLike] = None,
    params: Optional[Mapping[str, Mapping[str, Any]]] = None,
    skip_first: bool = False,
    ignore_roi_bmp: Optional[bool] = None,
    start: int = 0,
    stop: Optional[int] = None,
    step: int = 1,
    scale: Optional[float] = None,
    width: Optional[int] = None,
    fps: Optional[float] = None,
    max_frames: Optional[int] = None,
    masks: str = "png",
    video: bool = True,
    tile_height: int = TILE_HEIGHT,
    overwrite: bool = False,
    quiet: bool = True,
) -> ComparisonReport:
    """Run ``methods`` on the same frames; time them and score them against ground truth.

    Parameters
    ----------
    input_path : path
        A CDnet sequence folder, a dataset root of such sequences, or a video / image folder /
        glob pattern (see the module docstring).
    methods : sequence of str, optional
        Registered engine names; default all registered engines.
    report_dir : path, optional
        Where masks, side-by-side videos and ``report.{txt,csv,json}`` go; ``None`` writes
        nothing (figures only). An existing non-empty folder needs ``overwrite``.
    gt : path, optional
        CDnet sequence folder with the ground truth of a single input (default: the input
        itself when it is a CDnet sequence). Not allowed with a dataset root.
    params : ``{method: {param: value}}``, optional
        Engine parameters.
    skip_first : bool
        Do not score the first processed frame (the engines have seen nothing before it).
        When processing starts at frame 1 this is ``bgsub eval --skip-first`` (which leaves out
        frame 1); with ``start`` it leaves out the first frame actually processed.
    ignore_roi_bmp : bool, optional
        Ignore ``ROI.bmp``; default: ignored for dataset roots (the real CDnet traffic ROI.bmp
        has the wrong size), used for a single sequence.
    start, stop, step, scale, width, fps
        Frame range, resizing and frame rate, as :func:`bgsub.io.sources.open_source`; applied to
        every sequence. Resized masks are brought back to the ground truth's size (nearest
        neighbour) for scoring and writing.
    max_frames : int, optional
        Process at most this many frames per sequence.
    masks : {"png", "mkv", "none"}
        ``<method>/binNNNNNN.png``, lossless ``<method>.mkv``, or no masks.
    video : bool
        Write ``side_by_side.mp4`` per input.
    tile_height : int
        Largest height of one tile of the side-by-side video (frames are never enlarged).
    overwrite : bool
        Replace earlier results in ``report_dir``: once the (first) input and its ground truth
        are accepted, the outputs of the compare run that wrote there before are removed (those
        its ``report.json`` lists, else those compare's naming rules give; see
        :func:`remove_previous_outputs`), so the folder holds this run's results only; other
        files stay.
    quiet : bool
        No progress bars (they are also off when stderr is not a terminal).

    Returns
    -------
    ComparisonReport
        Its ``warnings`` say when an input ends before its ground truth does (frames the run
        asked for that were never scored), also stated in the report's notes.

    Raises
    ------
    InputError
        Unknown method or parameter, missing or unreadable input or ground truth.
    OutputError
        ``report_dir`` exists and is not empty (without ``overwrite``), or cannot be written.
    """
    names, params = _checked_methods(methods, params)
    _check_options(masks=masks, max_frames=max_frames, tile_height=tile_height)
    input_text = str(input_path)
    out = Path(report_dir) if report_dir is not None else None
    jobs, is_dataset, plan_notes = _plan(input_text, gt, out)
    ignore_roi = is_dataset if ignore_roi_bmp is None else bool(ignore_roi_bmp)
    for job in jobs:  # bad ground truth (e.g. a mis-sized ROI.bmp) fails before any output
        if job.gt is not None:
            open_ground_truth(job.gt, ignore_roi_bmp=ignore_roi)
    created = check_report_dir(report_dir, overwrite) if out is not None else None
    options = _RunOptions(
        source=dict(start=start, stop=stop, step=step, scale=scale, width=width, fps=fps),
        max_frames=max_frames, skip_first=skip_first, ignore_roi_bmp=ignore_roi, masks=masks,
        video=video, tile_height=tile_height, overwrite=overwrite, quiet=quiet,
        tolerate_empty=is_dataset)
    report = ComparisonReport(
        input=input_text, methods=names, report_dir=str(out) if out else None,
        settings={
            "start": start, "stop": stop, "step": step, "scale": scale, "width": width,
            "max_frames": max_frames, "skip_first": skip_first, "roi_bmp": not ignore_roi,
            "params": {m: dict(v) for m, v in params.items()},
        },
    )
    # With overwrite, the previous run's outputs go once the first input is accepted (so a
    # mistyped --gt or a frame-size mismatch leaves them in place), and only they.
    written = RunOutputs(out, overwrite=overwrite, methods=names, protect=_read_paths(jobs))
    try:
        stopped = _run_jobs(jobs, names, params, options, report, written,
                            quiet=quiet or not is_dataset)
    except (BgsubError, KeyboardInterrupt):  # refused or stopped before any result
        if created is not None:
            remove_if_no_files(created)
        raise
    if stopped is not None and len(report.rows) < len(jobs) * len(names):
        report.warnings.append(f"stopped by {str(stopped) or 'Ctrl-C'}: "
                               f"{len(report.rows) // len(names)} of {len(jobs)} inputs run")
    if is_dataset:
        report.families, report.overall = mean_rows(report.rows, names)
    if plan_notes:
        report.settings["skipped"] = plan_notes
    if out is not None:
        written.clear_previous()
        report.outputs = list(written.paths)
        report.write(out)
    if stopped is not None:
        # The figures of the frames processed are in the report folder; the caller learns of
        # the interrupt, with the report attached (bgsub compare prints it).
        stopped.report = report  # type: ignore[attr-defined]
        raise stopped
    return report


def _checked_methods(methods: Optional[Sequence[str]],
                     params: Optional[Mapping[str, Mapping[str, Any]]]
                     ) -> Tuple[List[str], Dict[str, Mapping[str, Any]]]:
    """``(names, params)``: the methods (default: every registered engine) and their
    parameters, each engine built once so that an unknown method, a bad parameter or a
    missing model file fails before anything is decoded or written."""
    names = list(methods) if methods else [spec.name for spec in available_engines()]
    if not names:
        raise InputError("no methods to compare")
    duplicates = sorted({m for m in names if names.count(m) > 1})
    if duplicates:
        raise InputError(f"method {duplicates[0]!r} is listed twice")
    params = dict(params or {})
    for method in params:
        if method not in names:
            raise InputError(f"parameters given for {method!r}, which is not among the methods")
    for method in names:
        get_engine_spec(method).create(**params.get(method, {}))
    return names, params


def _check_options(*, masks: str, max_frames: Optional[int], tile_height: int) -> None:
    if masks not in MASK_FORMATS:
        raise InputError(f"masks must be one of {', '.join(MASK_FORMATS)}, not {masks!r}")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, not {max_frames}")
    if tile_height < 16:
        raise InputError(f"tile height must be at least 16 pixels, not {tile_height}")


def _run_jobs(jobs: Sequence[_Job], names: Sequence[str],
              params: Mapping[str, Mapping[str, Any]], options: "_RunOptions",
              report: ComparisonReport, written: RunOutputs, *, quiet: bool
              ) -> Optional[KeyboardInterrupt]:
    """Run every job, adding its rows and warnings to ``report``; returns the interrupt that
    stopped them (after the rows of the frames processed), or None."""
    for job in progress(jobs, total=len(jobs), desc="sequences", quiet=quiet, unit="seq"):
        stopped = None
        try:
            rows, warnings = _run_job(job, names, params, options, written)
        except _Partial as partial:
            rows, warnings, stopped = partial.rows, partial.warnings, partial.stop
        except KeyboardInterrupt as stop:  # before the job's first frame
            if not report.rows:
                raise
            rows, warnings, stopped = [], [], stop
        report.rows.extend(rows)
        report.warnings.extend(warnings)
        if stopped is not None:
            return stopped
    return None
