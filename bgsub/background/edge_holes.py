"""Holes closed by the frame's edges: the flat inside of an object, bounded by its own outline.

The inside of a uniformly coloured object (a car's door, a dog's flank) matches the background
it covers once the camera has moved the model by less than the object's size, so only the
object's outline and textured parts are found. :func:`~bgsub.background.fusion.clean_mask`
fills the holes the mask encloses on its own; where the found parts leave a gap, the hole is
open, but the object's own outline, an edge of the frame, usually closes it.
:func:`fill_edge_holes` fills the regions of the frame that the mask and the frame's edges
enclose together, when the mask holds at least a ``share`` of their boundary: a region bounded
mostly by edges and touching the mask at a corner is background beside an object, not inside
it.

Edges are Canny's (gray levels 80 / 160, the usual 1:2 hysteresis), thickened by one pixel so
that a one-pixel break in an outline does not open a hole to the background around it.
"""

from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from bgsub.background.morphology import around, kernel

__all__ = ["fill_edge_holes"]

#: Canny's hysteresis thresholds (gray levels): an object's outline, not the background's
#: fine texture, whose edges would cut the background into small enclosed regions.
_CANNY = (80, 160)
#: Only regions within the mask's bounding box grown by this (px) can be filled: a hole in an
#: object lies within the object's extent.
_MARGIN = 8


def fill_edge_holes(mask: np.ndarray, gray: np.ndarray, *, share: float,
                    max_area: int) -> np.ndarray:
    """``mask`` with the regions the frame's edges and it enclose filled.

    Parameters
    ----------
    mask : (h, w) uint8, 0/255
    gray : (h, w) uint8
        The frame the mask was made from.
    share : float
        The least fraction (0-1) of a region's boundary pixels that must touch the mask (the
        rest touching edges) for the region to be filled; 0 = off.
    max_area : int
        Regions of more pixels are not filled.

    Returns
    -------
    (h, w) uint8, 0/255: a new array, or ``mask`` itself when nothing is filled.
    """
    if share <= 0 or max_area <= 0 or not cv2.countNonZero(mask):
        return mask
    box = around(mask, _MARGIN)
    filled = _fill(mask[box] > 0, gray[box], share, max_area)
    if filled is None:
        return mask
    out = mask.copy()
    out[box][filled] = 255
    return out


def _fill(mask: np.ndarray, gray: np.ndarray, share: float,
          max_area: int) -> Optional[np.ndarray]:
    """``(h, w) bool`` of the pixels to fill in the cropped ``mask`` ((h, w) bool), or None."""
    edges = cv2.dilate(cv2.Canny(gray, *_CANNY), kernel(cv2.MORPH_RECT, 3)) > 0
    free = ~mask & ~edges
    # (Areas by counting labels: connectedComponentsWithStats costs more.)
    n, labels = cv2.connectedComponents(free.view(np.uint8), connectivity=4)
    if n <= 1:
        return None
    cross = kernel(cv2.MORPH_CROSS, 3)
    by_mask = free & (cv2.dilate(mask.view(np.uint8), cross) > 0)
    by_edge = free & (cv2.dilate(edges.view(np.uint8), cross) > 0)
    on_mask = np.bincount(labels[by_mask], minlength=n)
    on_either = np.bincount(labels[by_mask | by_edge], minlength=n)
    ok = (np.bincount(labels.ravel(), minlength=n) <= max_area) & (on_mask > 0)
    ok &= on_mask >= share * on_either
    for side in (labels[0], labels[-1], labels[:, 0], labels[:, -1]):
        ok[side] = False  # open to the rest of the frame
    ok[0] = False
    if not ok.any():
        return None
    return ok[labels]

