"""A batch from start to end: plan a job per input, run them on an executor, report.

:func:`plan` turns the inputs into :class:`~bgsub.batch.job.RunJob` values, skipping those whose
outputs are complete (:mod:`bgsub.batch.record`); :func:`execute` runs any job function on an
executor (:mod:`bgsub.batch.executors`) and survives Ctrl-C: the first stops the batch (running
jobs close their outputs partial-but-valid, the others do not start) and the results gathered so
far are returned; a second gives up waiting. :class:`BatchReport` is what the command prints
and the ``--summary`` JSON.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Tuple

from bgsub.batch import record
from bgsub.batch.inputs import BatchInput
from bgsub.batch.job import DONE, FAILED, NOT_STARTED, SKIPPED, JobResult, RunJob
from bgsub.batch.plan import OutputLayout
from bgsub.errors import InputError, OutputError
from bgsub.io.sinks import write_atomically
from bgsub.io.streams import is_live


@dataclass
class BatchReport:
    """The results of a batch, in the order of its inputs."""

    results: List[JobResult] = field(default_factory=list)
    interrupted: bool = False
    settings: Dict[str, Any] = field(default_factory=dict)

    def counts(self) -> Counter:
        """How many inputs ended with each status."""
        return Counter(result.status for result in self.results)

    def failed(self) -> List[JobResult]:
        """The inputs that failed."""
        return [result for result in self.results if result.status == FAILED]

    @property
    def ok(self) -> bool:
        """Every input is done or skipped."""
        return all(result.status in (DONE, SKIPPED) for result in self.results)

    def to_dict(self) -> Dict[str, Any]:
        return {"inputs": len(self.results), "counts": dict(self.counts()),
                "interrupted": self.interrupted, "settings": self.settings,
                "results": [result.to_dict() for result in self.results]}

    def write_json(self, path: str) -> None:
        data = json.dumps(self.to_dict(), indent=1, default=str) + "\n"
        write_atomically(Path(path), data.encode("utf-8"), what="the batch summary")


def plan(items: Iterable[BatchInput], layout: OutputLayout, *, method: str,
         params: Mapping[str, Any], run_params: Mapping[str, Any],
         source: Mapping[str, Any], overwrite: bool, threads: int, progress: bool = False,
         writing: Optional[Mapping[str, Any]] = None,
         preset: Optional[str] = None) -> Tuple[List[RunJob], List[JobResult]]:
    """The jobs to run, and the results of the inputs that need none (complete outputs:
    ``skipped``, with the reason when they were made with other settings; outputs that are not
    the batch's to replace: ``failed``, with the reason).
    ``progress``: the jobs show a bar over their frames (when they run in this process);
    ``writing``: how the outputs are written (:attr:`RunJob.writing`); ``preset``: the
    engine's named preset (:attr:`RunJob.preset`)."""
    jobs: List[RunJob] = []
    settled: List[JobResult] = []
    for item in items:
        outputs = layout.outputs(item.name)
        job = RunJob(item.path, item.name, outputs, layout.record(item.name), method,
                     dict(params), dict(run_params), dict(source), overwrite, threads, progress,
                     dict(writing or {}), preset)
        decision, refused = record.decide(job.record, settings=job.settings(),
                                          outputs=outputs, overwrite=overwrite)
        if decision == record.SKIP and is_live(item.path):
            decision = record.RUN
            refused = (f"{outputs['masks']} exists, and {item.path} is a live source, recorded "
                       "anew each time (--overwrite replaces it)")
        if decision in (record.SKIP, record.KEEP):
            settled.append(JobResult(item.name, item.path, SKIPPED, outputs,
                                     message=refused or ""))
        elif refused:
            settled.append(JobResult(item.name, item.path, FAILED, outputs, message=refused))
        else:
            jobs.append(RunJob(**{**job.__dict__, "overwrite": decision == record.REDO}))
    return jobs, settled


def outcome_result(job: RunJob, outcome: Any) -> JobResult:
    """The :class:`JobResult` of ``job`` from what an executor reported for it."""
    if isinstance(outcome, JobResult):
        return outcome
    result = JobResult(job.name, job.input, FAILED, outputs=dict(job.outputs))
    if isinstance(outcome, BaseException) and type(outcome).__name__ == "CancelledError":
        result.status = NOT_STARTED
    elif type(outcome).__name__ == "BrokenProcessPool":  # (a worker's death breaks the pool)
        result.message = ("its worker process ended abruptly (killed, or out of memory), and "
                          "the batch's other workers with it; a rerun of the batch redoes it")
    else:
        result.message = f"the worker running it failed: {type(outcome).__name__}: {outcome}"
    return result


def execute(executor: Any, fn: Callable[..., Any], items: List[Any], *,
            on_outcome: Callable[[Any, Any], bool]) -> bool:
    """Run ``fn(item, should_stop)`` for every item on ``executor`` (started here, not closed);
    ``on_outcome(item, outcome)`` gets each as it finishes and returns whether it was stopped by
    an interruption. Returns whether the batch was interrupted."""
    executor.start(fn, items)
    interrupted = False
    while True:
        try:
            for item, outcome in executor.results():
                if on_outcome(item, outcome) and not interrupted:
                    interrupted = True  # Ctrl-C reached the job first (this process's job)
                    executor.stop()
            return interrupted
        except KeyboardInterrupt:
            if interrupted:
                raise  # the second Ctrl-C: stop waiting for the running jobs
            interrupted = True
            executor.stop()


def check_method(method: str, params: Mapping[str, Any], layout: OutputLayout,
                 preset: Optional[str] = None) -> None:
    """Refuse, before any input is read, a method, preset or parameters that every input would
    fail with: unknown ones, or side outputs the method cannot make."""
    from bgsub import engines

    engine = engines.create_engine(method, preset, **params)
    getattr(engine, "close", lambda: None)()  # its second thread, if any
    if layout.flow_vis and not callable(getattr(engine, "debug_image", None)):
        raise InputError(f"--flow-vis: method {method!r} cannot draw its motion (it has no "
                         "debug_image); use a moving-camera method such as grbm")
    if layout.motion and not hasattr(engine, "last_motion"):
        raise InputError(f"--motion: method {method!r} estimates no camera motion; use a "
                         "moving-camera method such as grbm or compensated")


def check_layout(layout: OutputLayout, items: List[BatchInput]) -> None:
    """Refuse output folders that are input folders or hold input videos (what is written
    there would be read as inputs next time), one folder for two side outputs of the same
    extension, and an input whose masks would go to the batch's record folder."""
    inputs = {Path(item.path).resolve() for item in items}
    video_folders = {path.parent for path in inputs if path.is_file()}
    seen: Dict[Tuple[Path, str], str] = {}
    for flag, folder in layout.folders():
        resolved = Path(folder).resolve()
        if resolved in inputs:
            raise OutputError(f"{folder}: {flag} is an input folder; give another folder")
        if resolved in video_folders:
            raise OutputError(f"{folder}: {flag} is the folder of input videos; what is written "
                              "there would be read as inputs next time (give another folder)")
        extension = layout.extension(flag)
        if (resolved, extension) in seen:
            raise OutputError(f"{folder}: given to both {seen[resolved, extension]} and {flag}")
        seen[resolved, extension] = flag
    records = Path(layout.record_folder).resolve()
    for item in items:
        if Path(layout.outputs(item.name)["masks"]).resolve() == records:
            raise OutputError(f"{item.path}: its masks would go to {records}, the batch's own "
                              "record folder; rename the input, or give another --mask-format")
