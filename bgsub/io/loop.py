"""The frame loop: frames in, one or several engines, any number of consumers.

:class:`FrameLoop` reads ``(index, frame)`` pairs (a :class:`bgsub.io.sources.FrameSource`),
gives each frame to every engine, and hands the frame with all its masks (a
:class:`FrameResult`) to each :class:`Consumer`: the mask, picture and motion writers below, a
progress bar, a ground-truth scorer. ``bgsub run`` is this loop with one engine; a comparison is
the same loop with several.

The loop owns what every command needs around the frames:

* **one frame, every output**: each frame goes to all consumers or, when interrupted, to none
  (Ctrl-C, SIGTERM or SIGHUP arriving while a frame is being handed out waits until every
  consumer has it), so outputs line up frame for frame;
* **shutdown**: when the frames run out, or an error or a signal stops the run, every consumer
  is closed (outputs are finished under their final names, partial but valid, and each says
  once what it holds); a second signal during that shutdown is ignored, so it cannot cut the
  finishing of an output short. The interrupt (``KeyboardInterrupt``, or the command line's
  ``Terminated``) or error is then raised again for the caller;
* **look-back start**: the engines that can are handed the stream's first frames ahead of the
  first mask (:func:`bgsub.engines.lookback.primed`);
* **counting**: frames, wall-clock time, and per engine its time in ``apply`` (and in that
  read-ahead) and the frames whose ``last_status`` was not ``"ok"`` (:class:`RunStats`, also
  readable as :attr:`FrameLoop.stats` after an interrupt).

Signals are held and ignored only for those that already have a Python handler (Ctrl-C's, and
the command line's SIGTERM/SIGHUP handler), and only in the main thread.
"""

from __future__ import annotations

import contextlib
from abc import ABC, abstractmethod
import signal
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import (Any, Callable, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence,
                    Tuple)

import numpy as np

from bgsub.engines.base import supports
from bgsub.engines.lookback import primed
from bgsub.errors import ProcessingError

#: Signals the loop holds back while a frame is handed out: Ctrl-C, and the command line's
#: SIGTERM / SIGHUP.
HELD_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                     if hasattr(signal, name))


@dataclass(frozen=True)
class FrameResult:
    """One frame and what every engine made of it.

    Attributes
    ----------
    index : int
        0-based position of the frame in the input (``bin{index + 1:06d}.png`` names its mask).
    frame : (H, W, 3) uint8 array
        The frame, BGR, as the engines got it.
    masks : mapping of str to (H, W) uint8 array
        Each engine's mask by engine name, 0 = background, 255 = foreground (or bool).
    engines : mapping of str to engine
        The engines by name, for what they report after the frame (``last_motion``,
        ``last_status``, ``debug_image()``).
    seconds : mapping of str to float
        Each engine's time in ``apply`` for this frame, by engine name.
    """

    index: int
    frame: np.ndarray
    masks: Mapping[str, np.ndarray]
    engines: Mapping[str, Any]
    seconds: Mapping[str, float] = field(default_factory=dict)


class Consumer(ABC):
    """Receives a run's frames. Subclasses implement :meth:`add`; the rest is optional.

    The loop calls, in order: :meth:`start` once, then per frame :meth:`prepare` on every
    consumer and :meth:`add` on every consumer, and :meth:`close` once at the end (also after
    an error or an interrupt, and also when :meth:`start` of a later consumer failed).
    """

    def start(self, engines: Mapping[str, Any]) -> None:
        """Before the first frame: check that the engines provide what this consumer reads
        (``TypeError`` otherwise)."""

    def prepare(self, result: FrameResult) -> None:
        """Slow per-frame work (drawing, scoring) before any consumer gets the frame. An
        interrupt here leaves the frame out of every output."""

    @abstractmethod
    def add(self, result: FrameResult) -> None:
        """Take the frame. Called with signals held: every consumer gets a frame or none."""

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        """The run ended. ``complete``: every frame of the input was added (the frames ran
        out); ``error``: what stopped the run (``KeyboardInterrupt`` for a signal), or None.
        Finish the outputs here; an exception raised while ``error`` is None stops the run
        (the consumers closed after this one see it as ``error``)."""


@dataclass
class EngineStats:
    """What one engine did during a run.

    Attributes
    ----------
    seconds : float
        Time spent in its ``apply``.
    statuses : Counter
        How many frames ended with each ``last_status`` other than ``"ok"``.
    has_status : bool
        Whether the engine reports a ``last_status`` at all.
    """

    seconds: float = 0.0
    statuses: Counter = field(default_factory=Counter)
    has_status: bool = False

    @property
    def not_ok(self) -> int:
        """Frames whose status was not ``"ok"``."""
        return sum(self.statuses.values())


@dataclass
class RunStats:
    """What a run did, frame by frame as the consumers got them.

    Attributes
    ----------
    frames : int
        Frames every consumer got.
    seconds : float
        Wall-clock time of the loop (reading, engines, consumers).
    engines : dict of str to EngineStats
        Per engine, by name.
    complete : bool
        The frames ran out (no error or interrupt stopped the run before).
    """

    frames: int = 0
    seconds: float = 0.0
    engines: Dict[str, EngineStats] = field(default_factory=dict)
    complete: bool = False

    @property
    def fps(self) -> float:
        """Frames per second."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")

    @property
    def statuses(self) -> Counter:
        """The not-ok statuses of all engines together."""
        return sum((e.statuses for e in self.engines.values()), Counter())

    @property
    def has_status(self) -> bool:
        """Whether any engine reports a ``last_status``."""
        return any(e.has_status for e in self.engines.values())

    @property
    def not_ok(self) -> int:
        """Frames (summed over engines) whose status was not ``"ok"``."""
        return sum(e.not_ok for e in self.engines.values())


class _Interrupts:
    """The loop's handler for :data:`HELD_SIGNALS`: holds them while a frame is handed out,
    delivers the first to the handler it replaced (which raises ``KeyboardInterrupt``), and
    drops every later one: the run is already stopping."""

    def __init__(self) -> None:
        self._saved: Dict[int, Callable] = {}
        self._held: Optional[List[int]] = None
        self.raised = False  # a signal stopped the run

    def __enter__(self) -> "_Interrupts":
        if threading.current_thread() is threading.main_thread():
            for signum in HELD_SIGNALS:
                handler = signal.getsignal(signum)
                if callable(handler):  # not SIG_DFL / SIG_IGN: their action cannot be deferred
                    self._saved[signum] = handler
                    signal.signal(signum, self._on_signal)
        return self

    def __exit__(self, *exc_info) -> None:
        for signum, handler in self._saved.items():
            signal.signal(signum, handler)

    def _on_signal(self, signum: int, frame: Any) -> None:
        if self.raised:
            return
        if self._held is not None:
            self._held.append(signum)
            return
        self._deliver(signum, frame)

    def _deliver(self, signum: int, frame: Any) -> None:
        try:
            self._saved[signum](signum, frame)
        except BaseException:
            self.raised = True
            raise

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """Hold the signals until the block ends, then deliver the first one held."""
        if self._held is not None:  # (nested)
            yield
            return
        self._held = []
        try:
            yield
        finally:
            held, self._held = self._held, None
            if held and not self.raised:
                self._deliver(held[0], None)


@contextlib.contextmanager
def hold_interrupts() -> Iterator[None]:
    """Hold back Ctrl-C (and any of :data:`HELD_SIGNALS` with a Python handler, such as the
    command line's SIGTERM) until the block ends, then deliver it. Nothing is held outside the
    main thread, where handlers cannot be changed."""
    with _Interrupts() as interrupts, interrupts.held():
        yield


class FrameLoop:
    """Feed frames through engines to consumers.

    Parameters
    ----------
    engines : mapping of str to engine, or one engine
        Each has OpenCV's ``apply(frame) -> (H, W) uint8 mask``. One engine alone is named by
        its class.
    consumers : sequence of Consumer
        Closed in reverse order at the end, as a ``with`` block would.

    Attributes
    ----------
    stats : RunStats
        Filled as the frames go by; after an interrupt, the frames every consumer got.
    """

    def __init__(self, engines: Any, consumers: Sequence[Consumer]) -> None:
        if not isinstance(engines, Mapping):
            engines = {type(engines).__name__: engines}
        if not engines:
            raise ValueError("FrameLoop needs at least one engine")
        self.engines: Dict[str, Any] = dict(engines)
        self.consumers: List[Consumer] = list(consumers)
        self._ran = False
        self.stats = RunStats(engines={
            name: EngineStats(has_status=supports(engine, "last_status"))
            for name, engine in self.engines.items()})

    def run(self, frames: Iterable[Tuple[int, np.ndarray]]) -> RunStats:
        """Run every frame of ``frames`` (``(index, (H, W, 3) uint8)`` pairs), then close the
        consumers; returns :attr:`stats`. An error or interrupt closes them too and is raised
        again once they are closed. A loop runs once (its consumers are closed after)."""
        if self._ran:
            raise RuntimeError("a FrameLoop runs once: its consumers are closed")
        self._ran = True
        started = time.perf_counter()
        with _Interrupts() as interrupts, contextlib.ExitStack() as stack:
            for consumer in self.consumers:
                stack.push(self._closer(consumer, interrupts))
                consumer.start(self.engines)
            try:
                took: Dict[str, float] = {}
                frames = primed(self.engines, frames, took=took)
                for name, seconds in took.items():  # (the read-ahead counts as the engine's)
                    self.stats.engines[name].seconds += seconds
                for index, frame in frames:
                    self._one_frame(index, frame, interrupts)
                self.stats.complete = True
            finally:
                self.stats.seconds = time.perf_counter() - started
        return self.stats

    def _closer(self, consumer: Consumer, interrupts: _Interrupts) -> Callable[..., bool]:
        def close(exc_type, error, tb) -> bool:
            with interrupts.held():  # an output being finished is not cut short
                consumer.close(complete=self.stats.complete, error=error)
            return False
        return close

    def _one_frame(self, index: int, frame: np.ndarray, interrupts: _Interrupts) -> None:
        masks, took = {}, {}
        for name, engine in self.engines.items():
            t0 = time.perf_counter()
            mask = engine.apply(frame)
            took[name] = time.perf_counter() - t0
            masks[name] = _checked_mask(mask, name, index, frame)
        result = FrameResult(index=index, frame=frame, masks=masks, engines=self.engines,
                             seconds=took)
        for consumer in self.consumers:
            consumer.prepare(result)
        with interrupts.held():
            for consumer in self.consumers:
                consumer.add(result)
            for name, engine in self.engines.items():
                stats = self.stats.engines[name]
                stats.seconds += took[name]
                status = getattr(engine, "last_status", None)
                if status is not None and status != "ok":
                    stats.statuses[str(status)] += 1
            self.stats.frames += 1


def _checked_mask(mask: Any, name: str, index: int, frame: np.ndarray) -> np.ndarray:
    """``mask`` when it is an ``(H, W)`` uint8 or bool array of ``frame``'s size;
    :class:`ProcessingError` naming the engine otherwise."""
    height, width = frame.shape[:2]
    if not isinstance(mask, np.ndarray) or mask.dtype not in (np.uint8, np.bool_) \
            or mask.ndim != 2:
        got = (f"shape {mask.shape} dtype {mask.dtype}" if isinstance(mask, np.ndarray)
               else type(mask).__name__)
        why = f"a mask must be a ({height}, {width}) uint8 array, got {got}"
    elif mask.shape != (height, width):
        why = f"a mask must be {width}x{height}, got {mask.shape[1]}x{mask.shape[0]}"
    else:
        return mask
    raise ProcessingError(f"{name} returned an unusable mask for frame {index + 1}: {why}")
