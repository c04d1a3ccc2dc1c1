"""Structuring elements for the masks' morphology, made once per shape and size, and the box
around a mask that a local step needs to look at."""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = ["kernel", "around", "enclosed"]


@functools.lru_cache(maxsize=None)
def kernel(shape: int, size: int) -> np.ndarray:
    """The ``size`` x ``size`` structuring element of OpenCV ``shape`` (``cv2.MORPH_RECT``,
    ``cv2.MORPH_ELLIPSE``), cached: the engines use the same few every frame. Do not modify
    it."""
    return cv2.getStructuringElement(shape, (size, size))


def enclosed(mask: np.ndarray) -> np.ndarray:
    """``(h, w) uint8``, 1 where a 0-pixel of ``mask`` ((h, w) uint8, 0/1) does not reach the
    frame's border (4-connected): the holes the mask encloses."""
    # Flood the background from a one-pixel frame around the image: what stays 0 is enclosed.
    flooded = cv2.copyMakeBorder(mask, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    cv2.floodFill(flooded, None, (0, 0), 1)
    return 1 - flooded[1:-1, 1:-1]


def around(mask: np.ndarray, margin: int) -> tuple:
    """The ``(rows, columns)`` slices of ``mask``'s bounding box ((h, w) uint8, non-zero =
    set) grown by ``margin`` px, within the frame: where a step that reaches at most
    ``margin`` beyond the mask can change anything."""
    x, y, w, h = cv2.boundingRect(mask)
    rows, cols = mask.shape
    return (slice(max(y - margin, 0), min(y + h + margin, rows)),
            slice(max(x - margin, 0), min(x + w + margin, cols)))
