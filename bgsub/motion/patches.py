"""Patches cut on a grid of one pyramid level, weighed by their texture, and read by the model.

A level's first-frame side (grid, texture weights, the patches kept and their projections onto
the model's filters) does not change between the readouts of a pair, nor when the frame's
:class:`~bgsub.motion.pyramid.FramePyramid` is read again: :class:`PatchGrids` keeps it.
:func:`read_level` pairs it with the second frame pre-warped by a motion guess, in one batched
inference.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Protocol, Tuple, runtime_checkable

import cv2
import numpy as np
from numpy.lib.stride_tricks import as_strided

from bgsub.model.tiling import patch_grid
from bgsub.motion.global_motion import (GlobalMotion, apply_homography, fit_global_motion,
                                        is_identity)
from bgsub.motion.pyramid import warp_back

__all__ = ["WEAK_TEXTURE", "PatchMotion", "LevelGrid", "LevelReading", "PatchGrids",
           "level_texture_map", "patch_motion", "patches_at", "read_level", "reading_from",
           "reads_raw", "texture_weights", "textured_pixels"]

#: Patches with less than this fraction of the level's largest structure-tensor eigenvalue are
#: at the noise level when the stronger ones lie in one compact region (``_COMPACT``): see
#: :func:`texture_weights`. (OpenCV's corner detector, the `compensated` engine's front end,
#: keeps corners of at least 1 % of the best one's quality.)
WEAK_TEXTURE = 0.003
_COMPACT = 1.0 / 3.0


@runtime_checkable
class PatchMotion(Protocol):
    """A patch-motion estimator other than the gated RBM (a test's oracle, another learnt
    model): it reads raw patch pairs itself, so the gated RBM's projections of the first
    frame's patches are neither made nor reused for it. A :class:`~bgsub.model.rbm.GatedRBM`
    is not one: :func:`patch_motion` reads it through :mod:`bgsub.model.readout`."""

    patch_size: int

    def patch_motion(self, x_raw: np.ndarray, y_raw: np.ndarray, *,
                     max_disp: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(disp (N, 2) float32, confidence (N,) float32, flat (N,) bool)`` of the ``(N, p*p)
        float32`` raw patch pairs ``x_raw`` / ``y_raw`` in [0, 1], within ``max_disp`` px."""


def reads_raw(model: Any) -> bool:
    """Whether ``model`` is a :class:`PatchMotion`: the protocol's own test (both members
    present), without ``isinstance``'s scan of the protocol, which costs tens of microseconds
    and runs several times a frame."""
    return hasattr(model, "patch_size") and callable(getattr(model, "patch_motion", None))


def patch_motion(model: Any, x_raw: np.ndarray, y_raw: np.ndarray, *, max_disp: int,
                 x_features: Any = None) -> tuple:
    """One batched gated-RBM readout.

    Parameters
    ----------
    model : bgsub.model.rbm.GatedRBM or a :class:`PatchMotion`
    x_raw, y_raw : (N, p*p) float32 raw patches in [0, 1]
    max_disp : int
    x_features : bgsub.model.readout.PatchFeatures, optional
        ``x_raw`` already projected (GatedRBM only; reused across reads of the same patches).

    Returns
    -------
    disp : (N, 2) float32 ``(dx, dy)``
    confidence : (N,) float32, 0 for flat pairs
    flat : (N,) bool
    """
    if len(x_raw) == 0:
        return np.zeros((0, 2), np.float32), np.zeros(0, np.float32), np.zeros(0, bool)
    if reads_raw(model):
        return model.patch_motion(x_raw, y_raw, max_disp=max_disp)
    from bgsub.model import readout

    # prepare() + patch_displacements() fused (same result to float32 rounding).
    return readout.raw_patch_motion(model, x_raw, y_raw, max_disp=max_disp, x_features=x_features)


def texture_weights(e: np.ndarray, centres: np.ndarray, shape: tuple, *,
                    texture_scale: float) -> np.ndarray:
    """Texture weights ``e / (e + texture_scale)`` of patches with smaller structure-tensor
    eigenvalues ``e`` ((N,) float32) centred at ``centres`` ((N, 2) ``(x, y)``) in a level of
    ``shape`` (H, W); ``(N,) float32`` in [0, 1).

    When every patch with at least ``WEAK_TEXTURE`` of the largest ``e`` lies within a third of
    the level's width and of its height (one textured object over a flat, noisy background),
    the others get weight 0: their "texture" is sensor noise, which reads as random motions
    that RANSAC can fit (a still camera over a noisy gray ramp would be given motions of up to
    13 px). The object's own motion is then the only one measured, and the engines take it for
    an object's (``min_extent``).
    """
    tex = (e / (e + np.float32(texture_scale))).astype(np.float32)
    if len(e) == 0:
        return tex
    strong = e >= np.float32(WEAK_TEXTURE) * e.max()
    h, w = shape[:2]
    spread = np.ptp(centres[strong], axis=0)
    if spread[0] < _COMPACT * w and spread[1] < _COMPACT * h:
        tex[~strong] = 0.0
    return tex


def level_texture_map(gray: np.ndarray, p: int) -> np.ndarray:
    """:func:`bgsub.model.tiling.texture_map` (window ``p``) of a ``(H, W) float32`` level,
    exact wherever a ``p x p`` box fits inside the image (at every patch centre), in one OpenCV
    call: ``cornerMinEigenVal`` computes the same smaller structure-tensor eigenvalue from Sobel
    gradients scaled by ``1 / (4 p)`` and box *sums*, which is 4 times ``texture_map``'s
    (gradients / 8, box means). Near the border the two differ (``texture_map`` reflects the
    box, this reflects with 101). Returns ``(H, W) float32``, at least 0."""
    gray = np.asarray(gray, dtype=np.float32)
    tmap = cv2.cornerMinEigenVal(gray, p, ksize=3)
    tmap *= np.float32(0.25)
    return np.maximum(tmap, 0.0, out=tmap)


def textured_pixels(gray: np.ndarray) -> np.ndarray:
    """``(H, W) bool``: pixels of ``gray`` ``(H, W) float32`` with any gradient (|dx| + |dy|
    above about 0.0025 per pixel on gray values in [0, 1]); flat pixels agree under every
    motion and would only dilute the photometric check."""
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1)
    return (np.abs(gx) + np.abs(gy)) > np.float32(0.02)  # Sobel is 8x the per-pixel slope


_GRIDS: dict = {}


def _grid(shape: tuple, p: int, stride: int) -> tuple:
    """:func:`bgsub.model.tiling.patch_grid`, memoised (the same few grids every frame); the
    centres are read-only."""
    key = (int(shape[0]), int(shape[1]), int(p), int(stride))
    if key not in _GRIDS:
        if len(_GRIDS) > 64:
            _GRIDS.clear()
        centres, grid_shape = patch_grid(shape, patch_size=p, stride=stride)
        centres.setflags(write=False)
        _GRIDS[key] = (centres, grid_shape)
    return _GRIDS[key]


def patches_at(image: np.ndarray, centres: np.ndarray, p: int, *, stride: int = 0) -> np.ndarray:
    """The ``p x p`` patches of ``image`` ``(H, W)`` centred at integer ``centres`` ``(n, 2)``:
    ``(n, p*p) float32`` (one gather from a strided view, no loop). ``stride > 0`` says
    ``centres`` is the whole :func:`~bgsub.model.tiling.patch_grid` of ``image`` with that
    stride: one strided slice then."""
    if len(centres) == 0:
        return np.zeros((0, p * p), np.float32)
    image = np.ascontiguousarray(image, dtype=np.float32)
    h, w = image.shape
    s0, s1 = image.strides
    # The same view as sliding_window_view(image, (p, p)), without its per-call overhead.
    windows = as_strided(image, shape=(h - p + 1, w - p + 1, p, p), strides=(s0, s1, s0, s1),
                         writeable=False)
    if stride > 0:
        return np.ascontiguousarray(windows[::stride, ::stride]).reshape(len(centres), p * p)
    half = p // 2
    ci = centres.astype(np.intp) - half
    return windows[ci[:, 1], ci[:, 0]].reshape(len(ci), p * p)


@dataclass
class LevelGrid:
    """A first-frame level's patch grid with ``stride``, as cut by :class:`PatchGrids`.

    Attributes
    ----------
    centres : (N, 2) float32, read-only
        Patch centres ``(x, y)`` in the level's pixels, row-major over ``grid_shape``.
    grid_shape : (rows, cols)
    texture : (N,) float32
        :func:`texture_weights` in [0, 1).
    pick : (K,) intp
        The patches read (texture at least ``min_texture``, at most ``max_patches``).
    x : (K, p*p) float32
        Their raw patches, gray in [0, 1].
    stride : int
    features : bgsub.model.readout.PatchFeatures or None
        ``x`` projected onto a GatedRBM's filters (None for other models or no patch).
    """

    centres: np.ndarray
    grid_shape: tuple
    texture: np.ndarray
    pick: np.ndarray
    x: np.ndarray
    stride: int
    features: Any = None

    @property
    def whole(self) -> bool:
        """Every patch of the grid is read (its patches are then cut by one strided slice)."""
        return len(self.pick) == len(self.centres)


class PatchGrids:
    """What is cut from one first frame for one model and patch settings: per level shape and
    stride a :class:`LevelGrid`, and per level shape its texture map and textured pixels.

    Parameters
    ----------
    model : the patch-motion model (``patch_size``)
    min_texture : float
        Patches with a lower texture weight are not read.
    max_patches : int or None
        Read at most this many patches per grid (the most textured).
    texture_scale : float
        Eigenvalue at which the texture weight is 0.5 (:func:`texture_weights`).
    """

    def __init__(self, model: Any, *, min_texture: float, max_patches: Optional[int],
                 texture_scale: float) -> None:
        self.model = model
        self.patch_size = int(model.patch_size)
        self.min_texture = min_texture
        self.max_patches = max_patches
        self.texture_scale = texture_scale
        self._grids: Dict[Tuple[tuple, int], LevelGrid] = {}
        self._texture: Dict[tuple, np.ndarray] = {}
        self._textured: Dict[tuple, np.ndarray] = {}

    def has(self, shape: tuple, stride: int) -> bool:
        """Whether the grid of ``stride`` on a level of ``shape`` is cut already."""
        return (shape, stride) in self._grids

    def grid(self, image: np.ndarray, stride: int) -> LevelGrid:
        """The grid of ``stride`` on the level ``image`` ``(H, W) float32``, cut on first use."""
        key = (image.shape, stride)
        if key not in self._grids:
            self._grids[key] = self._cut(image, stride)
        return self._grids[key]

    def textured(self, image: np.ndarray) -> np.ndarray:
        """:func:`textured_pixels` of the level ``image``, kept."""
        if image.shape not in self._textured:
            self._textured[image.shape] = textured_pixels(image)
        return self._textured[image.shape]

    def _cut(self, image: np.ndarray, stride: int) -> LevelGrid:
        p = self.patch_size
        centres, grid_shape = _grid(image.shape, p, stride)
        n = len(centres)
        tex = np.zeros(n, np.float32)
        if n:
            if image.shape not in self._texture:
                # A level's texture map serves every grid cut from it.
                self._texture[image.shape] = level_texture_map(image, p)
            ci = centres.astype(np.intp)  # centres are integers for odd p
            tex = texture_weights(self._texture[image.shape][ci[:, 1], ci[:, 0]], centres,
                                  image.shape, texture_scale=self.texture_scale)
        pick = np.flatnonzero(tex >= self.min_texture)
        if self.max_patches is not None and len(pick) > self.max_patches:
            pick = pick[np.argsort(-tex[pick], kind="stable")[:self.max_patches]]
            pick.sort()
        x = patches_at(image, centres[pick], p, stride=stride if len(pick) == n else 0)
        return LevelGrid(centres, grid_shape, tex, pick, x, stride, self._features(x))

    def _features(self, x: np.ndarray) -> Any:
        if reads_raw(self.model) or len(x) == 0:
            return None
        from bgsub.model.readout import patch_features

        return patch_features(self.model, x, side="x")

    def add_subgrid(self, shape: tuple, stride: int, sub_stride: int) -> None:
        """Derive the grid of ``sub_stride`` (a multiple of ``stride``, same origin) on the
        level of ``shape`` from its cut grid of ``stride``, of which it is every
        ``sub_stride / stride``-th patch, without recomputing anything."""
        full = self._grids[(shape, stride)]
        k = sub_stride // stride
        rows, cols = full.grid_shape
        sub = (np.arange(0, rows, k)[:, None] * cols + np.arange(0, cols, k)[None, :]).ravel()
        centres, grid_shape = _grid(shape, self.patch_size, sub_stride)
        tex = full.texture[sub]
        pick = np.flatnonzero(tex >= self.min_texture)
        pos = np.searchsorted(full.pick, sub[pick])  # every subset pick is a pick of the full grid
        features = None if full.features is None else full.features.take(pos)
        self._grids[(shape, sub_stride)] = LevelGrid(centres, grid_shape, tex, pick,
                                                     full.x[pos], sub_stride, features)


@dataclass
class LevelReading:
    """Patch motion at one level (the level's pixels), as :func:`read_level` returns it.

    Attributes
    ----------
    centres : (N, 2) float32
    grid_shape : (rows, cols)
    disp : (N, 2) float32
        ``(dx, dy)`` to the second frame: the pre-warp's motion plus ``residual``.
    residual : (N, 2) float32
        The model's reading on the pre-warped second frame (0 where not read).
    conf : (N,) float32
    texture : (N,) float32
    valid : (N,) bool
        Read, not flat, and (unless ``accept_edge``) inside the model's range.
    beyond : (N,) bool
        Read, not flat, and at the edge of the model's range.
    """

    centres: np.ndarray
    grid_shape: tuple
    disp: np.ndarray
    residual: np.ndarray
    conf: np.ndarray
    texture: np.ndarray
    valid: np.ndarray
    beyond: np.ndarray

    @property
    def weights(self) -> np.ndarray:
        """``conf * texture`` where valid, else 0: ``(N,) float32``."""
        return np.where(self.valid, self.conf * self.texture, 0.0)


    def fit(self, model: str, *, threshold: float, shape: tuple) -> GlobalMotion:
        """The motion RANSAC fits to the valid readings of a level of ``shape`` (H, W): the
        ``model`` asked for, or fewer degrees of freedom when few patches are valid (a coarse
        level of a small frame)."""
        w = self.weights
        n_valid = int(np.count_nonzero(w > 0))
        if n_valid < 40 and model in ("homography", "affine"):
            model = "similarity"
        if n_valid < 12:
            model = "translation"
        return fit_global_motion(self.centres, self.centres + self.disp, weights=w, model=model,
                                 threshold=threshold, min_points=6,
                                 frame_size=(shape[1], shape[0]))


def reading_from(grid: LevelGrid, h_est: np.ndarray, disp: np.ndarray, conf: np.ndarray,
                 flat: np.ndarray, *, max_disp: int, accept_edge: bool = False) -> LevelReading:
    """The :class:`LevelReading` of ``grid`` whose picked patches the model read as ``disp``
    ``(K, 2)``, ``conf`` ``(K,)`` and ``flat`` ``(K,) bool`` on the second frame pre-warped by
    ``h_est`` (see :func:`read_level` for ``accept_edge``)."""
    n, pick = len(grid.centres), grid.pick
    residual = np.zeros((n, 2), np.float32)
    confidence = np.zeros(n, np.float32)
    valid = np.zeros(n, bool)
    beyond = np.zeros(n, bool)
    residual[pick] = disp
    confidence[pick] = conf
    # A reading at the edge of the range may be a larger motion clipped: not trusted.
    inside = np.max(np.abs(disp), axis=1) < max_disp - 0.25
    valid[pick] = ~flat & (inside | accept_edge)
    beyond[pick] = ~flat & ~inside
    # Correspondence: x -> H (x + r), because warped(x + r) = g2(H (x + r)) ~ g1(x).
    dst = apply_homography(h_est, grid.centres + residual).astype(np.float32)
    return LevelReading(grid.centres, grid.grid_shape, dst - grid.centres, residual, confidence,
                        grid.texture, valid, beyond)


def read_level(grid: LevelGrid, g2: np.ndarray, h_est: np.ndarray, *, model: Any,
               max_disp: int, accept_edge: bool = False) -> LevelReading:
    """Patch motion from the first frame's ``grid`` to the level ``g2`` ``(H, W) float32`` of
    the second frame pre-warped by ``h_est`` ``(3, 3)`` (the level's pixels).

    ``accept_edge``: keep readings at the edge of the model's range (``max_disp``) valid. They
    may be a larger motion, clipped, but still point the right way, which is all a pre-warp
    needs; the final readout drops them.
    """
    if len(grid.pick):
        warped = g2 if is_identity(h_est) else warp_back(g2, h_est)
        y = patches_at(warped, grid.centres[grid.pick], int(model.patch_size),
                       stride=grid.stride if grid.whole else 0)
        d, c, flat = patch_motion(model, grid.x, y, max_disp=max_disp, x_features=grid.features)
    else:
        d, c, flat = np.zeros((0, 2), np.float32), np.zeros(0, np.float32), np.zeros(0, bool)
    return reading_from(grid, h_est, d, c, flat, max_disp=max_disp, accept_edge=accept_edge)
