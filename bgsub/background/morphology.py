"""Structuring elements for the masks' morphology, made once per shape and size."""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = ["kernel"]


@functools.lru_cache(maxsize=None)
def kernel(shape: int, size: int) -> np.ndarray:
    """The ``size`` x ``size`` structuring element of OpenCV ``shape`` (``cv2.MORPH_RECT``,
    ``cv2.MORPH_ELLIPSE``), cached: the engines use the same few every frame. Do not modify
    it."""
    return cv2.getStructuringElement(shape, (size, size))
