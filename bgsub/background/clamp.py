"""Frames bounded in place: :func:`at_least` and :func:`at_most`.

numpy's ``maximum`` and ``minimum`` against a scalar take an unvectorised path (a 320x240
colour frame of float32: 0.09 ms, against 0.04 ms for OpenCV's ``max`` and ``min``, which give
the same values for the finite numbers the models hold). Each function falls back to numpy for
arrays OpenCV cannot take in place (not C-contiguous, not float32).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["at_least", "at_most"]


def at_least(a: np.ndarray, low: float) -> np.ndarray:
    """``a`` (float32, any shape) raised to at least ``low``, in place; returns ``a``."""
    flat = _one_channel(a)
    if flat is None:
        return np.maximum(a, np.float32(low), out=a)
    cv2.max(flat, float(low), dst=flat)
    return a


def at_most(a: np.ndarray, high: float) -> np.ndarray:
    """``a`` (float32, any shape) lowered to at most ``high``, in place; returns ``a``."""
    flat = _one_channel(a)
    if flat is None:
        return np.minimum(a, np.float32(high), out=a)
    cv2.min(flat, float(high), dst=flat)
    return a


def _one_channel(a: np.ndarray):
    """A 2-D view of ``a`` that OpenCV sees as one channel (a scalar then bounds every value),
    or None when ``a`` is empty, not float32 or not C-contiguous."""
    if a.dtype != np.float32 or not a.flags.c_contiguous or a.size == 0:
        return None
    return a.reshape(a.shape[0], -1) if a.ndim > 1 else a.reshape(1, -1)
