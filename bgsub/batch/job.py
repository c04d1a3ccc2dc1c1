"""One input of a batch, as a job a local process or a Dask worker runs.

A :class:`RunJob` holds only plain, picklable values (paths, the method's name, its parameters);
:func:`run_input` opens the input, builds the engine, writes the outputs and the completion
record (:mod:`bgsub.batch.record`), and returns a :class:`JobResult`. It never raises for a
problem of its input: a failure is a result with a one-line message, so the batch goes on.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Dict, List, Optional

from bgsub.batch import record
from bgsub.errors import BgsubError

#: Statuses of a :class:`JobResult`.
DONE, SKIPPED, FAILED, INTERRUPTED, NOT_STARTED = (
    "done", "skipped", "failed", "interrupted", "not started")

StopCheck = Callable[[], bool]


@dataclass(frozen=True)
class RunJob:
    """What :func:`run_input` needs for one input.

    Attributes
    ----------
    input, name : str
        The input as :func:`bgsub.io.sources.open_source` takes it, and its name.
    outputs : dict
        ``{"masks": path, "vis": path, ...}``: a path per kind of
        :class:`bgsub.io.pipeline.OutputRequest` (side outputs only when written).
    record : str
        Its completion record.
    method : str
        The engine.
    params : dict
        The engine parameters given (they are part of the record's settings).
    run_params : dict
        Parameters that change how fast, not what (``overlap``), set per job.
    source : dict
        Keyword arguments of ``open_source`` (frame range, size, fps).
    overwrite : bool
        Replace existing outputs (set for outputs the batch itself made).
    threads : int
        OpenCV threads of the process running the job.
    progress : bool
        Show a progress bar over the frames (for a job run in the command's own process).
    writing : dict
        How the outputs are written: ``codec``, ``min_object_area`` (the fields of
        :class:`~bgsub.io.pipeline.OutputRequest` beyond the paths).
    preset : str or None
        The engine's named preset (``params`` over its values; part of the record's settings).
    """

    input: str
    name: str
    outputs: Dict[str, str]
    record: str
    method: str
    params: Dict[str, Any] = field(default_factory=dict)
    run_params: Dict[str, Any] = field(default_factory=dict)
    source: Dict[str, Any] = field(default_factory=dict)
    overwrite: bool = False
    threads: int = 1
    progress: bool = False
    writing: Dict[str, Any] = field(default_factory=dict)
    preset: Optional[str] = None

    def settings(self) -> Dict[str, Any]:
        """The settings its completion record holds (see :func:`record.settings`), with the
        ways of writing not left at their defaults (so records of batches run without them
        stay as they were)."""
        held = record.settings(input_path=self.input, method=self.method, params=self.params,
                               source=self.source)
        writing = {k: v for k, v in self.writing.items() if v not in (None, "auto")}
        if writing:
            held["writing"] = writing
        if self.preset is not None:  # (records of runs without one stay as they were)
            held["preset"] = self.preset
        return held


@dataclass
class JobResult:
    """What became of one input: ``status`` is ``done``, ``skipped``, ``failed``,
    ``interrupted`` or ``not started``; ``message`` the one-line reason of a failure; ``warnings`` notes such as a
    video that ended early."""

    name: str
    input: str
    status: str
    outputs: Dict[str, str] = field(default_factory=dict)
    frames: int = 0
    seconds: float = 0.0
    message: str = ""
    warnings: List[str] = field(default_factory=list)

    @property
    def fps(self) -> float:
        """Frames per second over the whole job (opening the input, building the engine,
        the frames, closing the outputs); 0 when no frame was processed."""
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> Dict[str, Any]:
        data = asdict(self)
        data["fps"] = round(self.fps, 3)
        data["seconds"] = round(self.seconds, 3)
        return data


def _stop_check(should_stop: Optional[StopCheck]) -> Any:
    """A frame-loop consumer that stops the run when ``should_stop()`` says so: raised while
    the frame is prepared, so the frame goes to no output and every output ends on the same
    frame (partial but valid, as after Ctrl-C)."""
    from bgsub.io.loop import Consumer

    class StopCheck(Consumer):
        def prepare(self, result: Any) -> None:
            if should_stop is not None and should_stop():
                raise KeyboardInterrupt

        def add(self, result: Any) -> None:
            pass

    return StopCheck()


def _process(job: RunJob, loop_stats: List[Any], should_stop: Optional[StopCheck],
             warnings: List[str]) -> int:
    """Run the engine over the input into the outputs; the frames processed. The frame loop's
    stats go to ``loop_stats`` first, so an interrupted run's count is known."""
    from bgsub import engines
    from bgsub.io.loop import FrameLoop
    from bgsub.io.pipeline import OutputRequest, open_outputs
    from bgsub.io.sources import open_source
    from bgsub.io.writers import ProgressBar

    source = open_source(job.input, **job.source)
    engine = engines.create_engine(job.method, job.preset, **job.params, **job.run_params)
    with contextlib.ExitStack() as stack:
        stack.enter_context(source)
        stack.callback(getattr(engine, "close", lambda: None))  # its second thread, if any
        request = OutputRequest(**job.outputs, **job.writing, overwrite=job.overwrite)
        info = source.info
        consumers = open_outputs(stack, request, width=info.width, height=info.height,
                                 fps=info.fps)[0] + [_stop_check(should_stop)]
        consumers.append(ProgressBar(total=source.info.frame_count, desc=job.name,
                                     enabled=job.progress))
        loop = FrameLoop({job.method: engine}, consumers)
        loop_stats.append(loop.stats)
        stats = loop.run(source)
    short = source.truncation()
    if short:
        warnings.append(short)
    return stats.frames


def run_input(job: RunJob, should_stop: Optional[StopCheck] = None) -> JobResult:
    """Make the outputs of one input; see the module's docstring.

    ``should_stop`` is asked before the job opens anything (``not started`` when it says so)
    and before each frame is written: then the outputs are closed partial-but-valid and the
    result is ``interrupted`` (so is Ctrl-C in this process).
    """
    from bgsub.batch.threads import limit_opencv
    from bgsub.engines.threads import reuse_freed_memory
    from bgsub.io.sink_base import stop_notes_muted

    limit_opencv(job.threads)
    reuse_freed_memory()  # (a worker process reads and writes frames as `bgsub run` does)
    result = JobResult(job.name, job.input, FAILED, outputs=dict(job.outputs))
    loop_stats: List[Any] = []
    if should_stop is not None and should_stop():  # stopped before this job's turn
        result.status = NOT_STARTED
        return result
    started = time.perf_counter()
    try:
        settings = job.settings()
        record.write(job.record, status="running", settings=settings, outputs=job.outputs)
        with stop_notes_muted():  # (the batch's own line says what became of the input)
            result.frames = _process(job, loop_stats, should_stop, result.warnings)
        record.write(job.record, status="complete", settings=settings, outputs=job.outputs,
                     frames=result.frames)
        result.status = DONE
    except KeyboardInterrupt:
        result.status = INTERRUPTED
        result.message = "interrupted (outputs partial but valid)"
    except BgsubError as err:
        result.message = str(err)
    except Exception as err:  # a bug, or a library failing on this input: this input only
        result.message = f"internal error: {type(err).__name__}: {err}"
    if loop_stats and not result.status == DONE:
        result.frames = loop_stats[0].frames
    result.seconds = time.perf_counter() - started
    return result
