"""The objects' own colours: a found object grows over the parts of it that match the background.

Where an object's surface is flat, or close in colour to the background it covers, neither the
background model nor the motion evidence can tell it from background, and the fused mask keeps
only its outline and textured parts (a dog's smooth flank, a bottle's plain side).
:class:`ObjectColours` learns, from the previous frame and its mask, two colour histograms: the
objects' (the mask, eroded off its uncertain edge) and the background's around them (a band
outside the mask). A pixel near this frame's mask whose colour the objects' histogram explains
clearly better than the background's, with equal priors, joins the blob it touches:

    P(object | colour) = h_object(colour) / (h_object(colour) + h_background(colour)) > above

Only pixels connected to a blob of the mask, within ``radius`` of it, can join: the colour
model says what an object looks like, not where a new one is.
"""

from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from bgsub.background.morphology import around, kernel

__all__ = ["ObjectColours", "colour_index"]

#: Levels per channel (4,096 bins): nearby shades of one surface share a bin; 8 levels told the
#: objects from their ground less well (generated jitter scenes, on saved masks).
LEVELS = 16
_SHIFT = 4  # 256 // LEVELS == 1 << _SHIFT
#: The mask is eroded by this (px) before its colours count as the objects': its edge mixes.
_INNER = 5
#: The background's band lies between these two dilations of the mask (px).
_BAND = (9, 41)
#: Fewer pixels than this in either set: no colour model.
_MIN_PIXELS = 20
#: Added to each normalised histogram: a colour neither set holds has P = 1/2.
_PRIOR = np.float32(1e-4)


def colour_index(frame: np.ndarray) -> np.ndarray:
    """``(h, w) int32``: each pixel's histogram bin, ``LEVELS`` levels per channel of the
    ``(h, w, 3)`` or ``(h, w)`` uint8 ``frame``."""
    q = frame >> _SHIFT
    if q.ndim == 2:
        return q.astype(np.int32)
    idx = q[..., 0].astype(np.int32)
    idx <<= _SHIFT
    idx |= q[..., 1]
    idx <<= _SHIFT
    idx |= q[..., 2]
    return idx


class ObjectColours:
    """The colour model of the objects of one frame, applied to the next.

    Parameters
    ----------
    radius : int
        How far (working px) beyond the mask a pixel may join it (0 = off).
    above : float
        The posterior probability of the objects' colour a pixel needs to join, in [0.5, 1].
    """

    def __init__(self, *, radius: int, above: float) -> None:
        self.radius = int(radius)
        self.above = float(above)
        self._table: Optional[np.ndarray] = None  # (LEVELS ** channels,) float32: P(object)

    def reset(self) -> None:
        """Forget the objects' colours (a new shot)."""
        self._table = None

    def restart(self, frame: np.ndarray) -> None:
        """:meth:`reset` (the engine's restart from ``frame``)."""
        self.reset()

    def learn(self, frame: np.ndarray, mask: np.ndarray) -> None:
        """Learn the colours of ``mask``'s objects ((h, w) uint8 0/255) and of the background
        around them in ``frame`` ((h, w, 3) or (h, w) uint8), for the next :meth:`grow`."""
        self._table = None
        if self.radius == 0 or cv2.countNonZero(mask) < _MIN_PIXELS:
            return
        box = around(mask, _BAND[1] // 2)
        mask, frame = mask[box], frame[box]
        inner = cv2.erode(mask, kernel(cv2.MORPH_ELLIPSE, _INNER)) > 0
        outer, gap = (cv2.dilate(mask, kernel(cv2.MORPH_ELLIPSE, k)) for k in reversed(_BAND))
        band = outer > gap
        if np.count_nonzero(inner) < _MIN_PIXELS or np.count_nonzero(band) < _MIN_PIXELS:
            return
        idx = colour_index(frame)
        bins = LEVELS ** (3 if frame.ndim == 3 else 1)
        h_obj = _normalised(np.bincount(idx[inner], minlength=bins))
        h_bg = _normalised(np.bincount(idx[band], minlength=bins))
        self._table = (h_obj + _PRIOR) / (h_obj + h_bg + 2 * _PRIOR)

    def grow(self, mask: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """``mask`` ((h, w) uint8 0/255) with the pixels of ``frame`` near it that look like
        the last objects, connected to its blobs (8-connected). The mask itself when there is
        no colour model."""
        if self._table is None or not cv2.countNonZero(mask):
            return mask
        # Nothing beyond the radius of the mask's bounding box can join: work inside it.
        box = around(mask, self.radius)
        part = mask[box]
        near = cv2.dilate(part, kernel(cv2.MORPH_ELLIPSE, 2 * self.radius + 1)) > 0
        likely = self._table[colour_index(frame[box])] > self.above
        joined = ((near & likely) | (part > 0)).view(np.uint8)
        n, labels = cv2.connectedComponents(joined, connectivity=8)
        touched = np.zeros(n, bool)
        touched[labels[part > 0]] = True
        touched[0] = False
        grown = mask.copy()
        grown[box] = touched[labels].view(np.uint8) * np.uint8(255)
        return grown


def _normalised(counts: np.ndarray) -> np.ndarray:
    return (counts / max(int(counts.sum()), 1)).astype(np.float32)
