"""Cores per job: several engines at once must not each start a thread per core.

numpy's BLAS and OpenCV size their thread pools from the machine's cores. N jobs on N cores
would then run N x N threads that preempt one another; each job is held to ``cores // N``
threads instead: BLAS through the environment of the worker processes (read when numpy loads,
so it is set before they start), OpenCV with ``cv2.setNumThreads`` in each worker, and the
moving-camera engines' second thread (``overlap``) turned off when a job has one core.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any, Dict, Iterator, Mapping

#: Environment variables that size the BLAS and OpenMP thread pools numpy and OpenCV use.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # macOS, Windows
        return max(1, os.cpu_count() or 1)


def threads_per_job(jobs: int) -> int:
    """Threads each of ``jobs`` concurrent jobs may use on this machine (at least 1)."""
    return max(1, usable_cores() // max(1, jobs))


@contextlib.contextmanager
def worker_environment(threads: int) -> Iterator[None]:
    """Set :data:`THREAD_VARIABLES` to ``threads`` while worker processes are started (they
    inherit the environment), and restore them after."""
    saved = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    os.environ.update({name: str(threads) for name in THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def limit_opencv(threads: int) -> None:
    """OpenCV's own thread pool to ``threads`` in this process."""
    import cv2

    cv2.setNumThreads(int(threads))


def engine_params(method: str, params: Mapping[str, Any], *, threads: int) -> Dict[str, Any]:
    """``params`` plus what holds engine ``method`` to ``threads`` cores: ``overlap=0`` (no
    second thread) for engines that take it when ``threads`` is 1, unless given in ``params``.
    (The engines' own ``threads`` parameter already defaults to one BLAS/OpenCV thread.)"""
    from bgsub import engines

    known = engines.get_engine_spec(method).params
    chosen = dict(params)
    if "overlap" in known and threads < 2:
        chosen.setdefault("overlap", 0)
    return chosen
