"""Look-back start: the first masks of a stream from a model that has seen the scene.

A background model that starts at frame 1 has seen nothing behind the objects: the first mask
is empty and the next ones weak, and many real clips are 30-80 frames long. A caller that reads
the stream itself can do better: :func:`primed` reads the first frames ahead and hands them to
every engine that has the optional ``prime`` capability; such an engine runs them backwards in
a twin of itself, and for the first frames, those the twin has seen more of the scene for,
returns the twin's masks. The stream then goes on from frame 1, unchanged. Engines without the
capability (OpenCV's) start as before.

The twin's masks replace the engine's, not its model: an engine primed with the frames
themselves would meet a slow object on the frames where it had already learnt it (a bottle
drifting on water: UCSD bottle 0.754 -> 0.385, docs/decisions.md)."""

from __future__ import annotations

import itertools
import time
from typing import Any, Dict, Iterable, Iterator, Mapping, Optional, Tuple, Union

import numpy as np

from bgsub.engines.base import supports

__all__ = ["READ_AHEAD_BYTES", "primed"]

#: At most this many bytes of frames are read ahead, whatever the engines' ``lookback``: 30
#: frames up to 1920x1080, 10 at 3840x2160.
READ_AHEAD_BYTES = 256 * 2 ** 20


def primed(engines: Union[Mapping[str, Any], Iterable[Any]],
           frames: Iterable[Tuple[int, np.ndarray]], *,
           took: Optional[Dict[str, float]] = None) -> Iterator[Tuple[int, np.ndarray]]:
    """``frames`` (``(index, (H, W[, 3]) uint8)`` pairs), the same and in the same order, once
    every engine of ``engines`` (a sequence, or a mapping by name) that supports ``prime``
    has been primed with as many of the first frames as its ``lookback`` asks for. The frames
    read ahead are held (copied) until they are handed on: memory for the largest
    ``lookback`` (at most :data:`READ_AHEAD_BYTES`), whatever the stream's length. ``took``,
    when given, receives each primed engine's seconds by name (mapping) or position
    (sequence)."""
    named = engines.items() if isinstance(engines, Mapping) else enumerate(engines)
    takers = [(name, engine) for name, engine in named if supports(engine, "prime")]
    wanted = max((int(getattr(engine, "lookback", 0)) for _, engine in takers), default=0)
    frames = iter(frames)
    if wanted < 2:
        return frames
    head, held = [], 0
    for index, image in itertools.islice(frames, wanted):
        head.append((index, np.array(image, copy=True)))
        held += image.nbytes
        if held >= READ_AHEAD_BYTES:
            break
    for name, engine in takers:
        started = time.perf_counter()
        engine.prime([image for _, image in head])
        if took is not None:
            took[name] = time.perf_counter() - started
    return itertools.chain(head, frames)
