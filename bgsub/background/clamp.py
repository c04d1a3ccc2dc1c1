"""Frames bounded in place: :func:`at_least` and :func:`at_most`.

numpy's ``maximum`` and ``minimum`` against a scalar take an unvectorised path, slower than
OpenCV's ``max`` and ``min``, which give the same values for the finite numbers the models
hold. Each function falls back to numpy for
arrays OpenCV cannot take in place (not C-contiguous, not float32).
"""

from __future__ import annotations

from typing import Callable, Optional

import cv2
import numpy as np

__all__ = ["at_least", "at_most"]


def at_least(a: np.ndarray, low: float) -> np.ndarray:
    """``a`` (float32, any shape) raised to at least ``low``, in place; returns ``a``."""
    return _bounded(a, low, cv2.max, np.maximum)


def at_most(a: np.ndarray, high: float) -> np.ndarray:
    """``a`` (float32, any shape) lowered to at most ``high``, in place; returns ``a``."""
    return _bounded(a, high, cv2.min, np.minimum)


def _bounded(a: np.ndarray, bound: float, opencv: Callable, fallback: Callable) -> np.ndarray:
    """``a`` bounded in place by OpenCV's ``opencv`` (max or min) against ``bound``, or by
    numpy's same operation ``fallback`` where OpenCV cannot take ``a``."""
    flat = _one_channel(a)
    if flat is None:
        return fallback(a, np.float32(bound), out=a)
    opencv(flat, float(bound), dst=flat)
    return a


def _one_channel(a: np.ndarray) -> Optional[np.ndarray]:
    """A 2-D view of ``a`` that OpenCV sees as one channel (a scalar then bounds every value),
    or None when ``a`` is empty, not float32 or not C-contiguous."""
    if a.dtype != np.float32 or not a.flags.c_contiguous or a.size == 0:
        return None
    return a.reshape(a.shape[0], -1) if a.ndim > 1 else a.reshape(1, -1)
