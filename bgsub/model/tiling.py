"""Frames to patch pairs: the input stage of the gated-RBM motion front end.

A frame pair becomes one ``(N, p*p) float32`` array of patches per frame, cut on a regular grid
with :func:`numpy.lib.stride_tricks.sliding_window_view` (no loop per patch), plus the patch
centres and a texture score per patch. The texture score is the smaller eigenvalue of the
structure tensor averaged over the patch (Shi-Tomasi): it is small both for flat patches and for
patches that hold a single straight edge (the aperture problem), where no model can tell the
displacement along the edge, so later stages down-weight those patches.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from bgsub.errors import InputError

#: Smaller structure-tensor eigenvalue that maps to texture weight 0.5 (see :func:`texture_score`).
TEXTURE_SCALE = 2e-3

__all__ = [
    "TEXTURE_SCALE",
    "PatchPairs",
    "to_gray",
    "patch_grid",
    "extract_patches",
    "extract_patch_pairs",
    "texture_map",
    "texture_at",
    "texture_score",
]


@dataclass
class PatchPairs:
    """Patches cut at the same places from two frames.

    Attributes
    ----------
    x, y : (N, p*p) float32
        Row-major patches of the first and second frame, gray values in [0, 1].
    centres : (N, 2) float32
        Patch centres ``(x, y)`` in pixel coordinates of the frames.
    grid_shape : (rows, cols)
        The patches form this grid, row-major (``N == rows * cols``).
    patch_size : int
    stride : int
    """

    x: np.ndarray
    y: np.ndarray
    centres: np.ndarray
    grid_shape: tuple
    patch_size: int
    stride: int


def to_gray(frame: np.ndarray) -> np.ndarray:
    """A frame as gray float32 in [0, 1].

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) gray array, uint8 (0-255) or float (already in [0, 1])

    Returns
    -------
    (H, W) float32
    """
    frame = np.asarray(frame)
    if frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[:, :, 0]
    if frame.ndim == 3:
        if frame.shape[2] != 3:
            raise InputError(f"frames must have 1 or 3 channels, not {frame.shape[2]}")
        if frame.dtype != np.uint8:
            frame = frame.astype(np.float32)
        frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    elif frame.ndim != 2:
        raise InputError(f"a frame must be (H, W) or (H, W, 3), not shape {frame.shape}")
    if frame.dtype == np.uint8:
        return frame.astype(np.float32) * np.float32(1.0 / 255.0)
    return frame.astype(np.float32, copy=False)


def _check_grid(patch_size: int, stride: int) -> None:
    if patch_size < 1 or stride < 1:
        raise InputError(f"patch_size and stride must be positive, not {patch_size}, {stride}")


def patch_grid(shape: tuple, *, patch_size: int = 13, stride: int = 6) -> tuple:
    """Where patches are cut in an image of ``shape``.

    Parameters
    ----------
    shape : (H, W, ...)
    patch_size, stride : int

    Returns
    -------
    centres : (N, 2) float32 ``(x, y)`` of the patch centres (row-major grid)
    grid_shape : (rows, cols)
    """
    h, w = int(shape[0]), int(shape[1])
    _check_grid(patch_size, stride)
    if h < patch_size or w < patch_size:
        empty = np.zeros((0, 2), np.float32)
        return empty, (0, 0)
    half = (patch_size - 1) / 2.0
    xs = np.arange(0, w - patch_size + 1, stride, dtype=np.float32) + half
    ys = np.arange(0, h - patch_size + 1, stride, dtype=np.float32) + half
    gx, gy = np.meshgrid(xs, ys)
    centres = np.stack([gx.ravel(), gy.ravel()], axis=1).astype(np.float32)
    return centres, (len(ys), len(xs))


def extract_patches(image: np.ndarray, *, patch_size: int = 13, stride: int = 6) -> np.ndarray:
    """All ``patch_size`` x ``patch_size`` patches of a gray image on the grid of :func:`patch_grid`.

    Parameters
    ----------
    image : (H, W) float32
    patch_size, stride : int

    Returns
    -------
    (N, patch_size**2) float32, row-major patches in the order of :func:`patch_grid`.
    """
    _check_grid(patch_size, stride)
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 2:
        raise InputError(f"extract_patches needs an (H, W) gray image, not shape {image.shape} "
                         "(see to_gray)")
    if image.shape[0] < patch_size or image.shape[1] < patch_size:
        return np.zeros((0, patch_size * patch_size), np.float32)
    windows = sliding_window_view(image, (patch_size, patch_size))[::stride, ::stride]
    # One copy into a contiguous block: the model needs a C-contiguous matrix for BLAS.
    return np.ascontiguousarray(windows.reshape(-1, patch_size * patch_size))


def extract_patch_pairs(
    frame1: np.ndarray,
    frame2: np.ndarray,
    *,
    patch_size: int = 13,
    stride: int = 6,
) -> PatchPairs:
    """Patch pairs cut at the same places from two frames of the same size.

    Parameters
    ----------
    frame1, frame2 : (H, W, 3) BGR / (H, W) gray uint8, or (H, W) float32 gray in [0, 1]
    patch_size : int
        Side of the square patches (the model's, 13 in the paper).
    stride : int
        Grid step in pixels; ``stride < patch_size`` makes the patches overlap.

    Returns
    -------
    PatchPairs
    """
    g1, g2 = to_gray(frame1), to_gray(frame2)
    if g1.shape != g2.shape:
        raise InputError(f"frames differ in size: {g1.shape} and {g2.shape}")
    centres, grid_shape = patch_grid(g1.shape, patch_size=patch_size, stride=stride)
    return PatchPairs(
        x=extract_patches(g1, patch_size=patch_size, stride=stride),
        y=extract_patches(g2, patch_size=patch_size, stride=stride),
        centres=centres,
        grid_shape=grid_shape,
        patch_size=patch_size,
        stride=stride,
    )


def texture_map(gray: np.ndarray, *, window: int = 13) -> np.ndarray:
    """Smaller eigenvalue of the structure tensor averaged over ``window`` x ``window`` boxes.

    Parameters
    ----------
    gray : (H, W) float32 in [0, 1]
    window : int
        Side of the averaging box (the patch size, so each value describes one patch).

    Returns
    -------
    (H, W) float32, >= 0; the value at a pixel describes the box centred there. Units are squared
    intensity gradients per pixel (a unit-contrast checkerboard of 4 px squares gives ~0.03).
    """
    gray = np.asarray(gray, dtype=np.float32)
    # Central differences (Sobel / 8): gradients in intensity per pixel.
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    box = (window, window)
    a = cv2.boxFilter(gx * gx, -1, box, borderType=cv2.BORDER_REFLECT)
    b = cv2.boxFilter(gx * gy, -1, box, borderType=cv2.BORDER_REFLECT)
    c = cv2.boxFilter(gy * gy, -1, box, borderType=cv2.BORDER_REFLECT)
    # Eigenvalues of [[a, b], [b, c]]: (a + c)/2 -+ sqrt(((a - c)/2)^2 + b^2).
    half_trace = 0.5 * (a + c)
    root = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.maximum(half_trace - root, 0.0).astype(np.float32, copy=False)


def texture_score(
    gray: np.ndarray,
    centres: np.ndarray,
    *,
    patch_size: int = 13,
    scale: float = TEXTURE_SCALE,
) -> np.ndarray:
    """Texture of the patches centred at ``centres``, mapped to a weight in [0, 1).

    Parameters
    ----------
    gray : (H, W) float32 in [0, 1]
    centres : (N, 2) float ``(x, y)`` patch centres
    patch_size : int
    scale : float
        The smaller structure-tensor eigenvalue that gives weight 0.5 (``w = e / (e + scale)``).
        The default puts a patch with a few percent contrast in both directions near 0.5, flat
        or single-edge patches near 0.

    Returns
    -------
    (N,) float32 in [0, 1)
    """
    if len(centres) == 0:
        return np.zeros(0, np.float32)
    e = texture_at(gray, centres, window=patch_size)
    return (e / (e + np.float32(scale))).astype(np.float32)


def texture_at(gray: np.ndarray, centres: np.ndarray, *, window: int = 13) -> np.ndarray:
    """:func:`texture_map` sampled at ``centres`` only (the eigenvalues are computed there, not
    over the whole image).

    Parameters
    ----------
    gray : (H, W) float32 in [0, 1]
    centres : (N, 2) float ``(x, y)``; rounded to the nearest pixel and clipped to the image
    window : int

    Returns
    -------
    (N,) float32 >= 0, equal to ``texture_map(gray, window=window)`` at those pixels.
    """
    gray = np.asarray(gray, dtype=np.float32)
    if len(centres) == 0:
        return np.zeros(0, np.float32)
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    # One 3-channel box filter instead of three single-channel ones.
    tensor = cv2.merge([gx * gx, gx * gy, gy * gy])
    tensor = cv2.boxFilter(tensor, -1, (window, window), borderType=cv2.BORDER_REFLECT)
    h, w = tensor.shape[:2]
    cx = np.clip(np.rint(centres[:, 0]).astype(np.intp), 0, w - 1)
    cy = np.clip(np.rint(centres[:, 1]).astype(np.intp), 0, h - 1)
    a, b, c = tensor[cy, cx].T
    half_trace = 0.5 * (a + c)
    root = np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.maximum(half_trace - root, 0.0).astype(np.float32, copy=False)
