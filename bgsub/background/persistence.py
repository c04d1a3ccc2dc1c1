"""A blob new in this frame, touching nothing of the last mask, is dropped: one frame's flicker
is not an object (:class:`BlobPersistence`)."""

from __future__ import annotations

from typing import Optional

import numpy as np

from bgsub.background.fusion import persistent_blobs

__all__ = ["BlobPersistence"]


class BlobPersistence:
    """A blob of the mask must overlap the previous frame's mask, moved by the camera and grown
    by ``radius`` px (:func:`~bgsub.background.fusion.persistent_blobs`; ``radius`` 0 = off).
    The first mask with foreground after a (re)start has nothing to overlap and is kept whole:
    a young model often finds nothing in its first frames, and what it first finds is the
    objects already in view."""

    def __init__(self, radius: int) -> None:
        self.radius = int(radius)
        self._previous: Optional[np.ndarray] = None  # the last mask before this filter

    def reset(self) -> None:
        """Forget the last mask: the next one with foreground is kept whole."""
        self._previous = None

    def restart(self, frame: np.ndarray) -> None:
        """:meth:`reset` (the engine's restart from ``frame``)."""
        self.reset()

    def filter(self, mask: np.ndarray, matrix: np.ndarray) -> np.ndarray:
        """``mask`` ((h, w) uint8 0/255) less its blobs new since the last frame; ``matrix``
        (3, 3) is the camera motion from that frame."""
        if self.radius <= 0:
            return mask
        previous = self._previous
        if previous is None or previous.shape != mask.shape:
            # Nothing found yet since the (re)start: the first mask with foreground is kept
            # whole. (A copy: the engine may hand this very array to the caller.)
            self._previous = mask.copy() if mask.any() else None
            return mask
        self._previous = mask.copy()
        return persistent_blobs(mask, previous, matrix, radius=self.radius)
