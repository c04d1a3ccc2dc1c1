"""Small helpers the stages share (below every package: they import nothing of bgsub)."""

from __future__ import annotations

from typing import Any, Callable

import cv2
import numpy as np

__all__ = ["fast_median", "is_affine", "through_bgra", "warp_image", "weighted_quantiles"]


def fast_median(a: np.ndarray) -> Any:
    """``np.median(a, axis=0)`` of a ``(K,)`` or ``(K, C)`` float array without NaN (K >= 1),
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


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, q: Any) -> Any:
    """The ``q`` quantiles (a scalar or sequence in [0, 1]) of ``values`` (N,), each value
    counting its ``weights`` (N,), N >= 1 with a positive sum: the smallest value whose
    cumulative weight reaches ``q`` of the total."""
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return values[order][np.searchsorted(cum, np.asarray(q) * cum[-1])]


def is_affine(matrix: np.ndarray) -> bool:
    """The ``(3, 3)`` homography's last row is ``(0, 0, c)``: an affine map (``warpAffine``)."""
    m = np.asarray(matrix)
    return abs(float(m[2, 0])) <= 1e-12 and abs(float(m[2, 1])) <= 1e-12 and float(m[2, 2]) != 0.0


def through_bgra(resample: Callable[[np.ndarray], np.ndarray],
                 img: np.ndarray) -> np.ndarray:
    """``resample(img)`` for an OpenCV resampling that treats channels alike: a 3-channel
    ``img`` goes through BGRA, since OpenCV's 4-channel path is faster than its 3-channel one
    for ``remap`` and gives the same values per channel."""
    if img.ndim == 3 and img.shape[2] == 3:
        return cv2.cvtColor(resample(cv2.cvtColor(img, cv2.COLOR_BGR2BGRA)), cv2.COLOR_BGRA2BGR)
    return resample(img)


def warp_image(img: np.ndarray, matrix: np.ndarray, size: tuple, flags: int,
               border: int) -> np.ndarray:
    """``img`` ((H, W) or (H, W, C) float32 or uint8) warped by the (3, 3) ``matrix`` to
    ``size`` (W, H) with OpenCV's interpolation ``flags`` and ``border`` mode; same dtype and
    channel count."""
    if img.dtype == np.float32:
        # Float warps run faster in three channels than through BGRA (about 0.6x the time at
        # 320x240, the same values); uint8 ones about as fast either way.
        return _warp(img, matrix, size, flags, border)
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


class FieldWarp:
    """A (3, 3) homography ``matrix`` followed by a per-pixel displacement ``field`` ((H, W, 2)
    float32, in the output's pixels): the background's motion in a 3-D scene (plane plus
    parallax). The remap maps are made once; each call warps an image ((H, W) or (H, W, C)
    float32 or uint8, of the field's size) with OpenCV's interpolation ``flags`` and ``border``
    mode, as :func:`warp_image` does a matrix."""

    def __init__(self, matrix: np.ndarray, field: np.ndarray) -> None:
        h, w = field.shape[:2]
        xs, ys = pixel_grid(h, w)
        # Where the plane put each pixel, then where the previous frame saw it.
        on_plane = np.stack([xs - field[:, :, 0], ys - field[:, :, 1]], -1).reshape(1, -1, 2)
        src = cv2.perspectiveTransform(on_plane, np.linalg.inv(np.asarray(matrix, np.float64)))
        self.map_x = np.ascontiguousarray(src[0, :, 0].reshape(h, w))
        self.map_y = np.ascontiguousarray(src[0, :, 1].reshape(h, w))

    def __call__(self, img: np.ndarray, flags: int, border: int) -> np.ndarray:
        return through_bgra(lambda each: self._remap(each, flags, border), img)

    def _remap(self, img: np.ndarray, flags: int, border: int) -> np.ndarray:
        out = cv2.remap(img, self.map_x, self.map_y, flags, borderMode=border, borderValue=0.0)
        return out[:, :, None] if img.ndim == 3 and out.ndim == 2 else out


def cell_index(positions: np.ndarray, shape: tuple, cell: int) -> tuple:
    """``(cells, (gh, gw))``: the flat index of the ``cell`` x ``cell`` cell of an ``(H, W)``
    frame that holds each of the ``(N, 2)`` ``positions`` (clipped to the frame's cells), and
    the cell grid's size."""
    h, w = int(shape[0]), int(shape[1])
    gw, gh = (w + cell - 1) // cell, (h + cell - 1) // cell
    gx = np.clip((positions[:, 0] // cell).astype(np.intp), 0, gw - 1)
    gy = np.clip((positions[:, 1] // cell).astype(np.intp), 0, gh - 1)
    return gy * gw + gx, (gh, gw)


_GRIDS: dict = {}


def pixel_grid(h: int, w: int) -> tuple:
    """``(x, y)``: (H, W) float32 pixel coordinates, cached for the last size (read-only: they
    are shared)."""
    if (h, w) not in _GRIDS:
        _GRIDS.clear()
        xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
        _GRIDS[(h, w)] = (xs, ys)
    return _GRIDS[(h, w)]
