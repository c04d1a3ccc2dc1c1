"""Many inputs in one command: ``bgsub run IN1 IN2 ... -o OUTDIR/`` and the ``--jobs`` /
``--scheduler`` options of ``run``, ``compare`` and ``eval``.

A thin layer over :mod:`bgsub.batch`: the options, a progress bar over the inputs, one line per
failure, the closing summary line and the ``--summary`` JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Optional

from bgsub.errors import InputError, OutputError

_BATCH_HELP = """\
several inputs (or a folder or glob of videos) make a batch: one output per input in the -o
folder; a rerun skips complete ones (docs/cli.md, "Many inputs")."""


def add_parallel_options(parser: argparse.ArgumentParser) -> None:
    """``--jobs`` and ``--scheduler``: how many inputs at once, and where. ``--jobs`` defaults
    to 1 in every command (an interrupted run reports what it processed, and timings are not
    shared cores'); 0 takes the usable cores."""
    group = parser.add_argument_group("many inputs")
    group.add_argument("-j", "--jobs", type=int, default=1, metavar="N",
                       help="inputs run at once (default: 1; 0: the usable cores)")
    group.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on a Dask cluster (tcp://host:8786; bgsub[dask])")


def add_batch_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``bgsub run`` with several inputs."""
    from bgsub.batch.plan import MASK_FORMATS

    add_parallel_options(parser)
    group = parser._action_groups[-1]
    group.description = _BATCH_HELP
    group.add_argument("--mask-format", choices=MASK_FORMATS, default=None, metavar="FORMAT",
                       help=f"{'/'.join(MASK_FORMATS)} masks per input (default: mkv)")
    group.add_argument("--summary", default=None, metavar="FILE.json",
                       help="write the batch's summary as JSON")


def for_workers(args: argparse.Namespace, *names: str) -> None:
    """With ``--scheduler``, make the paths in ``args`` of these option names absolute: the
    Dask workers do not share this process's working folder."""
    if not getattr(args, "scheduler", None):
        return
    for name in names:
        value = getattr(args, name, None)
        if isinstance(value, list):
            setattr(args, name, [os.path.abspath(v) for v in value])
        elif value:
            setattr(args, name, os.path.abspath(value))


def jobs_and_threads(args: argparse.Namespace) -> tuple:
    """``(jobs, threads per job)`` of ``--jobs`` (a Dask task gets one thread)."""
    from bgsub.batch.threads import threads_per_job, usable_cores

    if args.jobs < 0:
        raise InputError(f"--jobs takes a number of inputs at once, or 0 for the usable cores; "
                         f"not {args.jobs}")
    jobs = args.jobs or usable_cores()
    return jobs, (1 if args.scheduler else threads_per_job(jobs))


def _layout(args: argparse.Namespace) -> Any:
    from bgsub.batch.plan import SIDE_OUTPUTS, OutputLayout
    from bgsub.io.sinks import MASK_VIDEO_CODECS

    if args.output.lower().endswith(tuple(MASK_VIDEO_CODECS)):
        raise OutputError(f"{args.output}: -o of several inputs is a folder (each input's masks "
                          "go to OUTDIR/NAME.mkv; --mask-format chooses the type)")
    sides = {kind: getattr(args, kind, None) for kind, _, _ in SIDE_OUTPUTS}
    for kind, flag, _ in SIDE_OUTPUTS:
        path = sides[kind]
        if path and path.lower().endswith((".mp4", ".avi", ".mkv", ".mov", ".npy", ".jsonl",
                                           ".csv")):
            raise OutputError(f"{path}: {flag} of several inputs is a folder (one file per "
                              "input, named after it)")
    return OutputLayout(args.output, args.mask_format or "mkv", **sides)


def _say(bar: Any, message: str) -> None:
    bar.write(f"bgsub: {message}", file=sys.stderr)


def _failure_line(result: Any) -> str:
    """One line naming the input and why it failed (most messages name it already)."""
    if result.message.startswith(result.input):
        return f"error: {result.message}"
    return f"error: {result.input}: {result.message}"


_STATUS_ORDER = ("done", "skipped", "failed", "interrupted", "not started")


def _closing_line(report: Any, seconds: float, folder: str) -> str:
    counts = report.counts()
    parts = ", ".join(f"{counts[status]} {status}" for status in _STATUS_ORDER if counts[status])
    frames = sum(result.frames for result in report.results)
    line = f"{len(report.results)} inputs: {parts}; {frames} frames in {seconds:.1f} s -> {folder}"
    failed = report.failed()
    if failed:
        line += f"; failed: {', '.join(result.name for result in failed)}"
    return line


def _source(args: argparse.Namespace) -> dict:
    """The ``open_source`` keywords of every input (the stall timeout only when given, so the
    records of batches run without it stay as they were)."""
    from bgsub.cli import common

    source = common.source_kwargs(args)
    if getattr(args, "stall_timeout", None) is not None:
        source["stall_seconds"] = args.stall_timeout
    return source


def _prepare(args: argparse.Namespace, *, method: str, params: dict, reads: list) -> tuple:
    """``(items, layout, jobs, threads per job)`` of a batch, every option and output checked
    and nothing created yet. ``reads``: the files every input's run reads besides the input
    (``--roi``, ``--config``, a model file), which no output may replace."""
    from bgsub.batch import inputs, runner
    from bgsub.cli import common

    for_workers(args, "input", "output", "vis", "flow_vis", "motion", "objects", "stats",
                "summary")
    items = inputs.expand(args.input)
    layout = _layout(args)
    jobs, per_job = jobs_and_threads(args)
    runner.check_layout(layout, items)
    outputs = [(flag, path) for item in items for flag, path in layout.flagged(item.name)]
    common.check_distinct([item.path for item in items] + reads,
                          outputs + [("--summary", args.summary)])
    runner.check_method(method, params, layout, args.preset)
    if args.summary:
        check_summary(args.summary, layout, overwrite=args.overwrite)
    return items, layout, jobs, per_job


def check_summary(path: str, layout: Any, *, overwrite: bool) -> None:
    """Refuse a ``--summary`` file that exists (without ``overwrite``) or cannot be written;
    its folder may be one of the batch's output folders, which the batch creates."""
    from bgsub.io.outputs import check_file_output, check_new_folder, output_path

    output = output_path(path)
    if output.exists() and not overwrite:
        raise OutputError(f"{output}: already exists (--overwrite replaces it, and redoes every "
                          "input; or give another --summary name)")
    folder = output.parent.resolve()
    if not folder.exists() and folder in {Path(f).resolve() for _, f in layout.folders()}:
        check_new_folder(folder, output)
    else:
        check_file_output(output, overwrite=overwrite)


def _result_line(result: Any) -> Optional[str]:
    """The one line an input's result gets while the batch runs, or None (done, or skipped
    as complete)."""
    from bgsub.batch.job import FAILED, INTERRUPTED, NOT_STARTED, SKIPPED
    from bgsub.io.outputs import frames_text

    if result.status == FAILED:
        return _failure_line(result)
    if result.status == SKIPPED and result.message:
        return f"{result.name}: {result.message}"
    if result.status == INTERRUPTED and result.frames:
        return (f"{result.name}: interrupted after {frames_text(result.frames)}, its outputs "
                "partial but valid; a rerun of the batch redoes it")
    if result.status == INTERRUPTED:
        return f"{result.name}: interrupted before its first frame; a rerun of the batch does it"
    if result.status == NOT_STARTED:
        return f"{result.name}: not started (the batch was stopped); a rerun of the batch does it"
    return None


def _report_result(bar: Any, result: Any) -> None:
    line = _result_line(result)
    if line:
        _say(bar, line)
    for warning in result.warnings:  # (most name the input already)
        named = warning if warning.startswith(result.input) else f"{result.input}: {warning}"
        _say(bar, f"warning: {named}")


def run_batch(args: argparse.Namespace, *, method: str, params: dict, reads: list) -> int:
    """``bgsub run`` with several inputs; the exit status. Nothing is created before every
    option, output and the executor (a Dask scheduler) has been checked."""
    from tqdm import tqdm

    from bgsub.batch import executors, runner, threads
    from bgsub.batch.job import INTERRUPTED, run_input
    from bgsub.cli import common

    items, layout, jobs, per_job = _prepare(args, method=method, params=params, reads=reads)
    run_params = {k: v for k, v in threads.engine_params(method, params, threads=per_job).items()
                  if k not in params}
    started = time.perf_counter()
    executor = executors.make_executor(jobs=jobs, threads=per_job, scheduler=args.scheduler)
    with executor:
        layout.create_folders()
        todo, settled = runner.plan(items, layout, method=method, params=params,
                                    run_params=run_params, source=_source(args),
                                    overwrite=args.overwrite, threads=per_job,
                                    progress=jobs == 1 and not args.scheduler and not args.quiet,
                                    writing={"codec": args.codec,
                                             "min_object_area": args.min_object_area},
                                    preset=args.preset)
        results = {result.name: result for result in settled}
        bar = tqdm(total=len(items), initial=len(settled), unit="input", desc=method,
                   file=sys.stderr, disable=args.quiet or not sys.stderr.isatty(), leave=False)
        for result in settled:
            _report_result(bar, result)

        def on_outcome(job: Any, outcome: Any) -> bool:
            result = runner.outcome_result(job, outcome)
            results[job.name] = result
            bar.update(1)
            _report_result(bar, result)
            return result.status == INTERRUPTED

        with bar:
            interrupted = runner.execute(executor, run_input, todo, on_outcome=on_outcome)
    settings = {"method": method, "preset": args.preset, "params": params, "jobs": jobs,
                "threads_per_job": per_job, "scheduler": args.scheduler}
    report = runner.BatchReport([results[item.name] for item in items], interrupted, settings)
    if args.json:
        print(json.dumps(report.to_dict(), default=str), flush=True)
    common.note(_closing_line(report, time.perf_counter() - started, args.output),
                quiet=args.quiet and report.ok)
    if args.summary:  # (after the closing line: a full disk may refuse it)
        report.write_json(args.summary)
    if interrupted:
        raise KeyboardInterrupt
    return 0 if report.ok else 1


def is_batch(args: argparse.Namespace) -> bool:
    """Whether ``args.input`` (the command line's inputs) makes a batch."""
    from bgsub.batch import inputs

    return inputs.is_batch(args.input)


def dispatch(args: argparse.Namespace, *, method: str, params: dict,
             reads: Optional[list] = None) -> Optional[int]:
    """Run a batch when ``args.input`` (a list) makes one and return its exit status; else set
    ``args.input`` to the one input and return None (a single run). ``reads``: the files a run
    reads besides its input (see :func:`run_batch`)."""
    from bgsub.batch import inputs

    if inputs.is_batch(args.input):
        return run_batch(args, method=method, params=params, reads=list(reads or []))
    jobs_and_threads(args)  # (a bad --jobs is refused as a batch refuses it)
    for flag, value in (("--jobs", args.jobs != 1), ("--scheduler", args.scheduler),
                        ("--summary", args.summary), ("--mask-format", args.mask_format)):
        if value:
            raise InputError(f"{flag} is for several inputs (a batch); give more than one "
                             "input, or a folder or glob of videos" + _SINGLE_HINTS.get(flag, ""))
    args.input = args.input[0]
    return None


_SINGLE_HINTS = {"--jobs": " (a single input runs in one process)",
                 "--mask-format": " (a single input's -o names the format: masks.mkv, or "
                                  "masks/ for binNNNNNN.png)"}
