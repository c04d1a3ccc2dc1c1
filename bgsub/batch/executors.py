"""Where a batch's jobs run: in this process, in local worker processes, or on a Dask cluster.

Every executor runs ``fn(item, should_stop) -> result`` for each item, where ``fn`` is a
module-level function and ``item`` a picklable value (for ``bgsub run``,
:func:`bgsub.batch.job.run_input` and a :class:`bgsub.batch.job.RunJob`; any per-sequence job of
``compare`` or ``eval`` fits the same shape). ``should_stop()`` turns true once the batch is
stopped (Ctrl-C): a job that checks it between frames closes its outputs partial-but-valid.

Use one as a context manager::

    with LocalExecutor(workers=2) as executor:
        executor.start(fn, items)
        for item, outcome in executor.results():   # in the order they finish
            ...                                    # outcome: fn's result, or the exception
                                                   # that kept it from returning one

On Ctrl-C call :meth:`stop` (the jobs not started are reported with
:class:`concurrent.futures.CancelledError`) and then :meth:`results` again for the rest.
"""

from __future__ import annotations

import concurrent.futures as cf
import functools
import multiprocessing
import signal
import time
import uuid
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Tuple

from bgsub.batch.threads import limit_opencv, worker_environment
from bgsub.errors import InputError

Outcome = Tuple[Any, Any]

#: The extra that installs the Dask client (``pip install 'bgsub[dask]'``).
DASK_EXTRA = "bgsub[dask]"


class _Executor:
    """Futures bookkeeping shared by the executors."""

    def __init__(self) -> None:
        self._pending: Dict[Any, Any] = {}   # future -> item
        self._cancelled: List[Any] = []      # items stopped before they started

    def __enter__(self) -> "_Executor":
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def close(self) -> None:
        """Release the workers (waiting for running jobs when the batch was not stopped)."""

    def _as_completed(self, futures: List[Any]) -> Iterable[Any]:
        return cf.as_completed(futures)

    def results(self) -> Iterator[Outcome]:
        """``(item, outcome)`` of every job not reported yet, as they finish (those stopped
        before they started, by :meth:`stop`, with a ``CancelledError``)."""
        while self._cancelled or self._pending:
            while self._cancelled:
                yield self._cancelled.pop(0), cf.CancelledError("not started: batch stopped")
            for future in self._as_completed(list(self._pending)):
                if future not in self._pending:
                    continue  # cancelled by stop() meanwhile: reported from _cancelled
                item = self._pending.pop(future)
                try:
                    outcome = future.result()
                except BaseException as err:  # the job's process died, the worker was lost
                    outcome = err
                yield item, outcome

    def _cancel_pending(self) -> None:
        for future, item in list(self._pending.items()):
            if future.cancel():
                del self._pending[future]
                self._cancelled.append(item)


class InlineExecutor(_Executor):
    """Jobs one after another in this process (``--jobs 1``): Ctrl-C reaches the running job
    directly, and its progress bar is this process's."""

    def start(self, fn: Callable[..., Any], items: Iterable[Any]) -> None:
        self._fn, self._items = fn, list(items)

    def results(self) -> Iterator[Outcome]:
        while self._cancelled or self._items:
            if self._cancelled:
                yield self._cancelled.pop(0), cf.CancelledError("not started: batch stopped")
            else:
                item = self._items.pop(0)
                yield item, self._fn(item, None)

    def stop(self) -> None:
        self._cancelled += self._items
        self._items = []


# ---------------------------------------------------------------------- local processes

_STOP_EVENT: Any = None


def _init_worker(stop_event: Any, threads: int) -> None:
    # Ctrl-C reaches every process of the terminal's group; the batch's own process decides
    # what stops and tells the workers through the event, so a job stops between frames only.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    global _STOP_EVENT
    _STOP_EVENT = stop_event
    limit_opencv(threads)


def _stop_requested() -> bool:
    return _STOP_EVENT is not None and _STOP_EVENT.is_set()


def _call_in_worker(fn: Callable[..., Any], item: Any) -> Any:
    return fn(item, _stop_requested)


class LocalExecutor(_Executor):
    """Up to ``workers`` jobs at once in worker processes of this machine, each held to
    ``threads`` BLAS/OpenCV threads (see :mod:`bgsub.batch.threads`).

    The workers are started with "spawn": fresh interpreters that read the thread limits from
    their environment when numpy loads (a forked child would inherit the parent's thread pools,
    and forking a process that runs threads is unsafe).
    """

    def __init__(self, *, workers: int, threads: int = 1) -> None:
        super().__init__()
        self.workers, self.threads = max(1, int(workers)), max(1, int(threads))
        context = multiprocessing.get_context("spawn")
        self._stop = context.Event()
        with worker_environment(self.threads):
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=context,
                                                initializer=_init_worker,
                                                initargs=(self._stop, self.threads))

    def start(self, fn: Callable[..., Any], items: Iterable[Any]) -> None:
        with worker_environment(self.threads):  # the workers start as jobs are submitted
            for item in items:
                self._pending[self._pool.submit(_call_in_worker, fn, item)] = item

    def stop(self) -> None:
        """Tell the running jobs to stop after their current frame; cancel the others."""
        self._stop.set()
        self._cancel_pending()

    def close(self) -> None:
        self._pool.shutdown(wait=not self._stop.is_set(), cancel_futures=True)


# ---------------------------------------------------------------------- Dask


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise InputError(f"--scheduler needs Dask's distributed client: pip install "
                         f"'{DASK_EXTRA}'") from None
    return distributed


class DaskStop:
    """``should_stop`` of a job on a Dask worker: the batch's named ``distributed.Event``,
    asked at most once per ``every`` seconds (each question is a round trip to the
    scheduler)."""

    def __init__(self, name: str, every: float = 1.0) -> None:
        self.name, self.every = name, every
        self._asked, self._set = 0.0, False

    def __call__(self) -> bool:
        now = time.monotonic()
        if not self._set and now - self._asked >= self.every:
            from distributed import Event

            self._asked, self._set = now, Event(self.name).is_set()
        return self._set


def _call_on_dask(item: Any, fn: Callable[..., Any], stop_name: str) -> Any:
    return fn(item, DaskStop(stop_name))


class DaskExecutor(_Executor):
    """One task per job on the Dask cluster whose scheduler is at ``address``
    (``tcp://host:8786``); the workers must reach the inputs and outputs at the same paths."""

    def __init__(self, address: str, *, timeout: float = 10.0) -> None:
        super().__init__()
        distributed = _import_distributed()
        try:
            self._client = distributed.Client(address, timeout=timeout)
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError(f"--scheduler {address}: cannot reach the Dask scheduler "
                             f"({err})") from None
        self._stop_name = f"bgsub-stop-{uuid.uuid4().hex}"

    def _as_completed(self, futures: List[Any]) -> Iterable[Any]:
        from distributed import as_completed

        return as_completed(futures)

    def start(self, fn: Callable[..., Any], items: Iterable[Any]) -> None:
        items = list(items)
        futures = self._client.map(_call_on_dask, items, fn=fn, stop_name=self._stop_name,
                                   pure=False)
        self._pending.update(zip(futures, items))

    def stop(self) -> None:
        """Set the batch's stop event. Tasks are not cancelled: a running one would go on
        unseen (Dask cannot interrupt it), so each ends itself, a queued one before it opens
        anything (:func:`bgsub.batch.job.run_input` asks first)."""
        from distributed import Event

        Event(self._stop_name, client=self._client).set()

    def close(self) -> None:
        self._client.close()


def make_executor(*, jobs: int, threads: int, scheduler: Optional[str] = None) -> _Executor:
    """The executor for ``--jobs``/``--scheduler``: Dask when ``scheduler`` is given, else local
    processes for ``jobs`` > 1, else this process."""
    if scheduler:
        return DaskExecutor(scheduler)
    if jobs > 1:
        return LocalExecutor(workers=jobs, threads=threads)
    return InlineExecutor()


def _call_plain(fn: Callable[[Any], Any], numbered: Tuple[int, Any],
                should_stop: Any) -> Any:
    return fn(numbered[1])


def ordered_map(fn: Callable[[Any], Any], items: Iterable[Any], *, jobs: int = 1,
                scheduler: Optional[str] = None) -> List[Any]:
    """``[fn(item) for item in items]``, on ``jobs`` local processes or the Dask cluster at
    ``scheduler``: the per-sequence loop of ``bgsub eval`` and ``compare`` on a dataset.

    ``fn`` must be a module-level function and the items picklable. The results come in the
    items' order; the first exception, in that order, is raised as it is (a
    :class:`bgsub.errors.BgsubError` keeps its one-line message). Ctrl-C cancels the items not
    started and is raised; the running ones finish unseen (they write nothing that matters).
    """
    from bgsub.batch.threads import threads_per_job

    items = list(items)
    if not scheduler and (jobs <= 1 or len(items) <= 1):
        return [fn(item) for item in items]
    outcomes: Dict[int, Any] = {}
    executor = make_executor(jobs=min(jobs, len(items)), scheduler=scheduler,
                             threads=threads_per_job(min(jobs, len(items))))
    with executor:
        executor.start(functools.partial(_call_plain, fn), list(enumerate(items)))
        try:
            for (index, _), outcome in executor.results():
                outcomes[index] = outcome
        except KeyboardInterrupt:
            executor.stop()
            raise
    for index in range(len(items)):
        if isinstance(outcomes[index], BaseException):
            raise outcomes[index]
    return [outcomes[index] for index in range(len(items))]
