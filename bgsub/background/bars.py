"""Black bars along the frame's edges: letterbox (top and bottom) and pillarbox (left and right).

They are frame-fixed overlays like a logo, but flat: no textured pixel in them tells the overlay
detector that they hold still, while a moving camera's warped background model drags the scene
over them and them over the scene (:mod:`bgsub.background.overlay`, which keeps them as
background). A bar is the run of rows (columns) from an edge of the frame whose gray values are
all within ``BAR_LEVEL`` of black, in every frame seen so far.
"""

from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

__all__ = ["BlackBars"]

#: A bar's gray values (0-255) are at most this: black, with compression's ringing.
BAR_LEVEL = 16
#: A bar covers at most this share of the frame's height (letterbox) or width (pillarbox).
BAR_SHARE = 0.25


class BlackBars:
    """The black bars of a stream of working-size gray frames: :meth:`observe` each frame,
    then :meth:`mask` gives them once they held for enough frames."""

    def __init__(self) -> None:
        self.depth: Optional[Tuple[int, int, int, int]] = None  # top, bottom, left, right
        self.frames = 0
        self._made: tuple = (None, None)  # (what the last mask was made from, that mask)

    def observe(self, gray: np.ndarray) -> None:
        """Take in a frame (``(h, w) uint8``): a bar is as deep as it is in every frame."""
        now = (_dark_run(gray), _dark_run(gray[::-1]), _dark_run(gray.T),
               _dark_run(gray.T[::-1]))
        self.depth = now if self.depth is None else tuple(map(min, self.depth, now))
        self.frames += 1

    def mask(self, shape: tuple, *, frames: int, grow: int) -> Optional[np.ndarray]:
        """``(h, w) bool``: the bars, each ``grow`` px deeper (the scene's edge against them
        blurs), once ``frames`` frames were observed; None without a bar. The same array while
        the bars stay as they are (the engine remakes its region of interest when it changes)."""
        if self.depth is None or self.frames < frames or not any(self.depth):
            return None
        key = (self.depth, shape[:2], grow)
        if self._made[0] != key:
            self._made = (key, self._drawn(shape, grow))
        return self._made[1]

    def _drawn(self, shape: tuple, grow: int) -> np.ndarray:
        """``(h, w) bool``: the bars of :attr:`depth`, each ``grow`` px deeper."""
        h, w = shape[:2]
        top, bottom, left, right = (d + grow if d else 0 for d in self.depth)
        rows, cols = np.arange(h), np.arange(w)
        across = (rows < top) | (rows >= h - bottom)
        along = (cols < left) | (cols >= w - right)
        return across[:, None] | along[None, :]


def _dark_run(gray: np.ndarray) -> int:
    """How many of ``gray``'s first rows ((h, w) uint8) are black (every value at most
    ``BAR_LEVEL``), up to ``BAR_SHARE`` of its rows."""
    n = int(gray.shape[0] * BAR_SHARE)
    dark = gray[:n].max(axis=1) <= BAR_LEVEL
    return n if dark.all() else int(np.argmin(dark))
