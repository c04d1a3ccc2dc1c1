"""Textured pixels that repeat themselves in the frame and hold still to a fraction of a pixel
while the camera moves (:class:`HeldStill`): burnt into the frame, whether or not the scene
shows through them.

A watermark word under a shaking camera fails the see-through tests (the scene barely moves under
it from one frame to the next, so it looks opaque) and the opaque overlays' test (its patches read
the scene's motion as well as none). A subject the camera follows repeats itself too, but it
shakes with the scene: the camera's shake moves it in the frame by a few tenths of a pixel or
more, while a burnt-in overlay does not move at all. So the repeating pixels' own shift, read by
Lucas-Kanade over each cell's repeating pixels between consecutive frames, tells them apart.
"""

from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from bgsub.background.morphology import kernel

__all__ = ["HeldStill", "HOLD_PX"]

#: A cell's repeating pixels hold still when their shift from frame to frame, averaged over the
#: frames where the camera moved, stays under this many px (followed subjects: 0.26 px and more on
#: the development scenes; a watermark's letters: a few hundredths).
HOLD_PX = 0.2
#: The cells the shift is read in (px a side), and the least repeating pixels a cell needs.
CELL = 16
LEAST = 8
#: The running mean of each cell's shift forgets at this rate a frame; a cell starts at 1 px.
RATE = 0.125
#: Shifts are capped at this many px (an object passing must not outweigh the cell's mean).
CAP_PX = 2.0
#: The held-still pixels are grown by this many px (a letter's anti-aliased rim).
GROW_PX = 3


class HeldStill:
    """The repeating pixels whose cells hold still (:attr:`mask`, ``(h, w) bool`` or None), from
    :meth:`update` on each frame where the camera moved."""

    def __init__(self) -> None:
        self.mask: Optional[np.ndarray] = None
        self._shift: Optional[np.ndarray] = None  # (gh, gw) float32: the cells' mean shift, px

    def update(self, repeating: np.ndarray, cur: np.ndarray, last: np.ndarray) -> None:
        """Read the shift of the ``repeating`` pixels ((h, w) bool) from ``last`` to ``cur``
        ((h, w) uint8, blurred), fold it into their cells' means, and remake :attr:`mask`."""
        if not repeating.any():
            self.mask = None
            return
        shift, read = _cell_shifts(repeating, cur, last)
        if self._shift is None or self._shift.shape != shift.shape:
            self._shift = np.ones(shift.shape, np.float32)
        self._shift += np.where(read, RATE * (shift - self._shift), 0).astype(np.float32)
        still = np.zeros(repeating.shape, bool)
        gh, gw = self._shift.shape
        cells = np.repeat(np.repeat(self._shift < HOLD_PX, CELL, axis=0), CELL, axis=1)
        still[:gh * CELL, :gw * CELL] = cells
        held = (repeating & still).view(np.uint8)
        side = 2 * GROW_PX + 1
        self.mask = cv2.dilate(held, kernel(cv2.MORPH_RECT, side)) > 0 if held.any() else None


def _cell_shifts(pixels: np.ndarray, cur: np.ndarray, last: np.ndarray) -> tuple:
    """``(shift, read)``, (gh, gw) float32 and bool: each CELL x CELL cell's Lucas-Kanade shift
    (px, capped at CAP_PX) of its ``pixels`` ((h, w) bool) from ``last`` to ``cur`` ((h, w)
    uint8), read where the cell holds LEAST of them and their gradients span two directions;
    only the cells around the pixels are read (0, not read, elsewhere)."""
    h, w = pixels.shape
    gh, gw = h // CELL, w // CELL
    shift, read = np.zeros((gh, gw), np.float32), np.zeros((gh, gw), bool)
    x, y, bw, bh = cv2.boundingRect(pixels[:gh * CELL, :gw * CELL].view(np.uint8))
    if bw == 0:
        return shift, read
    rows = slice(y // CELL, -(-(y + bh) // CELL))  # (the cells the pixels' box touches)
    cols = slice(x // CELL, -(-(x + bw) // CELL))
    cells = (rows, cols)
    box = np.s_[rows.start * CELL:rows.stop * CELL, cols.start * CELL:cols.stop * CELL]
    a, b = cur[box].astype(np.float32), last[box].astype(np.float32)
    mean = (a + b) * np.float32(0.5)
    ix = cv2.Sobel(mean, cv2.CV_32F, 1, 0, ksize=3) * np.float32(0.125)
    iy = cv2.Sobel(mean, cv2.CV_32F, 0, 1, ksize=3) * np.float32(0.125)
    it = a - b
    weight = pixels[box].astype(np.float32)
    size = (weight.shape[1] // CELL, weight.shape[0] // CELL)

    def per_cell(v: np.ndarray) -> np.ndarray:  # (the cells' means: their sums up to a scale)
        return cv2.resize(v * weight, size, interpolation=cv2.INTER_AREA)

    sxx, sxy, syy = per_cell(ix * ix), per_cell(ix * iy), per_cell(iy * iy)
    sxt, syt = per_cell(ix * it), per_cell(iy * it)
    n = cv2.resize(weight, size, interpolation=cv2.INTER_AREA) * np.float32(CELL * CELL)
    det = sxx * syy - sxy * sxy
    ok = (n >= LEAST - 0.5) & (det > 1e-3 * np.maximum(sxx + syy, 1e-12) ** 2)
    safe = np.where(ok, det, 1.0)
    dx = -(syy * sxt - sxy * syt) / safe
    dy = -(sxx * syt - sxy * sxt) / safe
    shift[cells] = np.where(ok, np.minimum(np.hypot(dx, dy), CAP_PX), 0.0)
    read[cells] = ok
    return shift, read
