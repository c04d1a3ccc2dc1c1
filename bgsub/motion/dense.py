"""The per-pixel flow field assembled from overlapping patch displacements."""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from bgsub.motion.flowfield import FlowEstimate

__all__ = ["dense_from_patches"]


def dense_from_patches(
    flow: "FlowEstimate", *, shape: tuple, patch_size: int = 13, min_weight: float = 1e-3
) -> np.ndarray:
    """Per-pixel flow from overlapping patch displacements (confidence-weighted average).

    Every valid patch votes for its displacement with weight ``confidence * texture``; a pixel
    takes the bilinear, weight-normalised average of the votes of the four grid patches around
    it, which is a smooth robust blend where patches agree and follows the better-supported
    patch where they do not. Where those four carry no weight (a pixel on the centre line of an
    invalid patch) but other valid patches cover the pixel, it takes the weighted average of
    the patches that cover it. Pixels no valid patch covers are NaN.

    Parameters
    ----------
    flow : FlowEstimate
    shape : (H, W)
    patch_size : int
    min_weight : float
        Pixels whose summed weight is below this are NaN.

    Returns
    -------
    (H, W, 2) float32, NaN where unknown.
    """
    h, w = int(shape[0]), int(shape[1])
    rows, cols = flow.grid_shape
    out = np.full((h, w, 2), np.nan, np.float32)
    if rows == 0 or cols == 0:
        return out
    wts = flow.weights.reshape(rows, cols)
    num = (flow.disp * flow.weights[:, None]).reshape(rows, cols, 2).astype(np.float32)
    grid = np.dstack([num, wts]).astype(np.float32)
    half = (patch_size - 1) / 2.0
    s = float(flow.stride)
    # Pixel (x, y) sits at grid coordinates ((x - half) / s, (y - half) / s).
    m = np.array([[1.0 / s, 0.0, -half / s], [0.0, 1.0 / s, -half / s]])
    up = cv2.warpAffine(grid, m, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                        borderMode=cv2.BORDER_REPLICATE)
    den = up[:, :, 2]
    ok = den > min_weight
    # Only pixels inside some patch: the grid covers [0, last centre + half] in each axis.
    cover_x = (cols - 1) * s + patch_size
    cover_y = (rows - 1) * s + patch_size
    ok[:, int(cover_x):] = False
    ok[int(cover_y):, :] = False
    out[ok] = up[ok, :2] / den[ok, None]
    _fill_from_covering_patches(out, flow, ok, patch_size, min_weight)
    return out


def _fill_from_covering_patches(out: np.ndarray, flow: "FlowEstimate", ok: np.ndarray,
                                patch_size: int, min_weight: float) -> None:
    """Give the pixels of ``out`` ((H, W, 2), NaN where not ``ok``) that valid patches cover
    the weighted average of those patches' votes, each vote spread evenly over its patch."""
    h, w = out.shape[:2]
    half = (patch_size - 1) // 2
    valid = flow.weights > 0
    cx, cy = np.rint(flow.centres[valid]).astype(np.intp).T
    inside = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
    weights = flow.weights[valid][inside].astype(np.float32)
    splat = np.zeros((h, w, 3), np.float32)
    splat[cy[inside], cx[inside], :2] = flow.disp[valid][inside] * weights[:, None]
    splat[cy[inside], cx[inside], 2] = weights
    # A box of the patch's side around each centre: the pixels that patch covers.
    spread = cv2.boxFilter(splat, -1, (patch_size, patch_size), anchor=(half, half),
                           normalize=False, borderType=cv2.BORDER_CONSTANT)
    fill = ~ok & (spread[:, :, 2] > min_weight)
    out[fill] = spread[fill, :2] / spread[fill, 2:3]
