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
``<method>/binNNNNNN.png`` masks (or ``<method>.mkv``), ``side_by_side.mp4`` (input | ground
truth | one mask per method, labelled), and ``report.txt`` / ``report.csv`` / ``report.json``
and the self-contained page ``report.html`` (:mod:`bgsub.evaluation.html_report`) at the top;
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

import dataclasses
import glob
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from bgsub.cli.common import progress
from bgsub.engines import available_engines, get_engine_spec
from bgsub.errors import BgsubError, InputError
from bgsub.evaluation.compare_job import Job, PartialJob, RunOptions, run_job
from bgsub.evaluation.compare_report import (
    HTML_REPORT, REPORT_FILES, TIMING_NOTE, ComparisonReport, ComparisonRow, mean_rows,
)
from bgsub.evaluation.groundtruth import (
    category_of, find_sequences, is_sequence, open_ground_truth,
)
from bgsub.evaluation.html_report import write_html_report
from bgsub.io.h264 import picture_codec
from bgsub.evaluation.report_dir import (
    SIDE_BY_SIDE, RunOutputs, check_report_dir, remove_if_no_files, remove_previous_outputs,
)
from bgsub.evaluation.report_frames import SequenceFrames
from bgsub.evaluation.side_by_side import TILE_HEIGHT, TileLayout

__all__ = ["MASK_FORMATS", "REPORT_FILES", "SIDE_BY_SIDE", "TILE_HEIGHT", "TIMING_NOTE",
           "ComparisonReport", "ComparisonRow", "TileLayout", "compare_methods",
           "remove_previous_outputs"]

PathLike = Union[str, "Path"]

SIDE_BY_SIDE_SUFFIX = Path(SIDE_BY_SIDE).suffix

#: Mask outputs: a folder of CDnet binNNNNNN.png, a lossless FFV1 video, or nothing.
MASK_FORMATS = ("png", "mkv", "none")



# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


def _has_glob(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def _is_cdnet_sequence(path: Path) -> bool:
    return (path / "input").is_dir() and is_sequence(path)


def _plan(input_path: str, gt: Optional[PathLike], report_dir: Optional[Path]) -> Tuple[
        List[Job], bool, List[str]]:
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
                jobs.append(Job(name=rel.name, family=category_of(rel), frames=str(seq),
                                 gt=seq, out=report_dir / rel if report_dir else None))
            names = [j.name for j in jobs]
            if len(set(names)) != len(names):  # root/a/x and root/b/x: keep the paths apart
                jobs = [Job(name=s.relative_to(path).as_posix(), family=j.family,
                             frames=j.frames, gt=j.gt, out=j.out) for s, j in zip(usable, jobs)]
            return jobs, True, notes

    seq_gt = Path(gt) if gt is not None else (path if _is_cdnet_sequence(path) else None)
    name = path.resolve().name if path.exists() else path.name  # a glob keeps its pattern
    family = category_of(seq_gt.resolve().name) if seq_gt is not None else ""
    return [Job(name=name, family=family, frames=input_path, gt=seq_gt, out=report_dir)], \
        False, []




def _read_paths(jobs: Sequence[Job]) -> List[Path]:
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
    html: bool = True,
    video_codec: str = "auto",
    tile_height: int = TILE_HEIGHT,
    overwrite: bool = False,
    quiet: bool = True,
    workers: int = 1,
    scheduler: Optional[str] = None,
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
        Write ``side_by_side.mp4`` per input (input, ground truth when there is one, one mask
        per method).
    video_codec : {"auto", "h264", "mp4v"}
        Codec of ``side_by_side.mp4`` (:func:`bgsub.io.h264.picture_codec`: H.264 when PyAV
        is installed, with ``"auto"``); the one used is ``report.settings["video_codec"]``.
    html : bool
        Write ``report.html`` (:mod:`bgsub.evaluation.html_report`): the figures, charts and a
        few frames of each input, in one page that needs nothing else.
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
    workers, scheduler : int, str, optional
        The inputs of a dataset run at once in ``workers`` local processes, or on the Dask
        cluster at ``scheduler`` (see :func:`_run_jobs_elsewhere`).

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
    codec = picture_codec(SIDE_BY_SIDE_SUFFIX, video_codec) if video else None
    input_text = str(input_path)
    out = Path(report_dir) if report_dir is not None else None
    jobs, is_dataset, plan_notes = _plan(input_text, gt, out)
    ignore_roi = is_dataset if ignore_roi_bmp is None else bool(ignore_roi_bmp)
    for job in jobs:  # bad ground truth (e.g. a mis-sized ROI.bmp) fails before any output
        if job.gt is not None:
            open_ground_truth(job.gt, ignore_roi_bmp=ignore_roi)
    created = check_report_dir(report_dir, overwrite) if out is not None else None
    options = RunOptions(
        source=dict(start=start, stop=stop, step=step, scale=scale, width=width, fps=fps),
        max_frames=max_frames, skip_first=skip_first, ignore_roi_bmp=ignore_roi, masks=masks,
        video=video, video_codec=codec or "mp4v", tile_height=tile_height, overwrite=overwrite, quiet=quiet,
        tolerate_empty=is_dataset)
    report = ComparisonReport(
        input=input_text, methods=names, report_dir=str(out) if out else None,
        settings={
            "start": start, "stop": stop, "step": step, "scale": scale, "width": width,
            "max_frames": max_frames, "skip_first": skip_first, "roi_bmp": not ignore_roi,
            "params": {m: dict(v) for m, v in params.items()},
            **({"video_codec": codec} if codec else {}),
        },
    )
    # With overwrite, the previous run's outputs go once the first input is accepted (so a
    # mistyped --gt or a frame-size mismatch leaves them in place), and only they.
    written = RunOutputs(out, overwrite=overwrite, methods=names, protect=_read_paths(jobs))
    try:
        if len(jobs) > 1 and (workers > 1 or scheduler):
            stopped = _run_jobs_elsewhere(jobs, names, params, options, report, written,
                                          workers=workers, scheduler=scheduler)
        else:
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
        report.outputs = [*([HTML_REPORT] if html else []), *written.paths]
        report.write(out)
        if html:
            write_html_report(report, out / HTML_REPORT)
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


def _run_jobs(jobs: Sequence[Job], names: Sequence[str],
              params: Mapping[str, Mapping[str, Any]], options: "RunOptions",
              report: ComparisonReport, written: RunOutputs, *, quiet: bool
              ) -> Optional[KeyboardInterrupt]:
    """Run every job, adding its rows and warnings to ``report``; returns the interrupt that
    stopped them (after the rows of the frames processed), or None."""
    for job in progress(jobs, total=len(jobs), desc="sequences", quiet=quiet, unit="seq"):
        stopped, frames = None, None
        try:
            rows, warnings, frames = run_job(job, names, params, options, written)
        except PartialJob as partial:
            rows, warnings, stopped = partial.rows, partial.warnings, partial.stop
            frames = partial.frames
        except KeyboardInterrupt as stop:  # before the job's first frame
            if not report.rows:
                raise
            rows, warnings, stopped = [], [], stop
        report.rows.extend(rows)
        report.warnings.extend(warnings)
        if frames is not None:
            report.frames.append(frames)
        if stopped is not None:
            return stopped
    return None


def _job_elsewhere(call: Tuple[Job, Sequence[str], Mapping[str, Mapping[str, Any]],
                               RunOptions, Optional[Path]]
                   ) -> Tuple[List[ComparisonRow], List[str], SequenceFrames, List[str]]:
    """:func:`run_job` in a worker process: its rows, warnings, frames for the HTML report and
    the report files it wrote."""
    job, names, params, options, root = call
    written = RunOutputs(root, overwrite=False, methods=names, protect=[])
    rows, warnings, frames = run_job(job, names, params,
                                     dataclasses.replace(options, quiet=True), written)
    return rows, warnings, frames, written.paths


def _run_jobs_elsewhere(jobs: Sequence[Job], names: Sequence[str],
                        params: Mapping[str, Mapping[str, Any]], options: RunOptions,
                        report: ComparisonReport, written: RunOutputs, *, workers: int,
                        scheduler: Optional[str]) -> Optional[KeyboardInterrupt]:
    """:func:`_run_jobs` on local processes or a Dask cluster
    (:func:`bgsub.batch.executors.ordered_map`): rows, warnings and files in the jobs' order.
    The previous run's outputs go first (every ground truth was accepted already). Ctrl-C
    stops the jobs not started and is raised without a report."""
    from bgsub.batch.executors import ordered_map

    written.clear_previous()
    calls = [(job, list(names), dict(params), options, written.root) for job in jobs]
    for rows, warnings, frames, paths in ordered_map(_job_elsewhere, calls, jobs=workers,
                                                     scheduler=scheduler):
        report.rows.extend(rows)
        report.warnings.extend(warnings)
        report.frames.append(frames)
        written.paths.extend(path for path in paths if path not in written.paths)
    return None
