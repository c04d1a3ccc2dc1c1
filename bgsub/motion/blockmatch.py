"""Normalised cross-correlation (NCC) block matching: the classical reference for patch motion.

For every ``p x p`` patch of frame 1 (p = 13 by default, the model's patch size) find the integer
displacement ``(dx, dy)`` in ``[-r, r]^2`` whose patch in frame 2 has the highest NCC with it.
This is what the gated RBM's patch displacements are compared against (benchmarks/middlebury.py).

Speed: the loop runs over the ``(2r + 1)^2`` displacements only; for each one the NCC of *all*
patches comes from integral images (sums over every ``p x p`` window in O(H W)), so the cost is
``O((2r + 1)^2 H W)`` whatever the patch size, with no per-patch Python work.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import cv2
import numpy as np

from bgsub.errors import InputError


@dataclass(frozen=True)
class BlockMatch:
    """Dense block-matching result, indexed by patch *centre* pixel.

    Attributes
    ----------
    flow : (H, W, 2) float32
        Best integer ``(dx, dy)`` of the patch centred at each pixel; NaN within ``p // 2`` of the
        border (no full patch) and for flat patches (NCC undefined).
    score : (H, W) float32
        NCC of the best match in [-1, 1]; NaN where ``flow`` is NaN.
    """

    flow: np.ndarray
    score: np.ndarray


def _gray64(frame: np.ndarray, name: str) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim == 3 and frame.shape[2] == 3:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.dtype == np.uint8 else frame.mean(2)
    elif frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[..., 0]
    if frame.ndim != 2:
        raise InputError(f"{name} must be (H, W) gray or (H, W, 3) BGR, got shape {frame.shape}")
    return frame.astype(np.float64)


def _window_sums(image: np.ndarray, p: int) -> np.ndarray:
    """Sums of ``image`` over every ``p x p`` window: (H - p + 1, W - p + 1) float64, by top-left."""
    integral = cv2.integral(image, sdepth=cv2.CV_64F)
    return integral[p:, p:] - integral[:-p, p:] - integral[p:, :-p] + integral[:-p, :-p]


def _best_displacements(f: np.ndarray, g: np.ndarray, stats_f: tuple, stats_g: tuple, *,
                        p: int, r: int) -> Tuple[np.ndarray, np.ndarray]:
    """The best NCC over ``[-r, r]^2`` of every full ``p x p`` patch of ``f`` in ``g`` (both
    ``(H, W) float64``, mean-centred), given each frame's window sums and variances
    ``(sums, var)`` (``(H - p + 1, W - p + 1)``, by top-left): ``(best, disp)``, the NCC
    ``(rows, cols) float64`` (-inf where no candidate is defined) and its ``(rows, cols, 2)
    float32`` ``(dx, dy)``."""
    (sf, var_f), (sg, var_g) = stats_f, stats_g
    n = float(p * p)
    rows, cols = sf.shape  # top-left positions of full patches
    best = np.full((rows, cols), -np.inf)
    best_d = np.zeros((rows, cols, 2), np.float32)
    offsets = [(dx, dy) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
    offsets.sort(key=lambda d: (abs(d[0]) + abs(d[1]), max(abs(d[0]), abs(d[1]))))
    for dx, dy in offsets:
        # Top-left positions (y, x) whose displaced patch (y + dy, x + dx) fits in frame 2.
        y0, y1 = max(0, -dy), min(rows, rows - dy)
        x0, x1 = max(0, -dx), min(cols, cols - dx)
        if y0 >= y1 or x0 >= x1:
            continue
        fa = f[y0:y1 + p - 1, x0:x1 + p - 1]
        ga = g[y0 + dy:y1 + dy + p - 1, x0 + dx:x1 + dx + p - 1]
        sfg = _window_sums(fa * ga, p)
        sf_a = sf[y0:y1, x0:x1]
        sg_a = sg[y0 + dy:y1 + dy, x0 + dx:x1 + dx]
        denom = np.sqrt(var_f[y0:y1, x0:x1] * var_g[y0 + dy:y1 + dy, x0 + dx:x1 + dx])
        with np.errstate(invalid="ignore", divide="ignore"):
            ncc = (sfg - sf_a * sg_a / n) / denom
        ncc = np.where(denom > 0, ncc, -np.inf)
        region = best[y0:y1, x0:x1]
        better = ncc > region
        region[better] = ncc[better]
        best_d[y0:y1, x0:x1][better] = (dx, dy)
    return best, best_d


def ncc_block_match(
    frame1: np.ndarray,
    frame2: np.ndarray,
    *,
    max_disp: int = 4,
    patch_size: int = 13,
    min_std: float = 1e-3,
) -> BlockMatch:
    """Exhaustive integer NCC block matching of every patch of ``frame1`` in ``frame2``.

    A candidate displacement is only considered when the displaced patch lies fully inside
    ``frame2`` (no padding, no wrap-around). Ties go to the smallest ``|dx| + |dy|`` first
    (displacements are visited from the centre outwards).

    Parameters
    ----------
    frame1, frame2 : (H, W) or (H, W, 3) arrays, same size
        Gray or BGR frames (any numeric dtype; colour is converted to gray).
    max_disp : int
        Search range ``r``: displacements in ``[-r, r]^2``.
    patch_size : int
        Side ``p`` of the square patches (odd).
    min_std : float
        Patches of frame 1 whose pixel standard deviation is below this (in input units) are
        flat: NCC is undefined there and the result is NaN.

    Returns
    -------
    BlockMatch with ``flow (H, W, 2) float32`` and ``score (H, W) float32``, indexed by patch
    centre.
    """
    f = _gray64(frame1, "frame1")
    g = _gray64(frame2, "frame2")
    if f.shape != g.shape:
        raise InputError(f"frames differ in size: {f.shape[1]}x{f.shape[0]} vs {g.shape[1]}x{g.shape[0]}")
    p, r = int(patch_size), int(max_disp)
    h, w = f.shape
    if h < p or w < p:
        raise InputError(f"frames of {w}x{h} are smaller than one {p}x{p} patch")
    n = float(p * p)
    # Centre local means first: keeps the products small so float64 sums lose nothing.
    f = f - f.mean()
    g = g - g.mean()
    sf, sff = _window_sums(f, p), _window_sums(f * f, p)
    sg, sgg = _window_sums(g, p), _window_sums(g * g, p)
    var_f = np.maximum(sff - sf * sf / n, 0.0)
    var_g = np.maximum(sgg - sg * sg / n, 0.0)
    best, best_d = _best_displacements(f, g, (sf, var_f), (sg, var_g), p=p, r=r)
    flat = var_f < (min_std ** 2) * n
    undefined = flat | ~np.isfinite(best)
    best_d[undefined] = np.nan
    best[undefined] = np.nan
    half, (rows, cols) = p // 2, best.shape
    flow = np.full((h, w, 2), np.nan, np.float32)
    score = np.full((h, w), np.nan, np.float32)
    flow[half:half + rows, half:half + cols] = best_d
    score[half:half + rows, half:half + cols] = best
    return BlockMatch(flow=flow, score=score)


def ncc_block_match_at(
    frame1: np.ndarray,
    frame2: np.ndarray,
    centers: np.ndarray,
    *,
    max_disp: int = 4,
    patch_size: int = 13,
) -> Tuple[np.ndarray, np.ndarray]:
    """NCC block matching for the patches centred at ``centers`` (see :func:`ncc_block_match`).

    Parameters
    ----------
    frame1, frame2 : (H, W) or (H, W, 3) arrays, same size
    centers : (N, 2) int array
        Patch centres ``(x, y)``; each patch must lie inside the frame.

    Returns
    -------
    disp : (N, 2) float32 ``(dx, dy)``, NaN for flat patches; score : (N,) float32 NCC.
    """
    result = ncc_block_match(frame1, frame2, max_disp=max_disp, patch_size=patch_size)
    centers = np.asarray(centers, dtype=np.int64).reshape(-1, 2)
    h, w = result.score.shape
    half = patch_size // 2
    xs, ys = centers[:, 0], centers[:, 1]
    if ((xs < half) | (xs >= w - half) | (ys < half) | (ys >= h - half)).any():
        raise ValueError("a patch centre lies too close to the border for a full patch")
    return result.flow[ys, xs], result.score[ys, xs]
