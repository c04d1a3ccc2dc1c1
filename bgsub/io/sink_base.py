"""What every sink shares: the :class:`Sink` base class (finish once, say what a stopped run
left in the output) and the checks of what is written to it."""

from __future__ import annotations

import contextlib
import contextvars
import math
import numbers
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, Iterator, Optional, Tuple

import numpy as np

from bgsub.errors import BgsubError, OutputError
from bgsub.io.outputs import frames_text, say


def stop_reason(exc_type: Optional[type]) -> str:
    """How a sink's message names what stopped the run of an exception of ``exc_type``."""
    return "interrupted" if exc_type is not None and issubclass(exc_type, KeyboardInterrupt) \
        else "stopped by an error"


_stop_notes_muted = contextvars.ContextVar("bgsub_stop_notes_muted", default=False)


@contextlib.contextmanager
def stop_notes_muted() -> Iterator[None]:
    """Inside the ``with`` block, sinks stopped by an interruption or an error do not say what
    they hold: a batch reports each input in one line of its own instead."""
    token = _stop_notes_muted.set(True)
    try:
        yield
    finally:
        _stop_notes_muted.reset(token)


def check_image(image: np.ndarray, *, ndims: Tuple[int, ...], what: str) -> None:
    """``ValueError`` naming ``what`` unless ``image`` is a uint8 array of one of ``ndims``
    dimensions: ``(H, W)`` (2) or ``(H, W, 3)`` (3)."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in ndims \
            or (image.ndim == 3 and image.shape[2] != 3):
        shape = getattr(image, "shape", None)
        dtype = getattr(image, "dtype", type(image).__name__)
        wanted = " or ".join(_SHAPES[n] for n in ndims)
        raise ValueError(f"{what} must be a uint8 array of shape {wanted}, got shape {shape} "
                         f"dtype {dtype}")


_SHAPES = {2: "(H, W)", 3: "(H, W, 3)"}


def check_size(path: Path, width: Any, height: Any, what: str) -> None:
    """:class:`OutputError` unless ``width`` and ``height`` are whole numbers of at least 1."""
    for value in (width, height):
        # (A whole float is fine: cv2.VideoCapture.get(CAP_PROP_FRAME_WIDTH) gives 320.0.)
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and math.isfinite(value) and float(value).is_integer() and value >= 1):
            raise OutputError(f"{path}: cannot write {what} of {width}x{height} pixels; "
                              "width and height must be whole numbers of at least 1")


def binary_mask(mask: Any) -> np.ndarray:
    """``mask`` as ``(H, W) uint8`` 0/255 (a bool mask: True -> 255); ``ValueError`` for any
    other dtype, shape or values (a 0/1 mask would read as all background)."""
    if isinstance(mask, np.ndarray) and mask.dtype == bool:
        mask = mask.view(np.uint8) * np.uint8(255)
    check_image(mask, ndims=(2,), what="a mask")
    if np.count_nonzero(mask) != np.count_nonzero(mask == 255):
        found = np.unique(mask[(mask != 0) & (mask != 255)])[:3].tolist()
        raise ValueError(f"a mask must hold only 0 (background) and 255 (foreground), not "
                         f"{', '.join(map(str, found))}; multiply a 0/1 mask by 255 or give a "
                         "bool mask")
    return mask


class Sink(ABC):
    """What every sink shares: a context manager that finishes its output once, and says on
    stderr what an output holds when the run stopped early."""

    path: Path
    _finished = False

    @property
    @abstractmethod
    def frames_written(self) -> int:
        """Frames written so far."""

    @abstractmethod
    def close(self) -> None:
        """Finish the output (also after an interruption: the partial output stays valid)."""

    def finish(self, *, error: Optional[BaseException] = None, complete: bool = False) -> None:
        """Finish the output once and, when ``error`` stopped the run, say what it holds.

        Parameters
        ----------
        error : exception, optional
            What stopped the run (``KeyboardInterrupt`` for Ctrl-C or a signal), or None when
            it ended normally.
        complete : bool
            Every frame of the run is in this output (the frames ran out): an error after that
            (another output failing as it is finished) does not make it partial.

        A failure to finish the output raises when ``error`` is None; otherwise the run's own
        error is the one to report, and this output's failure gets its line on stderr. Later
        calls (and leaving a ``with`` block after this) do nothing.
        """
        if self._finished:
            return
        self._finished = True
        try:
            self.close()
        except BgsubError as err:
            if error is None:
                raise
            say(f"error: {err}")
            return
        interrupted = isinstance(error, KeyboardInterrupt)
        # A sink that never got a frame because opening a later output failed stays silent: the
        # error itself is the one line the user needs.
        if error is not None and (self.frames_written or interrupted) and not self._told() \
                and not _stop_notes_muted.get():
            say(self._partial_message(stop_reason(type(error)), complete=complete))

    def _told(self) -> bool:
        """Whether an error has already said what became of the output."""
        return False

    def _partial_message(self, reason: str, *, complete: bool) -> str:
        n = self.frames_written
        if n == 0:
            return f"{self.path}: not written ({reason} before the first frame)"
        if complete:
            run = "the run was interrupted" if reason == "interrupted" else f"the run {reason}"
            return f"{self.path} is complete: {run} after writing all {frames_text(n)}"
        return f"{self.path} is partial ({reason}) but valid: it holds {frames_text(n)}"

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.finish(error=exc)
