"""One input of `bgsub compare`: its frames decoded once and fed through every method by the
frame loop (:class:`bgsub.io.loop.FrameLoop`), whose consumers write the masks and the
side-by-side video and score the masks against the ground truth
(:class:`bgsub.evaluation.scoring.GroundTruthScorer`).

Masks are written and scored at the ground truth's size: masks of frames processed at another
size (``scale``/``width``) are resized with nearest neighbour, so they stay 0/255.
"""

from __future__ import annotations

import contextlib
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.engines import create_engine
from bgsub.errors import InputError, OutputError
from bgsub.evaluation.compare_report import ComparisonRow
from bgsub.evaluation.groundtruth import GroundTruth, open_ground_truth
from bgsub.evaluation.report_dir import SIDE_BY_SIDE, RunOutputs
from bgsub.evaluation.scoring import GroundTruthScorer
from bgsub.evaluation.report_frames import ReportFrames, SequenceFrames
from bgsub.evaluation.side_by_side import TRUTH_LABEL, SideBySideWriter, TileLayout
from bgsub.io.loop import Consumer, FrameLoop, FrameResult, RunStats
from bgsub.io.sinks import VideoSink, open_mask_sink
from bgsub.io.sources import FrameSource, VideoInfo, open_source
from bgsub.io.writers import MaskWriter, ProgressBar


@dataclass(frozen=True)
class Job:
    """One input to process: its frames, its ground truth (if any) and where outputs go."""

    name: str
    family: str
    frames: str  # passed to open_source
    gt: Optional[Path]
    out: Optional[Path]  # folder for this input's masks and video, None = write nothing


@dataclass(frozen=True)
class RunOptions:
    """How every input of one compare run is read, processed, scored and written (the
    arguments of :func:`compare_methods` of those names)."""

    source: Dict[str, Any]  # open_source's start, stop, step, scale, width, fps
    max_frames: Optional[int]
    skip_first: bool
    ignore_roi_bmp: bool
    masks: str
    video: bool
    video_codec: str  # of side_by_side.mp4: "h264" or "mp4v"
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


def _scoring(job: Job, info: VideoInfo, *, start: int, stop: Optional[int], step: int,
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
    warnings = [] if stop is not None else _past_gt_end(job, gt, info, start=start, step=step)
    return _Scoring(gt, numbers, resize, requested), list(gt.notes), warnings


def _past_gt_end(job: Job, gt: GroundTruth, info: VideoInfo, *, start: int,
                 step: int) -> List[str]:
    """The warning for an input whose stated length goes past the end its ground truth states
    (as `bgsub eval` says of masks past the ground truth: often another clip's frames)."""
    gt_end = gt.sequence_end  # None: sparse ground truth, or a window; it states no end
    if info.frame_count is None or gt_end is None:
        return []
    input_end = start + (info.frame_count - 1) * step + 1
    if input_end <= gt_end:
        return []
    return [f"{job.name}: {job.frames} holds frames up to {input_end}, past the ground truth's "
            f"last ({max(gt.frames)} in {job.gt}): check that the ground truth belongs to this "
            "input; only frames with ground truth are scored"]


def run_job(job: Job, methods: Sequence[str], params: Mapping[str, Mapping[str, Any]],
            run: RunOptions, written: RunOutputs
            ) -> Tuple[List[ComparisonRow], List[str], SequenceFrames]:
    """Run ``methods`` on one input; returns its rows, the warnings for stderr and a few of
    its frames for the HTML report.

    Raises :class:`PartialJob` (its rows and frames so far, and the interrupt) when Ctrl-C or
    a signal stops the input after some frames.
    """
    options = _source_options(run)
    with open_source(job.frames, **options) as source:
        info = source.info
        scoring, notes, warnings = _scoring(
            job, info, start=options["start"], stop=options["stop"], step=options["step"],
            skip_first=run.skip_first, ignore_roi_bmp=run.ignore_roi_bmp,
            resized=options["scale"] is not None or options["width"] is not None,
            tolerate_empty=run.tolerate_empty)
        size = scoring.resize if scoring and scoring.resize else (info.width, info.height)
        engines = {m: create_engine(m, **params.get(m, {})) for m in methods}
        # The input and its ground truth are accepted: a previous run's results may go.
        written.clear_previous()
        _make_folder(job, run)
        scorer = GroundTruthScorer(scoring.gt, scoring.numbers) if scoring else None
        reading = _Reading(source)
        stopped: Optional[KeyboardInterrupt] = None
        with contextlib.ExitStack() as stack:
            truth = scoring.gt if scoring else None
            outputs = _outputs(stack, job, methods, run, size=size, info=info, written=written,
                               truth=truth)
            frames = ReportFrames(methods, truth=truth,
                                  numbers=scoring.numbers if scoring else None)
            loop = FrameLoop(engines, [
                ProgressBar(total=info.frame_count, desc=job.name, enabled=not run.quiet),
                GroundTruthSized(size, [*outputs, *([scorer] if scorer else []), frames])])
            try:
                loop.run(reading)
            except KeyboardInterrupt as stop:  # the loop has finished the partial outputs
                stopped = stop
    if loop.stats.frames == 0:
        if stopped is not None:
            raise stopped
        raise InputError(f"{job.frames}: no frames in the requested range")
    # (Decoding ended well before the end the video declares; not asked when interrupted.)
    short = source.truncation() if stopped is None else None
    if short:
        notes.append(short)
        warnings.append(short)
    if stopped is not None:
        notes.append(f"stopped by {str(stopped) or 'Ctrl-C'} after {loop.stats.frames} frames: "
                     "the figures cover those")
        warnings.append(f"{job.name}: {notes[-1]}")
    if scoring is not None and not _scored_notes(job, scoring, scorer.scored, reading.last,
                                                 notes, warnings, stopped=stopped is not None):
        scorer = None
    rows = _rows(job, methods, loop.stats, scorer, notes)
    shown = frames.result(name=job.name, family=job.family, video=_video_path(job, run, written))
    if stopped is not None:
        raise PartialJob(rows, warnings, stopped, frames=shown)
    return rows, warnings, shown


def _video_path(job: Job, run: RunOptions, written: RunOutputs) -> str:
    """The job's side-by-side video relative to the report folder ("" when none is written)."""
    if not run.video or job.out is None or written.root is None:
        return ""
    return (job.out / SIDE_BY_SIDE).relative_to(written.root).as_posix()


class PartialJob(Exception):
    """Ctrl-C (or SIGTERM) stopped a job after some frames: its rows and frames so far, and
    the interrupt to raise again once they are in the report."""

    def __init__(self, rows: List[ComparisonRow], warnings: List[str],
                 stop: KeyboardInterrupt, *, frames: Optional[SequenceFrames] = None) -> None:
        super().__init__("interrupted")
        self.rows, self.warnings, self.stop = rows, warnings, stop
        self.frames = frames


def _source_options(run: RunOptions) -> Dict[str, Any]:
    """:func:`open_source`'s keywords for one input: the run's, ``stop`` cut by
    ``max_frames``."""
    options = dict(run.source)
    if run.max_frames is not None:
        limit = options["start"] + run.max_frames * options["step"]
        options["stop"] = limit if options["stop"] is None else min(options["stop"], limit)
    return options


def _make_folder(job: Job, run: RunOptions) -> None:
    """A dataset root's per-sequence folder (video sinks need their folder to exist)."""
    if job.out is not None and (run.video or run.masks != "none"):
        try:
            job.out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise OutputError(f"cannot create {job.out}: {err.strerror}") from None


def _outputs(stack: contextlib.ExitStack, job: Job, methods: Sequence[str], run: RunOptions, *,
             size: Tuple[int, int], info: VideoInfo, written: RunOutputs,
             truth: Optional[GroundTruth]) -> List[Consumer]:
    """The consumers that write this input's masks (``size`` = (width, height)) and its
    side-by-side video (with a ground-truth tile when ``truth`` is given); their sinks are
    entered on ``stack``."""
    if job.out is None:
        return []
    consumers: List[Consumer] = []
    if run.masks != "none":
        for method in methods:
            target = job.out / (method if run.masks == "png" else f"{method}.mkv")
            written.add(target)
            sink = stack.enter_context(open_mask_sink(
                target, width=size[0], height=size[1], fps=info.fps, overwrite=run.overwrite))
            consumers.append(MaskWriter(sink, engine=method))
    if run.video:
        labels = ["input", *([TRUTH_LABEL] if truth is not None else []), *methods]
        layout = TileLayout.for_frames(info.width, info.height, labels,
                                       tile_height=run.tile_height)
        written.add(job.out / SIDE_BY_SIDE)
        sink = stack.enter_context(VideoSink(
            job.out / SIDE_BY_SIDE, fps=info.fps, width=layout.width, height=layout.height,
            overwrite=run.overwrite, codec=run.video_codec))
        consumers.append(SideBySideWriter(sink, layout, methods, truth=truth))
    return consumers


class GroundTruthSized(Consumer):
    """Hands ``consumers`` every frame with its masks at ``size`` (width, height), the size
    they are written and scored at: nearest neighbour keeps them 0/255, and bool masks become
    0/255 uint8. Each mask is resized once, in :meth:`prepare`."""

    def __init__(self, size: Tuple[int, int], consumers: Sequence[Consumer]) -> None:
        self.size = size
        self.consumers = list(consumers)
        self._result: Optional[FrameResult] = None

    def start(self, engines: Mapping[str, Any]) -> None:
        for consumer in self.consumers:
            consumer.start(engines)

    def prepare(self, result: FrameResult) -> None:
        masks = {name: self._sized(mask) for name, mask in result.masks.items()}
        self._result = dataclasses.replace(result, masks=masks)
        for consumer in self.consumers:
            consumer.prepare(self._result)

    def add(self, result: FrameResult) -> None:
        for consumer in self.consumers:
            consumer.add(self._result)

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        with contextlib.ExitStack() as stack:  # each closed, in reverse, whatever the others do
            for consumer in self.consumers:
                stack.callback(consumer.close, complete=complete, error=error)

    def _sized(self, mask: np.ndarray) -> np.ndarray:
        if mask.dtype == np.bool_:
            mask = mask.astype(np.uint8) * np.uint8(255)
        if (mask.shape[1], mask.shape[0]) != self.size:
            mask = cv2.resize(mask, self.size, interpolation=cv2.INTER_NEAREST)
        return mask


class _Reading:
    """Iterates over a source's frames, keeping the number (1-based) of the last one read."""

    def __init__(self, source: FrameSource) -> None:
        self.source = source
        self.last: Optional[int] = None

    def __iter__(self) -> Iterator[Tuple[int, np.ndarray]]:
        for index, frame in self.source:
            self.last = index + 1
            yield index, frame


def _scored_notes(job: Job, scoring: "_Scoring", scored: Sequence[int], last: Optional[int],
                  notes: List[str], warnings: List[str], *, stopped: bool) -> bool:
    """Add the notes on which frames were scored; False when none was.

    Frames the source promised but never delivered (a video that states the wrong length, or
    none) are not scored, like those past an end known up front: the figures are those of
    `bgsub eval --last-frame <end>` on the masks written (``last``: the last frame read).
    """
    if not scored:
        notes.append(f"not scored: {job.frames} ends at frame {last}, before the first "
                     f"ground-truth frame to score ({scoring.requested[0]})")
        warnings.append(f"{job.name}: {notes[-1]}")
        return False
    notes.append(f"scored frames {_frame_span(scored)} ({len(scored)} frames)")
    if len(scored) < len(scoring.requested) and not stopped:
        notes.append(_short_input_note(len(scored), scoring.requested, last))
        warnings.append(f"{job.name}: {notes[-1]}")
    return True


def _rows(job: Job, methods: Sequence[str], stats: RunStats,
          scorer: Optional[GroundTruthScorer], notes: Sequence[str]) -> List[ComparisonRow]:
    """One row per method: frames, time in ``apply``, non-ok statuses and, when scored, the
    counts and metrics."""
    rows = []
    for method in methods:
        counts = scorer.counts(method) if scorer is not None else None
        rows.append(ComparisonRow(
            level="sequence", name=job.name, family=job.family, method=method,
            frames=stats.frames, seconds=stats.engines[method].seconds,
            eval_frames=len(scorer.scored) if scorer is not None else 0,
            counts=counts, metrics=counts.metrics() if counts is not None else None,
            not_ok=stats.engines[method].not_ok, notes=tuple(notes)))
    return rows
