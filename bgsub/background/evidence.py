"""Photometric motion evidence: does a pixel's neighbourhood move otherwise than the camera?

A local motion reading is evidence of an object only as far as the image can tell it apart from
the camera's motion. :func:`motion_evidence_map` asks the frames themselves: per pixel, it
compares how well the previous frame, moved by the camera, explains the current one (``r_cam``)
with how well it does moved by an alternative -- the local motion vectors' field, or no motion at
all (an object the camera follows stays put in the image) -- (``r_alt``, the better one). The
evidence is a ramp of ``s = (r_cam - r_alt) / (r_cam + r_alt + noise)``: 0 up to ``start``
(the camera explains the frame about as well: no evidence), 1 from ``start + span``.

This is aperture-aware by construction: on a flat patch every motion explains the frame alike,
on a straight edge a shift along the edge changes nothing, so only the component across it can
make ``r_alt`` smaller; on a corner or texture any disagreement does. A wrong local vector on
the background explains the frame worse than the camera and gives no evidence at all.

:func:`camera_evidence_map` is the other side: where the camera's motion explains the frame
clearly better than no motion, the pixel is background seen moving with the camera (textured
background under a moving camera; nothing on a flat patch or under a still camera).
:func:`frame_evidence` makes both maps from one warp.
"""

from __future__ import annotations

from typing import Optional

import cv2
import numpy as np

from bgsub._util import FieldWarp, cell_index, pixel_grid, through_bgra, warp_image
from bgsub.errors import InputError
from bgsub.motion.global_motion import apply_homography

__all__ = ["motion_evidence_map", "camera_evidence_map", "frame_evidence", "residual_field",
           "cell_index", "cells_to_pixels"]


def residual_field(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                   matrix: np.ndarray, shape: tuple, *, cell: int = 8) -> np.ndarray:
    """The local vectors' departure from the camera's motion as a smooth per-pixel field.

    Parameters
    ----------
    points, disp : (N, 2) float
        Positions in the previous frame and their displacements to the current one.
    weights : (N,) float
        Reliability of each vector (0 = unused).
    matrix : (3, 3) float64
        The camera motion (previous -> current).
    shape : (H, W)
        Size of the field, in current-frame coordinates.
    cell : int
        Vectors are pooled (weighted mean) in ``cell`` x ``cell`` cells, then interpolated.

    Returns
    -------
    (H, W, 2) float32: ``(dx, dy)`` to add to the camera's motion at each pixel (0 where no
    vector reports).
    """
    h, w = int(shape[0]), int(shape[1])
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    wt = np.asarray(weights, np.float64).reshape(-1)
    res = pts + np.asarray(disp, np.float64).reshape(-1, 2) - apply_homography(matrix, pts)
    ok = (wt > 0) & np.isfinite(res).all(axis=1)
    if not ok.any():
        return np.zeros((h, w, 2), np.float32)
    cur = pts[ok] + np.asarray(disp, np.float64).reshape(-1, 2)[ok]
    cells, (gh, gw) = cell_index(cur, shape, cell)
    den = np.bincount(cells, wt[ok], minlength=gh * gw)
    grid = np.zeros((gh * gw, 2), np.float32)
    for axis in (0, 1):
        num = np.bincount(cells, wt[ok] * res[ok, axis], minlength=gh * gw)
        grid[:, axis] = np.where(den > 0, num / np.maximum(den, 1e-12), 0.0)
    return cells_to_pixels(grid.reshape(gh, gw, 2), shape, cell)


def cells_to_pixels(grid: np.ndarray, shape: tuple, cell: int) -> np.ndarray:
    """A ``(gh, gw[, C])`` float32 cell grid interpolated (bilinearly) to the ``(H, W)`` frame."""
    gh, gw = grid.shape[:2]
    up = cv2.resize(grid, (gw * cell, gh * cell), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(up[:int(shape[0]), :int(shape[1])])


def motion_evidence_map(prev: np.ndarray, cur: np.ndarray, matrix: np.ndarray, *,
                        residual: Optional[np.ndarray] = None, window: int = 7,
                        noise: float = 4.0, start: float = 0.1,
                        span: float = 0.4) -> np.ndarray:
    """Where the current frame is better explained by another motion than the camera's.

    Parameters
    ----------
    prev, cur : (H, W) or (H, W, 3) uint8
        Consecutive frames (colour differences count in every channel).
    matrix : (3, 3) float64
        The camera motion (previous -> current).
    residual : (H, W, 2) float32, optional
        The local motion's departure from the camera's (:func:`residual_field`); without it
        only "no motion" is the alternative.
    window : int
        Side of the square over which absolute differences are averaged (px).
    noise : float
        Noise floor of the averaged differences (gray levels): flat areas' ratio stays small.
    start, span : float
        The evidence is ``clip((s - start) / span, 0, 1)``.

    Returns
    -------
    (H, W) float32 in [0, 1]: near 0 where the camera's motion explains the frame as well as
    any alternative (no evidence), near 1 where an alternative explains it clearly better.
    """
    return frame_evidence(prev, cur, matrix, residual=residual, window=window, noise=noise,
                          start=start, span=span)[0]


def camera_evidence_map(prev: np.ndarray, cur: np.ndarray, matrix: np.ndarray, *,
                        window: int = 7, noise: float = 4.0, start: float = 0.1,
                        span: float = 0.4) -> np.ndarray:
    """Where the current frame is clearly better explained by the camera's motion than by no
    motion: the same ramp as :func:`motion_evidence_map` of ``(r_still - r_cam) / (r_cam +
    r_still + noise)``, with the same parameters.

    Returns
    -------
    (H, W) float32 in [0, 1]: near 1 on background seen moving with the camera (textured, the
    camera moving); near 0 on flat areas, under a still camera, and where the frame stays put
    (an object the camera follows).
    """
    return frame_evidence(prev, cur, matrix, window=window, noise=noise, start=start,
                          span=span)[1]


def frame_evidence(prev: np.ndarray, cur: np.ndarray, matrix: np.ndarray, *,
                   residual: Optional[np.ndarray] = None, window: int = 7, noise: float = 4.0,
                   start: float = 0.1, span: float = 0.4,
                   parallax: Optional[FieldWarp] = None) -> tuple:
    """``(against, along)``, both (H, W) float32 in [0, 1]: :func:`motion_evidence_map` and
    :func:`camera_evidence_map` of the same frames (see there for the parameters), from one
    warp of ``prev`` (by ``matrix``, or by ``parallax``, the homography and the background's
    parallax, :class:`~bgsub._util.FieldWarp`)."""
    _check_frames(prev, cur)
    h, w = cur.shape[:2]
    k = (int(window), int(window))
    if parallax is not None:  # the camera's motion in a 3-D scene: plane plus parallax
        moved = parallax(prev, cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)
    else:
        moved = warp_image(prev, matrix, (w, h), cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)
    r_cam = _mean_absdiff(cur, moved, k)
    r_still = _mean_absdiff(cur, prev, k)
    along = _ramp(r_still - r_cam, r_cam + r_still + np.float32(noise), start, span)
    r_alt = r_still
    if residual is not None:
        # The camera-moved frame moved on by the residual: the local vectors' motion (exact for
        # a translation, and to first order for the small rotations and zooms between frames).
        grid_x, grid_y = pixel_grid(h, w)
        map_x, map_y = grid_x - residual[:, :, 0], grid_y - residual[:, :, 1]
        local = through_bgra(lambda img: cv2.remap(img, map_x, map_y, cv2.INTER_LINEAR,
                                                   borderMode=cv2.BORDER_REPLICATE), moved)
        r_alt = np.minimum(r_still, _mean_absdiff(cur, local, k))
    against = _ramp(r_cam - r_alt, r_cam + r_alt + np.float32(noise), start, span)
    return against, along


def _ramp(num: np.ndarray, den: np.ndarray, start: float, span: float) -> np.ndarray:
    """``clip((num / den - start) / span, 0, 1)``, (H, W) float32, in place in ``num``."""
    s = np.divide(num, den, out=num)
    s -= np.float32(start)
    s *= np.float32(1.0 / span)
    return np.clip(s, 0.0, 1.0, out=s)


def _check_frames(prev: np.ndarray, cur: np.ndarray) -> None:
    for name, image in (("prev", prev), ("cur", cur)):
        if getattr(image, "dtype", None) != np.uint8 or image.ndim not in (2, 3):
            raise InputError(f"motion_evidence_map takes uint8 frames; {name} is "
                             f"{getattr(image, 'dtype', type(image).__name__)} of shape "
                             f"{np.shape(image)}")
    if prev.shape != cur.shape:
        raise InputError(f"motion_evidence_map: prev and cur differ in shape, {prev.shape} and "
                         f"{cur.shape}")


def _mean_absdiff(a: np.ndarray, b: np.ndarray, k: tuple) -> np.ndarray:
    """(H, W) float32: |a - b| averaged over ``k``; for colour frames the channels' absolute
    differences are summed with the gray-level weights (so a change of hue at one gray level
    still counts: no channel's difference can cancel another's)."""
    diff = cv2.absdiff(a, b)
    if diff.ndim == 3:
        diff = cv2.cvtColor(diff, cv2.COLOR_BGR2GRAY)
    return cv2.blur(diff.astype(np.float32), k)
