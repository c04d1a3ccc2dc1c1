"""Patch motion between two frames, read by the gated RBM coarse to fine: :func:`estimate_flow`.

The steps (each a module of this package):

1. both frames' image pyramids (:mod:`~bgsub.motion.pyramid`), enough levels that the largest
   motion planned for is within the model's range at the coarsest;
2. the first frame's patches cut on a grid of each level, weighed by their texture and
   projected onto the model's filters once (:mod:`~bgsub.motion.patches`; kept in its
   :class:`FramePyramid`, or done ahead by :func:`prepare_first_frame`);
3. the coarsest level's start chosen among the prior, no motion and a grid of shifts
   (:mod:`~bgsub.motion.starts`);
4. each coarser level read on the second frame pre-warped by the motion so far, and the camera
   motion fitted to it (RANSAC, :mod:`bgsub.motion.global_motion`) pre-warps the next finer
   level, so the model only ever sees the *residual* motion, within its range for everything
   that moves with the camera;
5. the finest level's readout is the result (:class:`FlowEstimate`), optionally with the dense
   per-pixel field (:mod:`~bgsub.motion.dense`).

Each readout is one batched inference over all (textured) patches of a level.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Any, List, Optional, Tuple

import numpy as np

from bgsub.errors import InputError
from bgsub.motion.config import FlowConfig
from bgsub.motion.dense import dense_from_patches
from bgsub.motion.patches import LevelReading, PatchGrids, patch_motion, read_level, reads_raw
from bgsub.motion.pyramid import (FramePyramid, MotionRangeWarning, PyramidReach, auto_levels,
                                  model_range, motion_reach, pyramid_reach, scale_homography)
from bgsub.motion.starts import StartSearch, choose_start, corner_shift

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
        Texture weight in [0, 1) (:func:`bgsub.motion.patches.texture_weights`).
    valid : (N,) bool
        Patch evaluated (not flat, enough texture) and its residual inside the model's range.
    grid_shape : (rows, cols)
    stride : int
        Grid step at full resolution.
    prewarp : (3, 3) float64
        The camera motion used to pre-warp the finest level (identity when ``levels == 1`` and no
        ``prior``).
    residual : (N, 2) float32
        The model's own reading at the finest level (``disp`` minus the pre-warp's motion).
    dense : (H, W, 2) float32 or None
        Per-pixel flow (NaN unknown) when asked for (``FlowConfig.dense``).
    levels : int
        Pyramid levels used.
    coarse_status : str
        ``"ok"`` or why a coarse level's fit was refused (its pre-warp then kept the prior).
    beyond : (N,) bool or None
        Patch evaluated but its residual at the edge of the model's range: it moves more than
        the model can see relative to the pre-warp (after a good pre-warp, a moving object).
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


@dataclass(frozen=True)
class _Plan:
    """Which pyramid levels and grids are read (strides in each level's own pixels).

    ``fine``: the level of the final readout; ``fine_stride`` its grid; ``pre_stride`` the grid
    of the finest level's readouts before the last; ``coarse_stride`` that of the coarser
    levels."""

    pyramid: PyramidReach
    fine: int
    coarse_stride: int
    fine_stride: int
    pre_stride: int

    @property
    def levels(self) -> int:
        """Pyramid levels read (those of :attr:`pyramid`)."""
        return self.pyramid.levels


def _plan(shape: tuple, config: FlowConfig, *, patch_size: int, max_disp: int) -> _Plan:
    """The :class:`_Plan` of frames of ``shape`` (H, W) read as ``config`` says."""
    pyramid = pyramid_reach(shape, max_motion=config.max_motion, model_disp=max_disp,
                            patch_size=patch_size, levels=config.levels or None)
    fine = min(config.finest, pyramid.levels - 1)
    stride = config.stride
    fine_stride = stride if fine == 0 else max(4, int(round(stride / 2**fine)))
    pre_stride = fine_stride
    if config.refine_stride:
        pre_stride = max(4, int(round(config.refine_stride / 2**fine)))
    return _Plan(pyramid=pyramid, fine=fine, coarse_stride=max(4, config.coarse_stride or stride),
                 fine_stride=fine_stride, pre_stride=pre_stride)


class _Reader:
    """One coarse-to-fine reading from a first frame: its plan, pyramid and cut patches, and
    the steps of :func:`estimate_flow` that use them."""

    def __init__(self, first: FramePyramid, config: FlowConfig, model: Any) -> None:
        self.config, self.model = config, model
        self.patch_size = p = int(model.patch_size)
        self.max_disp = config.max_disp or model_range(model)
        self.plan = _plan(first.shape, config, patch_size=p, max_disp=self.max_disp)
        self.pyr1 = first.levels(self.plan.levels, p)
        max_patches = config.max_patches or None
        settings = (self.max_disp, p, config.min_texture, max_patches, config.texture_scale)
        self.grids: PatchGrids = first.cache(model, settings, lambda: PatchGrids(
            model, min_texture=config.min_texture, max_patches=max_patches,
            texture_scale=config.texture_scale))
        self.pyr2: List[np.ndarray] = []
        self._cut_first_frame()

    def _cut_first_frame(self) -> None:
        """Cut (and project) the first frame's patches of every grid the plan reads; what is
        cut already is kept."""
        plan, pyr1, grids = self.plan, self.pyr1, self.grids
        for lvl in range(plan.levels - 1, plan.fine, -1):
            grids.grid(pyr1[lvl], plan.coarse_stride)
        if self.config.start_tolerance > 0 and plan.levels > 1:
            grids.textured(pyr1[plan.levels - 1])
        grids.grid(pyr1[plan.fine], plan.fine_stride)
        fine_shape = pyr1[plan.fine].shape
        if (self.config.iterations > 1 and plan.pre_stride != plan.fine_stride
                and not grids.has(fine_shape, plan.pre_stride)):
            if (plan.pre_stride % plan.fine_stride == 0 and grids.max_patches is None
                    and not reads_raw(self.model)):
                # The refining grid is every (pre_stride / fine_stride)-th patch of the final
                # grid: take that subset of the final grid's patches and projections.
                grids.add_subgrid(fine_shape, plan.fine_stride, plan.pre_stride)
            else:
                grids.grid(pyr1[plan.fine], plan.pre_stride)

    def pair_with(self, second: FramePyramid) -> None:
        """Read against ``second`` (a pyramid of the first frame's size): build the levels the
        plan reads."""
        self.pyr2 = second.levels(self.plan.levels, self.patch_size)

    def read(self, lvl: int, stride: int, h_est: np.ndarray) -> LevelReading:
        """Level ``lvl``'s readout on the grid of ``stride``, the second frame pre-warped by
        the full-resolution motion ``h_est``; a coarser level than the final one keeps
        readings at the edge of the range, and so does a single level that expects no motion
        beyond the range (an edge reading is then that motion, not a larger one clipped: a
        random-dot model's range is 1 px)."""
        h_lvl = scale_homography(h_est, 0.5**lvl)
        within = self.plan.levels == 1 and self.config.max_motion <= self.max_disp
        return read_level(self.grids.grid(self.pyr1[lvl], stride), self.pyr2[lvl], h_lvl,
                          model=self.model, max_disp=self.max_disp,
                          accept_edge=lvl > self.plan.fine or within)

    def start(self, prior: Optional[np.ndarray]) -> Tuple[np.ndarray, bool, float]:
        """The coarsest level's start: ``(motion, read, shift)``, the full-resolution motion,
        whether choosing it read the level (its readout then counts as the level's first) and
        how far that readout moved it (that level's pixels; inf when not read)."""
        config, top = self.config, self.plan.levels - 1
        if (prior is None and config.search == 0) or top == 0:
            return (np.eye(3) if prior is None else prior), False, np.inf
        search = StartSearch(g1=self.pyr1[top], g2=self.pyr2[top], level=top, grids=self.grids,
                             stride=self.plan.coarse_stride, model=self.model,
                             max_disp=self.max_disp, fit_model=config.start_model,
                             threshold=config.ransac_threshold,
                             tolerance=config.start_tolerance)
        start = choose_start(search, prior, steps=config.search,
                             search_below=config.search_below)
        return start.motion, True, start.shift

    def refine(self, h_est: np.ndarray, *, started: bool, shift: float) -> Tuple[np.ndarray, str]:
        """The pre-warp of the final readout: ``h_est`` refined by every coarse readout and all
        but the last of the finest level's; and ``"ok"`` or why the first refused fit was."""
        plan, config, top = self.plan, self.config, self.plan.levels - 1
        status = "ok"
        # The coarsest level has settled once a readout barely moved its fit: skip its re-reads.
        settled = shift < config.converged
        for lvl, stride in _pre_reads(plan, config, started=started):
            if settled and lvl == top:
                continue
            reading = self.read(lvl, stride, h_est)
            shape = self.pyr1[lvl].shape
            fitted = reading.fit(config.coarse_model, threshold=config.ransac_threshold,
                                 shape=shape)
            if fitted.ok:
                if lvl == top and config.converged > 0:
                    h_lvl = scale_homography(h_est, 0.5**lvl)
                    settled = corner_shift(h_lvl, fitted.matrix, shape) < config.converged
                h_est = scale_homography(fitted.matrix, 2.0**lvl)
            elif status == "ok":
                status = f"level {lvl}: {fitted.reason}"
        return h_est, status

    def result(self, h_est: np.ndarray, status: str) -> FlowEstimate:
        """The final readout, pre-warped by ``h_est``, in full-resolution pixels."""
        fine = self.plan.fine
        reading = self.read(fine, self.plan.fine_stride, h_est)
        up = np.float32(2**fine)
        out = FlowEstimate(
            centres=reading.centres * up, disp=reading.disp * up, confidence=reading.conf,
            texture=reading.texture, valid=reading.valid, grid_shape=reading.grid_shape,
            stride=self.plan.fine_stride * 2**fine, prewarp=h_est,
            residual=reading.residual * up, levels=self.plan.levels, coarse_status=status,
            beyond=reading.beyond,
        )
        if self.config.dense:
            out.dense = dense_from_patches(out, shape=self.pyr1[0].shape,
                                           patch_size=self.patch_size)
        return out


def _pre_reads(plan: _Plan, config: FlowConfig, *, started: bool) -> List[Tuple[int, int]]:
    """The readouts ``(level, stride)`` that only improve the pre-warp, coarsest first.

    The coarsest level reads ``coarse_iterations`` times (one less when choosing the start read
    it already): a blurred or large motion is under-read at first, and re-reading after each
    re-warp converges where the model is most reliable. The levels between it and the final
    one then start close and read once; the final level reads ``iterations - 1`` times on the
    ``pre_stride`` grid before its last readout."""
    top = plan.levels - 1
    reads = [(lvl, plan.coarse_stride) for lvl in range(top, 0, -1) if lvl > plan.fine
             for _ in range(config.coarse_iterations - started if lvl == top else 1)]
    return reads + [(plan.fine, plan.pre_stride)] * (config.iterations - 1)


def prepare_first_frame(pyramid: FramePyramid, config: FlowConfig = FlowConfig(), *,
                        model: Any) -> None:
    """Do ahead of time the work :func:`estimate_flow` with the same ``config`` and ``model``
    does on ``pyramid`` as the *first* frame of a pair: build its levels; cut, texture-weigh
    and project its patches.

    The work is kept in ``pyramid`` and changes nothing in what :func:`estimate_flow` returns,
    only how long it takes. Safe to run in a second thread while ``pyramid`` is the *second*
    frame of another :func:`estimate_flow` call.
    """
    _Reader(pyramid, _checked_config(config), model)


def estimate_flow(frame1: Any, frame2: Any, config: FlowConfig = FlowConfig(), *, model: Any,
                  prior: Optional[np.ndarray] = None) -> FlowEstimate:
    """Patch displacements between two frames, coarse to fine.

    Parameters
    ----------
    frame1, frame2 : (H, W, 3) BGR or (H, W) gray uint8, (H, W) float32 gray in [0, 1], or
        FramePyramid (reused: a video's frame serves as ``frame2`` of one call and ``frame1`` of
        the next, and what is cut from a ``frame1`` is kept in it)
    config : FlowConfig
        How to read (grid, pyramid, starts, re-reads); its fields say what each setting does.
    model : bgsub.model.rbm.GatedRBM, a shipped model name or an .npz path
        The patch-motion model (``patch_size`` fixes the patch side).
    prior : (3, 3) float64, optional
        A guess of the camera motion (e.g. the previous frame's). With more than one level, the
        coarsest level is read pre-warped by the prior and by the identity (one batch), and the
        better start is kept (``config.start_tolerance``, ``config.start_model``).

    Returns
    -------
    FlowEstimate

    Raises
    ------
    InputError
        Frames of other dtypes, float frames outside [0, 1] or holding NaN or infinite values,
        frames of different sizes, a prior that is not a finite (3, 3) matrix.

    Warns
    -----
    MotionRangeWarning
        With automatic ``levels`` and ``warn_range``, when ``max_motion`` is beyond what the
        pyramid the frame size allows can read (the message gives that largest motion). A
        320x240 frame allows 3 levels, which read up to about 12 px per axis with a model of
        range 4 (24 px with ``search=1``).
    """
    config, model, prior = _checked_config(config), _loaded(model), _checked_prior(prior)
    for frame in (frame1, frame2):
        _check_frame(frame)
    first, second = (f if isinstance(f, FramePyramid) else FramePyramid(f)
                     for f in (frame1, frame2))
    if first.shape != second.shape:
        raise InputError(f"frames differ in size: {first.shape} and {second.shape}")
    reader = _Reader(first, config, model)
    reader.pair_with(second)
    _warn_if_out_of_reach(config, reader.plan, first.shape)
    h_est, started, shift = reader.start(prior)
    h_est, status = reader.refine(h_est, started=started, shift=shift)
    return reader.result(h_est, status)


def _warn_if_out_of_reach(config: FlowConfig, plan: _Plan, shape: tuple) -> None:
    """:class:`MotionRangeWarning` (at the caller of :func:`estimate_flow`) when the automatic
    pyramid of frames of ``shape`` (H, W) cannot read ``config.max_motion``."""
    reach = plan.pyramid.reach(config.search)
    if not config.warn_range or config.levels or config.max_motion <= reach:
        return
    n, step = plan.levels, plan.pyramid.reach()
    hint = (f"pass search={config.search + 1} or more (each adds {step} px) or a prior near "
            "the motion" if n > 1 else "give larger frames")
    warnings.warn(f"max_motion={config.max_motion:g} px is out of reach on {shape[1]}x"
                  f"{shape[0]} frames: the {n} pyramid level{'s' * (n > 1)} their size "
                  f"allows read motions up to about {reach} px, larger ones are misread; "
                  f"{hint}", MotionRangeWarning, stacklevel=3)


def _checked_config(config: Any) -> FlowConfig:
    if not isinstance(config, FlowConfig):
        raise InputError(f"config must be a FlowConfig, not {type(config).__name__}")
    return config


def _loaded(model: Any) -> Any:
    """``model``, loaded when it is a shipped model name or a file path."""
    if isinstance(model, (str, os.PathLike)):
        from bgsub.model.rbm import load_model

        return load_model(model)
    return model


def _checked_prior(prior: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """``prior`` as ``(3, 3) float64`` (or None); :class:`InputError` if it is not one."""
    if prior is None:
        return None
    prior = np.asarray(prior, np.float64)
    if prior.shape != (3, 3) or not np.isfinite(prior).all():
        raise InputError(f"prior must be a finite (3, 3) homography, not shape {prior.shape}")
    return prior


def _check_frame(frame: Any) -> None:
    """:class:`InputError` unless ``frame`` is a FramePyramid, uint8, or float gray in [0, 1]
    (a float frame in 0-255 would pass every texture and contrast threshold)."""
    if isinstance(frame, FramePyramid):
        return
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
