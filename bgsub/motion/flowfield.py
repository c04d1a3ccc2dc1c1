"""Patch motion from the gated RBM, coarse to fine, and the dense field assembled from it.

One 13x13 patch pair can only show a displacement of a few pixels (the model's range, +-3 or +-4
px), but a panning camera moves 5-20 px per frame. :func:`estimate_flow` therefore works on an
image pyramid (``cv2.pyrDown``): at the coarsest level motions are small enough for the model;
the camera motion fitted there (RANSAC, :mod:`bgsub.motion.global_motion`) pre-warps the second frame
at the next finer level, so the model only ever sees the *residual* motion, which is within its
range for everything that moves with the camera. Each level is one batched inference over all
(textured) patches.

Coordinates: a pyramid level ``l`` pixel ``x_l`` is ``x / 2**l`` in full-resolution pixels
(``pyrDown`` centres output pixel ``i`` on input pixel ``2 i``).
"""

from __future__ import annotations

import math
import os
import threading
import warnings
from dataclasses import dataclass
from typing import Any, List, Optional, Tuple

import cv2
import numpy as np
from numpy.lib.stride_tricks import as_strided

from bgsub.errors import InputError
from bgsub.motion.config import FlowConfig
from bgsub.motion.global_motion import (
    GlobalMotion,
    apply_homography,
    corner_distances,
    fit_global_motion,
    is_affine,
    is_identity,
)
from bgsub.model.tiling import TEXTURE_SCALE, patch_grid, to_gray

__all__ = [
    "FlowEstimate",
    "FramePyramid",
    "MotionRangeWarning",
    "estimate_flow",
    "prepare_first_frame",
    "auto_levels",
    "motion_reach",
    "PyramidReach",
    "pyramid_reach",
    "model_range",
    "patch_motion",
    "dense_from_patches",
]


@dataclass
class FlowEstimate:
    """Patch motion between two frames (full-resolution pixel units).

    Attributes
    ----------
    centres : (N, 2) float32
        Patch centres ``(x, y)`` in the first frame.
    disp : (N, 2) float32
        ``(dx, dy)``: the patch content at ``centres`` is at ``centres + disp`` in the second
        frame (pre-warp plus the model's residual). Undefined where not ``valid``.
    confidence : (N,) float32
        The readout's confidence in [0, 1] (0 for patches not evaluated).
    texture : (N,) float32
        Texture weight in [0, 1) (:func:`bgsub.model.tiling.texture_score` mapping).
    valid : (N,) bool
        Patch evaluated (not flat, enough texture) and its residual inside the model's range.
    beyond : (N,) bool
        Patch evaluated but its residual at the edge of the model's range: it moves more than
        the model can see relative to the pre-warp (after a good pre-warp, a moving object).
    grid_shape : (rows, cols)
    stride : int
        Grid step at full resolution.
    prewarp : (3, 3) float64
        The camera motion used to pre-warp the finest level (identity when ``levels == 1`` and no
        ``prior``).
    residual : (N, 2) float32
        The model's own reading at the finest level (``disp`` minus the pre-warp's motion).
    dense : (H, W, 2) float32 or None
        Per-pixel flow (NaN unknown) when asked for.
    levels : int
        Pyramid levels used.
    coarse_status : str
        ``"ok"`` or why a coarse level's fit was refused (its pre-warp then kept the prior).
    """

    centres: np.ndarray
    disp: np.ndarray
    confidence: np.ndarray
    texture: np.ndarray
    valid: np.ndarray
    grid_shape: tuple
    stride: int
    prewarp: np.ndarray
    residual: np.ndarray
    dense: Optional[np.ndarray] = None
    levels: int = 1
    coarse_status: str = "ok"
    beyond: Optional[np.ndarray] = None

    @property
    def weights(self) -> np.ndarray:
        """``confidence * texture`` where valid, else 0: ``(N,) float32``."""
        return np.where(self.valid, self.confidence * self.texture, 0.0).astype(np.float32)


def model_range(model: Any) -> int:
    """Largest displacement (px, per axis) the model was trained for: its ``meta["max_disp"]``
    (or ``meta["max_shift"]``), else 3."""
    meta = getattr(model, "meta", {}) or {}
    for key in ("max_disp", "max_shift", "max_displacement"):
        if key in meta:
            try:
                return max(1, int(round(float(meta[key]))))
            except (TypeError, ValueError):
                pass
    return 3


def patch_motion(model: Any, x_raw: np.ndarray, y_raw: np.ndarray, *, max_disp: int,
                 x_features: Any = None) -> tuple:
    """One batched gated-RBM readout.

    Parameters
    ----------
    model : bgsub.model.rbm.GatedRBM, or any object with ``patch_size`` and a method
        ``patch_motion(x_raw, y_raw, *, max_disp) -> (disp, confidence, flat)`` of this contract
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
    if hasattr(model, "patch_motion"):
        # Any other patch-motion estimator with the same contract (used by tests as an oracle).
        return model.patch_motion(x_raw, y_raw, max_disp=max_disp)
    from bgsub.model import readout

    # prepare() + patch_displacements() fused (same result to float32 rounding).
    return readout.raw_patch_motion(model, x_raw, y_raw, max_disp=max_disp, x_features=x_features)


def _warp_back(image: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``out(x) = image(matrix @ x)``: the second frame resampled into the first frame's grid."""
    h, w = image.shape[:2]
    m = np.asarray(matrix, np.float64)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    if is_affine(m):
        # Affine pre-warps (the coarse levels fit affine motion): the same map, cheaper.
        return cv2.warpAffine(image, m[:2] / m[2, 2], (w, h), flags=flags,
                              borderMode=cv2.BORDER_REPLICATE)
    return cv2.warpPerspective(image, m, (w, h), flags=flags, borderMode=cv2.BORDER_REPLICATE)


def _scaled(matrix: np.ndarray, factor: float) -> np.ndarray:
    """The homography ``matrix`` (full-resolution pixels) in pixels scaled by ``factor``."""
    # diag(f, f, 1) @ matrix @ diag(1/f, 1/f, 1), written out.
    out = np.array(matrix, dtype=np.float64)
    out[:2, 2] *= factor
    out[2, :2] /= factor
    return out


def auto_levels(shape: tuple, *, max_motion: float, model_disp: int, patch_size: int) -> int:
    """Pyramid levels so that ``max_motion`` px at full size is within ``model_disp`` at the
    coarsest level, while that level still holds a few patches across (its short side at least
    ``4 * patch_size``): on small frames fewer levels than ``max_motion`` needs (see
    :class:`MotionRangeWarning`)."""
    h, w = shape[:2]
    levels = 1
    # One pixel of margin: readings at the edge of the range are ambiguous (clipped or not).
    while max_motion / 2 ** (levels - 1) > model_disp - 1 and min(h, w) / 2**levels >= 4 * patch_size:
        levels += 1
    return levels


class MotionRangeWarning(UserWarning):
    """:func:`estimate_flow`'s automatic pyramid cannot reach the ``max_motion`` asked for: the
    frame is too small for the levels it needs, and larger motions are misread."""


def motion_reach(levels: int, *, model_disp: int, search: int = 0) -> int:
    """Largest motion (px per axis, full resolution) ``levels`` pyramid levels read from their
    start: the model's range less :func:`auto_levels`' one-pixel margin at the coarsest level,
    widened by the ``search`` grid there (steps of that much, see :func:`_choose_start`)."""
    step = max(1, model_disp - 1) * 2 ** (levels - 1)
    return step * (1 + max(0, int(search)) if levels > 1 else 1)


@dataclass(frozen=True)
class PyramidReach:
    """The pyramid :func:`estimate_flow` reads frames of one size with, and how far it reads:
    what :func:`pyramid_reach` returns, so that a caller who plans the ``search`` or says the
    reach in its own words (``bgsub flow``) counts as :func:`estimate_flow` does.

    Attributes
    ----------
    levels : int
        Pyramid levels read.
    model_disp : int
        The model's displacement range.
    """

    levels: int
    model_disp: int

    def reach(self, search: int = 0) -> int:
        """Largest motion read from the start with the ``search`` grid (:func:`motion_reach`)."""
        return motion_reach(self.levels, model_disp=self.model_disp, search=search)

    def search_for(self, max_motion: float, *, limit: int) -> int:
        """The smallest ``search`` whose reach covers ``max_motion``, at most ``limit`` (0 with
        one level, where :func:`estimate_flow` reads no grid of starts)."""
        step = self.reach()
        if self.levels <= 1 or step >= max_motion:
            return 0
        return min(int(limit), math.ceil(max_motion / step) - 1)


def pyramid_reach(shape: tuple, *, max_motion: float, model_disp: int, patch_size: int,
                  levels: Optional[int] = None) -> PyramidReach:
    """The pyramid :func:`estimate_flow` reads frames of ``shape`` (H, W) with: ``levels``
    (default :func:`auto_levels`), fewer where a level would be less than two patches across
    (as :meth:`FramePyramid.levels` stops)."""
    if levels is None:
        levels = auto_levels(shape, max_motion=max_motion, model_disp=model_disp,
                             patch_size=patch_size)
    wanted, levels = max(1, int(levels)), 1
    h, w = shape[:2]
    while levels < wanted and min(h, w) >= 2 * patch_size:
        h, w, levels = (h + 1) // 2, (w + 1) // 2, levels + 1
    return PyramidReach(levels=levels, model_disp=model_disp)


class FramePyramid:
    """A frame's gray image pyramid (``cv2.pyrDown``), built once and used as the second frame
    of one pair and the first of the next.

    It also keeps what :func:`estimate_flow` cuts from a *first* frame (per level and grid: the
    texture map, the patches and their projections onto the model's filters), so a video's
    consecutive pairs build each frame's pyramid once, and :func:`prepare_first_frame` can do
    that work ahead of time (e.g. in another thread, while the previous pair is read).

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) gray uint8, or (H, W) float32 gray in [0, 1]

    Attributes
    ----------
    images : list of (H_l, W_l) float32
        Level 0 (the frame, gray in [0, 1]) and the coarser levels built so far.
    """

    def __init__(self, frame: np.ndarray) -> None:
        self.images: List[np.ndarray] = [to_gray(frame)]
        self._caches: dict = {}
        self._lock = threading.Lock()  # levels() may be called from two threads at once

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        del state["_lock"]  # locks cannot be pickled; a copy gets its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    @property
    def shape(self) -> tuple:
        """``(H, W)`` of level 0."""
        return self.images[0].shape

    def levels(self, n: int, patch_size: int) -> List[np.ndarray]:
        """The first ``n`` levels, fewer when a level would be less than two patches across."""
        with self._lock:
            while len(self.images) < n and min(self.images[-1].shape) >= 2 * patch_size:
                self.images.append(cv2.pyrDown(self.images[-1]))
            return self.images[:n]

    def cache(self, model: Any, settings: tuple) -> dict:
        """The first-frame cache for one model and patch settings (a plain dict, see
        :func:`_level`); the model is kept alive with it so its ``id`` stays unique."""
        with self._lock:
            key = (id(model), settings)
            if key not in self._caches:
                self._caches[key] = (model, {})
            return self._caches[key][1]


@dataclass(frozen=True)
class _Plan:
    """Which pyramid levels and grids :func:`estimate_flow` reads (strides in each level's own
    pixels)."""

    pyramid: PyramidReach
    fine: int
    coarse_stride: int
    fine_stride: int
    pre_stride: int
    iterations: int

    @property
    def levels(self) -> int:
        """Pyramid levels read (those of :attr:`pyramid`)."""
        return self.pyramid.levels


def _plan(shape: tuple, *, p: int, rng: int, levels: Optional[int], max_motion: float,
          stride: int, coarse_stride: Optional[int], finest: int,
          refine_stride: Optional[int], iterations: int) -> _Plan:
    pyramid = pyramid_reach(shape, max_motion=max_motion, model_disp=rng, patch_size=p,
                            levels=levels)
    fine = min(max(0, int(finest)), pyramid.levels - 1)
    fine_stride = stride if fine == 0 else max(4, int(round(stride / 2**fine)))
    pre_stride = fine_stride
    if refine_stride is not None:
        pre_stride = max(4, int(round(int(refine_stride) / 2**fine)))
    return _Plan(pyramid=pyramid, fine=fine, coarse_stride=max(4, int(coarse_stride or stride)),
                 fine_stride=fine_stride, pre_stride=pre_stride,
                 iterations=max(1, int(iterations)))


def _prepare_first(pyr1: List[np.ndarray], cache: dict, plan: _Plan, *, model: Any, p: int,
                   rng: int, min_texture: float, max_patches: Optional[int],
                   texture_scale: float, photometric: bool) -> None:
    """Cut and project the first frame's patches for every grid ``plan`` reads (into
    ``cache``; what is there already is kept)."""

    def cut(lvl: int, stride: int) -> None:
        g = pyr1[lvl]
        _level(g, g, np.eye(3), model, p, stride, rng, min_texture, max_patches, cache=cache,
               read=False, texture_scale=texture_scale)
        key = (g.shape, stride)
        _x_features(model, cache[key][4], cache, key)

    for lvl in range(plan.levels - 1, plan.fine, -1):
        cut(lvl, plan.coarse_stride)
    coarsest = pyr1[plan.levels - 1]
    if photometric and plan.levels > 1 and ("textured", coarsest.shape) not in cache:
        cache[("textured", coarsest.shape)] = _textured_pixels(coarsest)
    cut(plan.fine, plan.fine_stride)
    fine_shape = pyr1[plan.fine].shape
    if plan.iterations > 1 and plan.pre_stride != plan.fine_stride \
            and (fine_shape, plan.pre_stride) not in cache:
        if plan.pre_stride % plan.fine_stride == 0 and max_patches is None \
                and not hasattr(model, "patch_motion"):
            # The refining grid is every (pre_stride / fine_stride)-th patch of the final grid:
            # take that subset of the final grid's patches and projections.
            _subgrid(cache, fine_shape, p, plan.fine_stride, plan.pre_stride, min_texture, model)
        else:
            cut(plan.fine, plan.pre_stride)


def _prepare_first_frame_kw(
    frame: FramePyramid,
    *,
    model: Any,
    stride: int = 6,
    levels: Optional[int] = None,
    max_motion: float = 20.0,
    max_disp: Optional[int] = None,
    coarse_stride: Optional[int] = None,
    min_texture: float = 0.05,
    texture_scale: float = TEXTURE_SCALE,
    max_patches: Optional[int] = None,
    iterations: int = 1,
    finest: int = 0,
    refine_stride: Optional[int] = None,
    start_tolerance: float = 0.0,
) -> None:
    """Do ahead of time the work :func:`estimate_flow` would do on ``frame`` as the *first*
    frame of a pair (build its pyramid; cut, texture-weigh and project its patches).

    Pass the same keyword values the later :func:`estimate_flow` call gets (the parameters are
    its parameters of the same names); the result is stored in ``frame`` and changes nothing
    in what :func:`estimate_flow` returns, only how long it takes. Safe to run in a second
    thread while ``frame`` is the *second* frame of another :func:`estimate_flow` call.
    """
    _first_frame_work(frame, model=model, stride=stride, levels=levels, max_motion=max_motion,
                      max_disp=max_disp, coarse_stride=coarse_stride, min_texture=min_texture,
                      texture_scale=texture_scale, max_patches=max_patches,
                      iterations=iterations, finest=finest, refine_stride=refine_stride,
                      start_tolerance=start_tolerance)



def _keywords(config: FlowConfig) -> dict:
    """``config`` as the keyword arguments of the coarse-to-fine reader (0 = None)."""
    if not isinstance(config, FlowConfig):
        raise InputError(f"config must be a FlowConfig, not {type(config).__name__}")
    out = {name: getattr(config, name) for name in (
        "stride", "max_motion", "coarse_model", "min_texture", "texture_scale", "dense",
        "ransac_threshold", "iterations", "search", "coarse_iterations", "finest",
        "search_below", "start_tolerance", "converged", "start_model", "warn_range")}
    for name in ("levels", "max_disp", "coarse_stride", "max_patches", "refine_stride"):
        out[name] = getattr(config, name) or None
    return out


_PREPARE_KEYS = ("stride", "levels", "max_motion", "max_disp", "coarse_stride", "min_texture",
                 "texture_scale", "max_patches", "iterations", "finest", "refine_stride",
                 "start_tolerance")


def prepare_first_frame(pyramid: FramePyramid, config: FlowConfig = FlowConfig(), *,
                        model: Any) -> None:
    """Do ahead of time the work :func:`estimate_flow` with the same ``config`` and ``model``
    would do on ``pyramid`` as the *first* frame of a pair (build its pyramid; cut,
    texture-weigh and project its patches).

    The result is stored in ``pyramid`` and changes nothing in what :func:`estimate_flow`
    returns, only how long it takes. Safe to run in a second thread while ``pyramid`` is the
    *second* frame of another :func:`estimate_flow` call.
    """
    kw = _keywords(config)
    _prepare_first_frame_kw(pyramid, model=model, **{k: kw[k] for k in _PREPARE_KEYS})


def estimate_flow(frame1: np.ndarray, frame2: np.ndarray, config: FlowConfig = FlowConfig(), *,
                  model: Any, prior: Optional[np.ndarray] = None) -> FlowEstimate:
    """Patch displacements between two frames, coarse to fine, read as ``config`` says.

    Parameters
    ----------
    frame1, frame2 : (H, W, 3) BGR or (H, W) gray uint8, (H, W) float32 gray in [0, 1], or
        FramePyramid (reused: a video's frame serves as ``frame2`` of one call and ``frame1`` of
        the next, and what is cut from a ``frame1`` is kept in it)
    config : FlowConfig
    model : bgsub.model.rbm.GatedRBM, a shipped model name or .npz path
    prior : (3, 3) float64, optional
        A guess of the camera motion (e.g. the previous frame's).
    """
    return _estimate_flow_kw(frame1, frame2, model=model, prior=prior, **_keywords(config))

def _first_frame_work(frame: FramePyramid, *, model: Any, stride: int, levels: Optional[int],
                      max_motion: float, max_disp: Optional[int],
                      coarse_stride: Optional[int], min_texture: float, texture_scale: float,
                      max_patches: Optional[int], iterations: int, finest: int,
                      refine_stride: Optional[int], start_tolerance: float) -> tuple:
    """The plan of :func:`estimate_flow` and the first frame's part of it, done (what is in
    ``frame`` already is kept): ``(plan, pyramid levels, cache, patch side, model range)``."""
    p = int(model.patch_size)
    rng = int(max_disp) if max_disp is not None else model_range(model)
    plan = _plan(frame.shape, p=p, rng=rng, levels=levels, max_motion=max_motion, stride=stride,
                 coarse_stride=coarse_stride, finest=finest, refine_stride=refine_stride,
                 iterations=iterations)
    pyr = frame.levels(plan.levels, p)
    cache = frame.cache(model, (rng, p, min_texture, max_patches, texture_scale))
    _prepare_first(pyr, cache, plan, model=model, p=p, rng=rng, min_texture=min_texture,
                   max_patches=max_patches, texture_scale=texture_scale,
                   photometric=start_tolerance > 0)
    return plan, pyr, cache, p, rng


def _estimate_flow_kw(
    frame1: np.ndarray,
    frame2: np.ndarray,
    *,
    model: Any,
    stride: int = 6,
    levels: Optional[int] = None,
    max_motion: float = 20.0,
    max_disp: Optional[int] = None,
    coarse_stride: Optional[int] = None,
    prior: Optional[np.ndarray] = None,
    coarse_model: str = "affine",
    min_texture: float = 0.05,
    texture_scale: float = TEXTURE_SCALE,
    max_patches: Optional[int] = None,
    dense: bool = False,
    ransac_threshold: float = 1.0,
    iterations: int = 1,
    search: int = 0,
    coarse_iterations: int = 1,
    finest: int = 0,
    refine_stride: Optional[int] = None,
    search_below: float = 1.0,
    start_tolerance: float = 0.0,
    converged: float = 0.0,
    start_model: str = "translation",
    warn_range: bool = True,
) -> FlowEstimate:
    """Patch displacements between two frames, coarse to fine.

    Parameters
    ----------
    frame1, frame2 : (H, W, 3) BGR or (H, W) gray uint8, (H, W) float32 gray in [0, 1], or
        FramePyramid (reused: a video's frame serves as ``frame2`` of one call and ``frame1`` of
        the next, and what is cut from a ``frame1`` is kept in it)
    model : bgsub.model.rbm.GatedRBM
        The patch-motion model (``patch_size`` fixes the patch side).
    stride : int
        Patch grid step at full resolution (6: patches overlap by more than half).
    levels : int, optional
        Pyramid levels (1 = full resolution only). Default: enough for ``max_motion``.
    max_motion : float
        Largest frame-to-frame motion (px, full resolution) to plan the pyramid for. The levels
        are capped by the frame size (the coarsest at least 4 patches across, see
        :func:`auto_levels`): a 320x240 frame allows 3 levels, which read up to about 12 px per
        axis with a model of range 4 (24 px with ``search=1``). Larger motions are misread
        (patches still valid, ``coarse_status`` still ``"ok"``), so a ``max_motion`` beyond that
        reach gives a :class:`MotionRangeWarning` (with automatic ``levels`` only, and
        ``warn_range``: callers that read beyond from a prior or say it themselves pass False;
        filtering the warning instead would change the process-wide warning state).
    max_disp : int, optional
        The model's displacement range; default :func:`model_range`.
    coarse_stride : int, optional
        Patch grid step at the coarser levels (default ``stride``, at least 4).
    prior : (3, 3) float64, optional
        A guess of the camera motion (e.g. the previous frame's). With more than one level,
        the coarsest level is read pre-warped by the prior and by the identity (one batch), and
        the better start is kept (see ``start_tolerance`` and ``start_model``).
    coarse_model : str
        Motion model fitted at the coarser levels to pre-warp the next (see
        :func:`bgsub.motion.global_motion.fit_global_motion`).
    min_texture : float
        Patches whose texture weight is below this are not evaluated (flat or single edge).
    texture_scale : float
        Smaller structure-tensor eigenvalue (gray values in [0, 1]) that maps to texture
        weight 0.5: weight ``e / (e + texture_scale)``. The default weighs patches by their
        texture up to strong texture; a much smaller scale (e.g. ``1e-5``) down-weights only
        the nearly flat and edge-only patches and lets all textured ones count alike, which
        suits blurred footage whose patches all have weak gradients.
    max_patches : int, optional
        Evaluate at most this many patches per level (the most textured): bounds the cost.
    dense : bool
        Also assemble the ``(H, W, 2)`` field (:func:`dense_from_patches`).
    ransac_threshold : float
        RANSAC inlier distance at each coarse level, in that level's pixels.
    iterations : int
        Readouts at the finest level: each one after the first re-warps by the motion fitted to
        the one before, so the model reads residuals near zero, where it is most accurate
        (costs one more batched inference per extra iteration). The levels between the
        coarsest and ``finest`` read once; the coarsest reads ``coarse_iterations`` times.
    coarse_iterations : int
        Readouts at the coarsest level, each after re-warping by the fit of the one before
        (like ``iterations``); the levels between it and ``finest`` read once.
    finest : int
        Pyramid level of the final readout (0 = full resolution). On blurry footage the model
        reads motion better on a reduced image; results are still in full-resolution pixels
        (patch centres on a grid of ``stride`` there).
    refine_stride : int, optional
        Grid step (full-resolution pixels) of the finest level's readouts before the last one
        (``iterations > 1``), which only refine the pre-warp; default ``stride``. A coarser grid
        (e.g. ``2 * stride``: a quarter of the patches) is cheaper and fits the pre-warp about
        as well; the last readout always uses ``stride``.
    search : int
        Also start the coarsest level from shifts on a ``(2 search + 1)^2`` grid (steps of
        about the model's range at that level), for shaking cameras whose motion the previous
        frame does not predict; each start costs one readout of the coarsest level.
    search_below : float
        With a ``prior``, read the grid of ``search`` only when fewer than this fraction of the
        coarsest level's patches agree with the better of the prior and no motion (1 =
        always): a shake beyond the level's range leaves few in agreement, while on ordinary
        frames the grid's shifted starts only add chances for a wrong one to win. Without a
        prior (a first frame) the grid is always read: nothing says the camera is still.
    start_tolerance : float
        How the start is chosen among the candidates (each refined by one readout and fit).
        0: the one most of the coarsest level's patches agree with. Above 0: the one under
        which most of that level's textured pixels keep their gray value (in [0, 1]) to within
        this after warping (:func:`photometric_agreement`): patches that read "no motion"
        whatever the start (a sharp patch against its motion-blurred counterpart, horizontal
        streaks of a blurred pan) vote for every start alike there, so they no longer decide.
    start_model : str
        Motion model fitted to each start candidate's readout. A translation: the start only
        has to bring the coarsest level within the model's range, and that level's few
        patches (15 on a 320x240 frame) fit a similarity's zoom to their noise; the re-reads
        that follow fit ``coarse_model`` to readings near zero, where they are reliable.
    converged : float
        Stop re-reading the coarsest level (``coarse_iterations``) once a readout moved the
        fitted motion by less than this many of that level's pixels at its corners
        (:func:`_corner_shift`): the next re-read would start where this one ended and only
        refine a settled estimate. The start's readout counts, measured against the candidate
        it refined (a steady pan that the prior predicts settles there). 0 = always read
        ``coarse_iterations`` times.

    Returns
    -------
    FlowEstimate

    Raises
    ------
    InputError
        Frames of other dtypes, float frames outside [0, 1] or holding NaN or infinite values,
        frames of different sizes, or invalid options.

    Warns
    -----
    MotionRangeWarning
        With automatic ``levels``, when ``max_motion`` is beyond what the pyramid the frame size
        allows can read (the message gives that largest motion).
    """
    model, prior = _checked_options(frame1, frame2, model=model, prior=prior, stride=stride,
                                    levels=levels, max_motion=max_motion)
    fp1 = frame1 if isinstance(frame1, FramePyramid) else FramePyramid(frame1)
    fp2 = frame2 if isinstance(frame2, FramePyramid) else FramePyramid(frame2)
    g1 = fp1.images[0]
    if g1.shape != fp2.images[0].shape:
        raise InputError(f"frames differ in size: {g1.shape} and {fp2.images[0].shape}")
    # The first frame's grids, texture maps, patches and their projections, per level and
    # stride (see _level), all cut up front (or ahead of time, by prepare_first_frame): shared
    # by the start's readout, every later readout of a level, and later calls on the same
    # FramePyramid with the same settings.
    plan, pyr1, cache, p, rng = _first_frame_work(
        fp1, model=model, stride=stride, levels=levels, max_motion=max_motion,
        max_disp=max_disp, coarse_stride=coarse_stride, min_texture=min_texture,
        texture_scale=texture_scale, max_patches=max_patches, iterations=iterations,
        finest=finest, refine_stride=refine_stride, start_tolerance=start_tolerance)
    pyr2 = fp2.levels(plan.levels, p)
    reach = plan.pyramid.reach(search)
    if warn_range and levels is None and max_motion > reach:
        n, step = plan.levels, plan.pyramid.reach()
        hint = (f"pass search={search + 1} or more (each adds {step} px) or a prior near the "
                "motion" if n > 1 else "give larger frames")
        warnings.warn(f"max_motion={max_motion:g} px is out of reach on {g1.shape[1]}x"
                      f"{g1.shape[0]} frames: the {n} pyramid level{'s' * (n > 1)} their size "
                      f"allows read motions up to about {reach} px, larger ones are misread; "
                      f"{hint}", MotionRangeWarning, stacklevel=3)
    levels = plan.levels
    cstride, fine, fine_stride, pre_stride = (plan.coarse_stride, plan.fine, plan.fine_stride,
                                              plan.pre_stride)

    status = "ok"
    if (prior is not None or search > 0) and levels > 1:
        h_est, shift = _choose_start(
            pyr1[levels - 1], pyr2[levels - 1], levels - 1, prior, model=model, p=p,
            cstride=cstride, rng=rng, min_texture=min_texture, max_patches=max_patches,
            start_model=start_model, ransac_threshold=ransac_threshold, search=search,
            search_below=search_below, texture_scale=texture_scale,
            start_tolerance=start_tolerance, cache=cache)
        started = True  # the start's readout was the coarsest level's first
    else:
        h_est = np.eye(3) if prior is None else np.asarray(prior, np.float64)
        started, shift = False, np.inf
    # The coarsest level has settled once a readout barely moved its fit: skip its re-reads.
    settled = shift < converged
    coarse_iterations = max(1, int(coarse_iterations))
    # Every coarse level, and all but the last readout of the finest one, only serve to improve
    # the pre-warp; the last readout is the result.
    # The coarsest level starts from a guess and reads coarse_iterations times: a blurred or
    # large motion is under-read at first (e.g. 2.1 px for 4.3 px), and re-reading after each
    # re-warp converges where the model is most reliable. Finer levels then start close and
    # read once. A coarsest readout that barely moves the fit ends its re-reads (``converged``).
    reads = [(lvl, cstride) for lvl in range(levels - 1, 0, -1) if lvl > fine
             for _ in range(coarse_iterations - started if lvl == levels - 1 else 1)]
    reads += [(fine, pre_stride)] * (plan.iterations - 1)
    for lvl, step in reads:
        if settled and lvl == levels - 1:
            continue
        factor = 0.5**lvl
        h_lvl = _scaled(h_est, factor)
        est = _level(pyr1[lvl], pyr2[lvl], h_lvl, model, p, step, rng,
                     min_texture, max_patches, accept_edge=lvl > fine, cache=cache,
                     texture_scale=texture_scale)
        fitted = _fit_level(est, coarse_model, ransac_threshold, pyr1[lvl].shape)
        if fitted.ok:
            h_est = _scaled(fitted.matrix, 1.0 / factor)
            if lvl == levels - 1 and converged > 0:
                settled = _corner_shift(h_lvl, fitted.matrix, pyr1[lvl].shape) < converged
        elif status == "ok":
            status = f"level {lvl}: {fitted.reason}"

    factor = 0.5**fine
    est = _level(pyr1[fine], pyr2[fine], _scaled(h_est, factor), model, p, fine_stride, rng,
                 min_texture, max_patches, cache=cache, texture_scale=texture_scale)
    up = np.float32(2**fine)
    out = FlowEstimate(
        centres=est["centres"] * up, disp=est["disp"] * up, confidence=est["conf"],
        texture=est["texture"], valid=est["valid"], grid_shape=est["grid_shape"],
        stride=fine_stride * 2**fine, prewarp=h_est, residual=est["residual"] * up,
        levels=levels, coarse_status=status, beyond=est["beyond"],
    )
    if dense:
        out.dense = dense_from_patches(out, shape=g1.shape, patch_size=p)
    return out


def _checked_options(frame1: Any, frame2: Any, *, model: Any, prior: Optional[np.ndarray],
                     stride: int, levels: Optional[int], max_motion: float) -> tuple:
    """:func:`estimate_flow`'s ``(model, prior)``, a model name loaded and the prior as
    ``(3, 3) float64``; :class:`InputError` for what it cannot take. Frames given as arrays must
    be uint8 or float gray in [0, 1] (a float frame in 0-255 would pass every texture and
    contrast threshold)."""
    if isinstance(model, (str, os.PathLike)):
        from bgsub.model.rbm import load_model

        model = load_model(model)
    for frame in (frame1, frame2):
        if isinstance(frame, FramePyramid):
            continue
        frame = np.asarray(frame)
        if frame.dtype.kind == "f":
            if not np.isfinite(frame).all():
                # A NaN spreads through every patch and pyramid level it touches.
                raise InputError("frame contains NaN or infinite values; give gray values in "
                                 "[0, 1] everywhere (e.g. frame[~np.isfinite(frame)] = 0)")
            if frame.size and not 0.0 <= float(frame.min()) <= float(frame.max()) <= 1.0:
                raise InputError("float frames must be gray values in [0, 1]; give uint8 frames "
                                 "as they are, or divide by 255")
        elif frame.dtype != np.uint8:
            raise InputError(f"frames must be uint8 or float in [0, 1], not {frame.dtype}")
    if prior is not None:
        prior = np.asarray(prior, np.float64)
        if prior.shape != (3, 3) or not np.isfinite(prior).all():
            raise InputError(f"prior must be a finite (3, 3) homography, not shape {prior.shape}")
    if not (isinstance(stride, (int, np.integer)) and stride >= 1):
        raise InputError(f"stride must be an integer of at least 1, not {stride!r}")
    if levels is not None and not (isinstance(levels, (int, np.integer)) and levels >= 1):
        raise InputError(f"levels must be at least 1 (or None: automatic), not {levels!r}")
    if not (np.isfinite(max_motion) and max_motion > 0):
        raise InputError(f"max_motion must be a positive number of pixels, not {max_motion!r}")
    return model, prior


def _choose_start(g1: np.ndarray, g2: np.ndarray, lvl: int, prior: Optional[np.ndarray], *,
                  model: Any, p: int, cstride: int, rng: int, min_texture: float,
                  max_patches: Optional[int], start_model: str, ransac_threshold: float,
                  search: int, search_below: float, texture_scale: float,
                  start_tolerance: float, cache: dict) -> Tuple[np.ndarray, float]:
    """The coarsest level's start: ``(h_est, shift)``, the full-resolution ``(3, 3)`` motion
    of the best candidate after one readout and fit, and how far that readout moved it (in
    level ``lvl``'s pixels at the corners; see ``converged``).

    Several hypotheses: the prior (a steady pan continues) and no motion (a shaking camera
    reverses); the level keeps the best of them after one readout each: the one most patches
    agree with, or (``start_tolerance``) the one under which most textured pixels keep their
    gray value. A shake beyond the level's range defeats both: then (when fewer than
    ``search_below`` of the patches agree, or with no prior to go by) a grid of shifts
    ``search`` steps of about the model's range on each side is read too. (A first frame of a
    fast pan whose tracked subject reads as "no motion" would otherwise set a wrong prior for
    the next.)
    """
    factor = 0.5**lvl
    step = max(1.0, rng - 1.0) / factor
    h_est = np.eye(3) if prior is None else np.asarray(prior, np.float64)
    rest = (factor, model, p, cstride, rng, min_texture, max_patches, start_model,
            ransac_threshold)
    options = dict(texture_scale=texture_scale, tolerance=start_tolerance, cache=cache)
    basic = [np.eye(3)] + ([h_est] if prior is not None else [])
    grid = [np.array([[1.0, 0, i * step], [0, 1.0, j * step], [0, 0, 1]])
            for i in range(-search, search + 1) for j in range(-search, search + 1)
            if i or j]
    if grid and (search_below >= 1.0 or prior is None):
        basic, grid = basic + grid, []  # read anyway: one batched readout of all of them
    h_est, support, score, shift = _best_start(g1, g2, basic, *rest, h_est, **options)
    if grid and support < search_below:
        h_grid, _, grid_score, grid_shift = _best_start(g1, g2, grid, *rest, h_est, **options)
        if grid_score > score:
            h_est, shift = h_grid, grid_shift
    return h_est, shift


def _level(g1, g2, h_est, model, p, stride, rng, min_texture, max_patches, *,
           accept_edge: bool = False, cache: Optional[dict] = None, read: bool = True,
           texture_scale: float = TEXTURE_SCALE) -> dict:
    """Patch motion at one level after pre-warping ``g2`` by ``h_est`` (that level's pixels).

    ``accept_edge``: keep readings at the edge of the model's range (a larger motion, clipped).
    They still point the right way, which is all a pre-warp needs; the final level drops them.
    ``cache``: a dict kept across calls on the same ``g1`` and ``stride`` (the first frame's
    grid, texture and patches do not change between iterations).
    """
    key = (g1.shape, stride)
    if cache is not None and key in cache:
        centres, grid_shape, tex, pick, x_pick = cache[key]
        cache["pick"], cache["x"] = pick, x_pick
    else:
        centres, grid_shape = _grid(g1.shape, p, stride)
        n = len(centres)
        tex = np.zeros(n, np.float32)
        if n:
            # The texture map of a level serves every grid cut from it (kept in cache).
            tkey = ("texture", g1.shape)
            tmap = cache.get(tkey) if cache is not None else None
            if tmap is None:
                tmap = _texture_map(g1, p)
                if cache is not None:
                    cache[tkey] = tmap
            ci = centres.astype(np.intp)  # centres are integers for odd p
            tex = _texture_weights(tmap[ci[:, 1], ci[:, 0]], centres, g1.shape,
                                   texture_scale=texture_scale)
        pick = np.flatnonzero(tex >= min_texture)
        if max_patches is not None and len(pick) > max_patches:
            pick = pick[np.argsort(-tex[pick], kind="stable")[:max_patches]]
            pick.sort()
        x_pick = _patches_at(g1, centres[pick], p, stride=stride if len(pick) == n else 0)
        if cache is not None:
            cache[key] = (centres, grid_shape, tex, pick, x_pick)
            cache["pick"], cache["x"] = pick, x_pick
    n = len(centres)
    residual = np.zeros((n, 2), np.float32)
    conf = np.zeros(n, np.float32)
    valid = np.zeros(n, bool)
    beyond = np.zeros(n, bool)
    if len(pick) and read:
        warped = g2 if is_identity(h_est) else _warp_back(g2, h_est)
        y_pick = _patches_at(warped, centres[pick], p, stride=stride if len(pick) == n else 0)
        xf = _x_features(model, x_pick, cache, key)
        d, c, flat = patch_motion(model, x_pick, y_pick, max_disp=rng, x_features=xf)
        residual[pick] = d
        conf[pick] = c
        # A reading at the edge of the range may be a larger motion clipped: not trusted.
        inside = np.max(np.abs(d), axis=1) < rng - 0.25
        valid[pick] = ~flat & (inside | accept_edge)
        beyond[pick] = ~flat & ~inside
    # Correspondence: x -> H (x + r), because warped(x + r) = g2(H (x + r)) ~ g1(x).
    dst = apply_homography(h_est, centres + residual).astype(np.float32)
    disp = dst - centres
    return dict(centres=centres, grid_shape=grid_shape, disp=disp, residual=residual,
                conf=conf, texture=tex, valid=valid, beyond=beyond)


def _best_start(g1, g2, cands, factor, model, p, stride, rng, min_texture, max_patches,
                fit_model, threshold, fallback, *, texture_scale: float = TEXTURE_SCALE,
                tolerance: float = 0.0, cache: Optional[dict] = None
                ) -> Tuple[np.ndarray, float, float, float]:
    """The best candidate start (full-resolution homographies) after refinement, all of them
    read in ONE batched inference: ``(motion, support, score, shift)``. Each candidate is
    refined by a ``fit_model`` motion fitted to its readout. ``support`` is the
    fraction of the level's evaluated patches that agree with the chosen motion (0 when none
    does); ``score``, what chose it: the support, or with ``tolerance > 0`` the
    :func:`photometric_agreement` of the level's images under it (-1 when no fit succeeded);
    ``shift``, how far the refinement moved the chosen candidate (:func:`_corner_shift`, this
    level's pixels; inf when no fit succeeded).

    ``cache``: :func:`_level`'s cache for ``g1``, so the level's later readouts reuse the
    first frame's grid, texture, patches and projections cut here (a fresh one if omitted)."""
    if cache is None:
        cache = {}
    est0 = _level(g1, g1, np.eye(3), None, p, stride, rng, min_texture, max_patches,
                  cache=cache, read=False, texture_scale=texture_scale)
    centres, tex, pick, x_pick = est0["centres"], est0["texture"], cache["pick"], cache["x"]
    if len(pick) == 0:
        return fallback, 0.0, -1.0, np.inf
    scaled = [_scaled(c, factor) for c in cands]
    ys = [_patches_at(_warp_back(g2, h) if not is_identity(h) else g2,
                      centres[pick], p) for h in scaled]
    xf = _x_features(model, x_pick, cache, (g1.shape, stride))
    if xf is not None:
        xf = xf.take(np.tile(np.arange(len(pick)), len(cands)))
    d, c, flat = patch_motion(model, np.tile(x_pick, (len(cands), 1)), np.concatenate(ys),
                              max_disp=rng, x_features=xf)
    best = (fallback, 0.0, -1.0, np.inf)
    textured = None
    if tolerance > 0:
        # Cached: a frame that reads the grid of starts scores two batches on the same level.
        textured = cache.get(("textured", g1.shape))
        if textured is None:
            textured = cache[("textured", g1.shape)] = _textured_pixels(g1)
    n, k = len(centres), len(pick)
    for i, h in enumerate(scaled):
        residual = np.zeros((n, 2), np.float32)
        conf = np.zeros(n, np.float32)
        valid = np.zeros(n, bool)
        sl = slice(i * k, (i + 1) * k)
        # Readings at the edge of the range are a larger motion clipped: a wrong start reads
        # them everywhere, consistently, so they must not count as support for it.
        inside = np.max(np.abs(d[sl]), axis=1) < rng - 0.25
        residual[pick], conf[pick], valid[pick] = d[sl], c[sl], ~flat[sl] & inside
        dst = apply_homography(h, centres + residual).astype(np.float32)
        est = dict(centres=centres, disp=dst - centres, conf=conf, texture=tex, valid=valid)
        fitted = _fit_level(est, fit_model, threshold, g1.shape)
        if not fitted.ok:
            continue
        support = fitted.n_inliers / k
        score = support if textured is None else photometric_agreement(
            g1, g2, fitted.matrix, tolerance=tolerance, textured=textured)
        if score > best[2]:
            best = (_scaled(fitted.matrix, 1.0 / factor), support, score,
                    _corner_shift(h, fitted.matrix, g1.shape))
    return best


def _corner_shift(h_a: np.ndarray, h_b: np.ndarray, shape: tuple) -> float:
    """How far apart two motions put an image's corners: the largest distance (pixels) over
    the four corners of an image of ``shape`` ``(H, W, ...)``, for ``(3, 3)`` homographies in
    its pixels. The corners bound the difference anywhere inside for affine motions (and
    nearly so for the mild homographies between frames)."""
    return float(np.max(corner_distances(h_a, h_b, width=shape[1], height=shape[0])))


def _textured_pixels(gray: np.ndarray) -> np.ndarray:
    """``(H, W) bool``: pixels with any gradient (|dx| + |dy| above about 0.0025 per pixel on
    gray values in [0, 1]); flat pixels agree under every motion and would only dilute the
    photometric check."""
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1)
    return (np.abs(gx) + np.abs(gy)) > np.float32(0.02)  # Sobel is 8x the per-pixel slope


def photometric_agreement(g1: np.ndarray, g2: np.ndarray, matrix: np.ndarray, *,
                          tolerance: float, textured: Optional[np.ndarray] = None) -> float:
    """Fraction of ``g1``'s textured pixels whose gray value ``g2`` repeats, to within
    ``tolerance``, at the place ``matrix`` maps them to.

    Parameters
    ----------
    g1, g2 : (H, W) float32 gray in [0, 1]
    matrix : (3, 3) float64
        Motion from ``g1`` to ``g2`` in these images' pixels.
    tolerance : float
        Largest gray-value difference that agrees.
    textured : (H, W) bool, optional
        :func:`_textured_pixels` of ``g1``, when already computed.

    Returns
    -------
    float
        In [0, 1]; pixels mapped outside ``g2`` count as disagreeing, so a motion that leaves
        most of the frame is not preferred for the little it explains.
    """
    if textured is None:
        textured = _textured_pixels(g1)
    n = int(np.count_nonzero(textured))
    if n == 0:
        return 0.0
    h, w = g1.shape
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    # -1 marks pixels mapped outside g2 (gray values are >= 0): they never agree.
    warped = cv2.warpPerspective(g2, np.asarray(matrix, np.float64), (w, h), flags=flags,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    agree = np.abs(warped - g1) <= np.float32(tolerance)
    return float(np.count_nonzero(agree & textured)) / n


def _subgrid(cache: dict, shape: tuple, p: int, stride: int, sub_stride: int,
             min_texture: float, model: Any) -> None:
    """Fill ``cache`` for the ``sub_stride`` grid from the cached ``stride`` grid it is a subset
    of (same origin; ``sub_stride`` a multiple of ``stride``), without recomputing anything."""
    centres, (rows, cols), tex, pick, x_pick = cache[(shape, stride)]
    xf = _x_features(model, x_pick, cache, (shape, stride))
    k = sub_stride // stride
    sub = (np.arange(0, rows, k)[:, None] * cols + np.arange(0, cols, k)[None, :]).ravel()
    sub_centres, sub_shape = _grid(shape, p, sub_stride)
    sub_tex = tex[sub]
    sub_pick = np.flatnonzero(sub_tex >= min_texture)
    pos = np.searchsorted(pick, sub[sub_pick])  # every subset pick is a pick of the full grid
    cache[(shape, sub_stride)] = (sub_centres, sub_shape, sub_tex, sub_pick, x_pick[pos])
    if xf is not None:
        cache[("xf", (shape, sub_stride))] = xf.take(pos)


def _x_features(model: Any, x_pick: np.ndarray, cache: Optional[dict], key: Any) -> Any:
    """The first frame's patches projected onto a GatedRBM's filters, computed once per level
    and kept in ``cache`` (every readout of a level pairs the same first-frame patches with a
    differently pre-warped second frame). None for other patch-motion models."""
    if hasattr(model, "patch_motion") or len(x_pick) == 0:
        return None
    from bgsub.model.readout import patch_features

    if cache is not None and ("xf", key) in cache:
        return cache[("xf", key)]
    xf = patch_features(model, x_pick, side="x")
    if cache is not None:
        cache[("xf", key)] = xf
    return xf


#: Patches with less than this fraction of the level's largest structure-tensor eigenvalue are
#: at the noise level when the stronger ones lie in one compact region (``_COMPACT``): see
#: :func:`_texture_weights`. (OpenCV's corner detector, the `compensated` engine's front end,
#: keeps corners of at least 1 % of the best one's quality.)
WEAK_TEXTURE = 0.003
_COMPACT = 1.0 / 3.0


def _texture_weights(e: np.ndarray, centres: np.ndarray, shape: tuple, *,
                     texture_scale: float) -> np.ndarray:
    """Texture weights ``e / (e + texture_scale)`` of patches with smaller structure-tensor
    eigenvalues ``e`` ((N,) float32) centred at ``centres`` ((N, 2) ``(x, y)``) in a level of
    ``shape`` (H, W); ``(N,) float32`` in [0, 1).

    When every patch with at least ``WEAK_TEXTURE`` of the largest ``e`` lies within a third of
    the level's width and of its height (one textured object over a flat, noisy background),
    the others get weight 0: their "texture" is sensor noise, which reads as random motions
    that RANSAC can fit (a still camera over a noisy gray ramp was fitted motions of up to 13
    px). The object's own motion is then the only one measured, and the engines take it for an
    object's (``min_extent``). On the real set this never changes a mask (measured, issue 4).
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


def _texture_map(gray: np.ndarray, p: int) -> np.ndarray:
    """:func:`bgsub.model.tiling.texture_map` (window ``p``) wherever a ``p x p`` box fits inside the
    image, i.e. at every patch centre, in one OpenCV call: ``cornerMinEigenVal`` computes the
    same smaller structure-tensor eigenvalue from Sobel gradients scaled by ``1 / (4 p)`` and
    box *sums*, which is 4 times ``texture_map``'s (gradients / 8, box means). (Near the border
    the two differ: ``texture_map`` reflects the box, this reflects with 101.)"""
    gray = np.asarray(gray, dtype=np.float32)
    tmap = cv2.cornerMinEigenVal(gray, p, ksize=3)
    tmap *= np.float32(0.25)
    return np.maximum(tmap, 0.0, out=tmap)


_GRIDS: dict = {}


def _grid(shape: tuple, p: int, stride: int) -> tuple:
    """:func:`bgsub.model.tiling.patch_grid`, memoised (the same few grids every frame); the centres
    are read-only."""
    key = (int(shape[0]), int(shape[1]), int(p), int(stride))
    if key not in _GRIDS:
        if len(_GRIDS) > 64:
            _GRIDS.clear()
        centres, grid_shape = patch_grid(shape, patch_size=p, stride=stride)
        centres.setflags(write=False)
        _GRIDS[key] = (centres, grid_shape)
    return _GRIDS[key]


def _patches_at(image: np.ndarray, centres: np.ndarray, p: int, *, stride: int = 0) -> np.ndarray:
    """The ``p x p`` patches centred at integer ``centres``: ``(n, p*p) float32`` (one gather
    from a strided view, no loop). ``stride > 0`` says ``centres`` is the whole
    :func:`~bgsub.model.tiling.patch_grid` of ``image`` with that stride: one strided slice then."""
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


def _fit_level(est: dict, model: str, threshold: float, shape: tuple) -> GlobalMotion:
    w = np.where(est["valid"], est["conf"] * est["texture"], 0.0)
    n_valid = int(np.count_nonzero(w > 0))
    # Few patches at a coarse level: fall back to fewer degrees of freedom.
    if n_valid < 40 and model in ("homography", "affine"):
        model = "similarity"
    if n_valid < 12:
        model = "translation"
    return fit_global_motion(est["centres"], est["centres"] + est["disp"], weights=w, model=model,
                             threshold=threshold, min_points=6,
                             frame_size=(shape[1], shape[0]))


def dense_from_patches(
    flow: FlowEstimate, *, shape: tuple, patch_size: int = 13, min_weight: float = 1e-3
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


def _fill_from_covering_patches(out: np.ndarray, flow: FlowEstimate, ok: np.ndarray,
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
