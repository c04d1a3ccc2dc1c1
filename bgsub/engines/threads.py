"""Threads of the moving-camera engines: how many workers BLAS and OpenCV may use while a frame
is processed (:class:`limited_threads`), and the engine's own second thread
(:class:`SecondThread`).

One frame's work is many small matmuls (a few hundred to ~1100 patches x 169 x 200) and
whole-frame OpenCV calls on 320x240 images. Handing those to worker threads costs more than it
saves: a multi-threaded OpenBLAS spin-waits for a busy core, and OpenCV's threads cost CPU time
for these small images (docs/BENCHMARKS.md). So the engines run each frame with ``threads``
(default 1) BLAS and OpenCV threads and restore the previous settings afterwards. The settings
are process-wide: engines stepped concurrently from several Python threads should all use the
same ``threads`` value.

Every frame allocates and frees a few dozen frame-sized arrays in each thread. glibc's malloc
returns such blocks to the kernel when they are freed (above its dynamic mmap threshold, and
whenever a thread's arena has more than its trim threshold free at the top), and the next
frame's arrays fault their pages in again, thousands of page faults a frame in the second
thread. :func:`reuse_freed_memory` (called when a second thread
starts, and by the command line) asks malloc to keep freed blocks for reuse instead.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
from typing import Any, Callable, Iterator, Optional

import cv2
import numpy as np

__all__ = ["limited_threads", "blas_threads", "reuse_freed_memory", "SecondThread"]

_BLAS_SYMBOLS = (
    ("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
    ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
    ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
    ("openblas_set_num_threads", "openblas_get_num_threads"),
)
_blas_api: Optional[tuple] = None  # (set, get) or () when not found


def _openblas() -> tuple:
    """``(set_num_threads, get_num_threads)`` of the OpenBLAS numpy uses, or ``()``."""
    global _blas_api
    if _blas_api is not None:
        return _blas_api
    _blas_api = ()
    import ctypes
    import glob
    import os

    # numpy's own first: wheels bundle scipy-openblas in numpy.libs (scipy may load another).
    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    candidates = sorted(glob.glob(os.path.join(libs, "*openblas*")))
    try:  # Linux: an OpenBLAS numpy was linked against elsewhere (opening it again shares it)
        with open("/proc/self/maps") as maps:
            candidates += sorted({line.split()[-1] for line in maps
                                  if "openblas" in line.lower()
                                  and line.split()[-1].startswith("/")})
    except OSError:
        pass
    for path in candidates:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _BLAS_SYMBOLS:
            if hasattr(lib, set_name) and hasattr(lib, get_name):
                setter, getter = getattr(lib, set_name), getattr(lib, get_name)
                setter.argtypes, setter.restype = [ctypes.c_int], None
                getter.argtypes, getter.restype = [], ctypes.c_int
                _blas_api = (setter, getter)
                return _blas_api
    return _blas_api


class limited_threads:
    """Context manager: at most ``n`` OpenBLAS and OpenCV worker threads inside, the previous
    counts restored on exit (``n <= 0``: change nothing). Without an OpenBLAS that exposes
    ``openblas_set_num_threads`` only OpenCV is limited (set ``OPENBLAS_NUM_THREADS=1``)."""

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self._saved: Optional[tuple] = None

    def __enter__(self) -> "limited_threads":
        if self.n > 0:
            blas = _openblas()
            old_blas = blas[1]() if blas else None
            old_cv = cv2.getNumThreads()
            if blas and old_blas > self.n:
                blas[0](self.n)
            if old_cv > self.n:
                cv2.setNumThreads(self.n)
            self._saved = (old_blas, old_cv)
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._saved is None:
            return
        old_blas, old_cv = self._saved
        self._saved = None
        blas = _openblas()
        if blas and old_blas is not None and old_blas > self.n:
            blas[0](old_blas)
        if old_cv > self.n:
            cv2.setNumThreads(old_cv)


def blas_threads() -> Optional[int]:
    """The worker threads of the OpenBLAS numpy uses, or None when it exposes no count."""
    blas = _openblas()
    return blas[1]() if blas else None


#: glibc's mallopt() parameters and the values :func:`reuse_freed_memory` sets: blocks up to 32
#: MiB (the largest mmap threshold glibc takes on 64-bit systems; a 1280x720 float32 colour
#: frame is 11 MiB) come from the heap, and up to 64 MiB free at the top of a heap stay there.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MALLOC_SETTINGS = ((_M_MMAP_THRESHOLD, 32 << 20), (_M_TRIM_THRESHOLD, 64 << 20))
_malloc_tuned: Optional[bool] = None


def reuse_freed_memory() -> bool:
    """Make glibc's malloc keep freed frame-sized blocks for reuse rather than return them to
    the kernel (the module docstring says why), once per process; True when the settings are
    in effect. Where the C library has no ``mallopt`` (macOS, Windows, musl's stub) nothing
    changes and it returns False. Memory stays flat: the same sizes are freed and reused every
    frame, and what a heap keeps free is bounded (64 MiB)."""
    global _malloc_tuned
    if _malloc_tuned is None:
        _malloc_tuned = _set_malloc_options()
    return _malloc_tuned


def _set_malloc_options() -> bool:
    import ctypes
    import platform

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all(mallopt(param, value) == 1 for param, value in _MALLOC_SETTINGS)


class SecondThread:
    """The engine's second thread: :meth:`alongside` runs jobs in it while the caller's block
    runs (``overlap=1``), or before the block in the calling thread (``overlap=0``). Pickles
    without its thread; a copy starts its own when it needs one."""

    def __init__(self, *, overlap: int, name: str) -> None:
        self.overlap = int(overlap)
        self.name = name
        self._worker: Optional[concurrent.futures.ThreadPoolExecutor] = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_worker": None}

    @contextlib.contextmanager
    def alongside(self, *jobs: Callable[[], None]) -> Iterator[None]:
        """``jobs`` run in order in the second thread while the ``with`` body runs, or before
        the body when ``overlap`` is 0. Always joined before the block ends: the jobs change
        the engine's state, which must be settled when ``apply()`` returns or raises. Their
        error is raised unless the body raised one."""
        if self.overlap <= 0:
            for job in jobs:
                job()
            yield
            return
        if self._worker is None:
            reuse_freed_memory()  # (a new thread's arena would otherwise fault every frame)
            self._worker = concurrent.futures.ThreadPoolExecutor(
                max_workers=1, thread_name_prefix=f"bgsub-{self.name}")
        future = self._worker.submit(lambda: [job() for job in jobs])
        try:
            yield
        except BaseException:
            future.exception()  # wait for it; the body's error is the one reported
            raise
        error = future.exception()
        if error is not None:
            raise error

    def close(self) -> None:
        """Stop the thread now rather than when the engine is garbage-collected; a later
        :meth:`alongside` starts it again."""
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.shutdown(wait=True)
