"""Small helpers the stages share (below every package: they import nothing of bgsub)."""

from __future__ import annotations

from typing import Any, Callable

import cv2
import numpy as np

__all__ = ["fast_median", "is_affine", "through_bgra", "warp_image"]


def fast_median(a: np.ndarray) -> Any:
    """``np.median(a, axis=0)`` of a finite ``(K,)`` or ``(K, C)`` float array (K >= 1),
    computed as numpy computes it (the same partition, the mean of the middle one or two values
    in ``a``'s precision) without its per-call overhead, which on a frame's few hundred or few
    thousand values is most of a median's cost: a scalar of ``a``'s dtype for ``(K,)``, a
    ``(C,)`` array for ``(K, C)``."""
    k = len(a)
    half = k // 2
    kth = [half - 1, half, -1] if k % 2 == 0 else [(k - 1) // 2, -1]
    part = np.partition(a, kth, axis=0)
    # The sum starts from 0.0, as numpy's mean does (so a median of -0.0 is 0.0).
    if k % 2:
        return (0.0 + part[half]) / 1.0
    return (0.0 + part[half - 1] + part[half]) / 2.0


def is_affine(matrix: np.ndarray) -> bool:
    """The ``(3, 3)`` homography's last row is ``(0, 0, c)``: an affine map (``warpAffine``)."""
    m = np.asarray(matrix)
    return abs(float(m[2, 0])) <= 1e-12 and abs(float(m[2, 1])) <= 1e-12 and float(m[2, 2]) != 0.0


def through_bgra(resample: Callable[[np.ndarray], np.ndarray],
                 img: np.ndarray) -> np.ndarray:
    """``resample(img)`` for an OpenCV resampling (warp, remap) that treats channels alike: a
    3-channel ``img`` goes through BGRA, since OpenCV's 4-channel bilinear path is faster than
    its 3-channel one and gives the same values per channel."""
    if img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(resample(cv2.cvtColor(img, cv2.COLOR_BGR2BGRA)), cv2.COLOR_BGRA2BGR)
    return resample(img)


def warp_image(img: np.ndarray, matrix: np.ndarray, size: tuple, flags: int,
               border: int) -> np.ndarray:
    """``img`` ((H, W) or (H, W, C) float32 or uint8) warped by the (3, 3) ``matrix`` to
    ``size`` (W, H) with OpenCV's interpolation ``flags`` and ``border`` mode; same dtype and
    channel count."""
    return through_bgra(lambda each: _warp(each, matrix, size, flags, border), img)


def _warp(img: np.ndarray, matrix: np.ndarray, size: tuple, flags: int,
          border: int) -> np.ndarray:
    """:func:`warp_image` in OpenCV's own channel handling."""
    m = np.asarray(matrix, np.float64)
    if is_affine(m):
        # An affine motion (translation, similarity, affine): warpAffine is the same map, cheaper.
        out = cv2.warpAffine(img, m[:2] / m[2, 2], size, flags=flags, borderMode=border,
                             borderValue=0.0)
    else:
        out = cv2.warpPerspective(img, m, size, flags=flags, borderMode=border, borderValue=0.0)
    # OpenCV returns (H, W) for an (H, W, 1) input: the channel axis is put back.
    return out[:, :, None] if img.ndim == 3 and out.ndim == 2 else out
