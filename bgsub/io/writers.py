"""Consumers of :class:`bgsub.io.loop.FrameLoop` that write to sinks, and a progress bar
(:mod:`bgsub.io.pipeline` opens the sinks of a run and chooses its writers).

Each writer takes a sink and the name of the engine whose results it writes (``engine=None``:
the loop's only engine). The loop closes the sinks when the run ends: complete, or partial but
valid after an error or interrupt (each sink says which on stderr).
"""

from __future__ import annotations

import sys
from typing import Any, Callable, Mapping, Optional

import numpy as np

from bgsub.engines.base import supports
from bgsub.errors import ProcessingError
from bgsub.io.loop import Consumer, FrameResult


class SinkWriter(Consumer):
    """Writes one engine's results to a sink, and finishes the sink when the run ends."""

    needs: Optional[str] = None  # the engine attribute this writer reads

    def __init__(self, sink: Any, *, engine: Optional[str] = None) -> None:
        self.sink = sink
        self.engine = engine

    def start(self, engines: Mapping[str, Any]) -> None:
        if self.engine is None:
            if len(engines) != 1:
                raise ValueError(f"{type(self).__name__}: name the engine (engine=...) of "
                                 f"the {len(engines)} engines {', '.join(engines)}")
            self.engine = next(iter(engines))
        elif self.engine not in engines:
            raise ValueError(f"{type(self).__name__}: no engine named {self.engine!r}")
        found = engines[self.engine]
        if self.needs is not None and not supports(found, self.needs):
            raise TypeError(f"{type(found).__name__} has no {self.needs} for {self.sink.path}")

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        self.sink.finish(complete=complete, error=error)


class MaskWriter(SinkWriter):
    """Each frame's mask into a mask sink (:func:`bgsub.io.sinks.open_mask_sink`), named by
    the frame's index. A mask the sink refuses (values other than 0 and 255) stops the run
    with a :class:`ProcessingError` naming the engine."""

    def add(self, result: FrameResult) -> None:
        try:
            self.sink.write(result.masks[self.engine], result.index)
        except ValueError as err:
            raise ProcessingError(f"{self.engine} returned an unusable mask for frame "
                                  f"{result.index + 1}: {err}") from None


class VisWriter(SinkWriter):
    """Each frame with its mask overlaid, beside the mask, into a :class:`VisSink`."""

    def add(self, result: FrameResult) -> None:
        self.sink.write(result.frame, result.masks[self.engine])


class DebugImageWriter(SinkWriter):
    """The engine's ``debug_image()`` after each frame into a :class:`VideoSink`: a black
    frame where it returns None, so the video stays in step with the input."""

    needs = "debug_image"

    def __init__(self, sink: Any, *, engine: Optional[str] = None) -> None:
        super().__init__(sink, engine=engine)
        self._picture: Optional[np.ndarray] = None

    def prepare(self, result: FrameResult) -> None:
        self._picture = result.engines[self.engine].debug_image()

    def add(self, result: FrameResult) -> None:
        if self._picture is None:
            self.sink.write_blank()
        else:
            self.sink.write(self._picture)


class MotionWriter(SinkWriter):
    """The engine's ``last_motion`` after each frame into a :class:`MotionSink`."""

    needs = "last_motion"

    def add(self, result: FrameResult) -> None:
        self.sink.write(result.engines[self.engine].last_motion)


class ProgressBar(Consumer):
    """A tqdm bar on stderr counting the frames; off when ``enabled`` is False or stderr is no
    terminal."""

    def __init__(self, *, total: Optional[int] = None, desc: str = "",
                 enabled: bool = True) -> None:
        self._bar: Any = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm  # only for a bar shown: importing it is a short run's cost

            self._bar = tqdm(total=total, desc=desc, unit="frame", file=sys.stderr,
                             dynamic_ncols=True, leave=False)

    def add(self, result: FrameResult) -> None:
        if self._bar is not None:
            self._bar.update(1)

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        if self._bar is not None:
            self._bar.close()


class FrameCallback(Consumer):
    """Calls ``function(index, mask)`` with each frame's index and its (only) engine's mask."""

    def __init__(self, function: Callable[[int, np.ndarray], None]) -> None:
        self.function = function

    def add(self, result: FrameResult) -> None:
        (mask,) = result.masks.values()
        self.function(result.index, mask)
