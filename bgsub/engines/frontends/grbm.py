"""The gated RBM's motion front end (the ``grbm`` engine, the paper's method): patch
displacements read off the factored 3-way RBM coarse to fine
(:func:`bgsub.motion.flowfield.estimate_flow`), re-read coarser where the final level is poorly
supported (motion blur); by default only the finest level, pre-warped by the previous frame's
motion, while that reads well (:class:`RetryWait`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Dict, NamedTuple, Optional

import numpy as np

from bgsub.camera.near_layer import NearLayer
from bgsub.engines.base import Param
from bgsub.engines.frontend import CameraFit, MotionFrontEnd, MotionResult
from bgsub.errors import InputError
from bgsub.io.flowio import flow_to_color
from bgsub.motion.config import FlowConfig
from bgsub.motion.flowfield import (FlowEstimate, FramePyramid, dense_from_patches,
                                    estimate_flow, prepare_first_frame)
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.patches import reads_raw
from bgsub.motion.refine import MIN_REFINE_WINDOW, refine_vectors
from bgsub.settings import check_settings, config_params, setting

__all__ = ["GrbmConfig", "GrbmFrontEnd", "FLOW_PARAMS", "Reading", "RetryWait"]

#: The :class:`FlowConfig` settings that are parameters of the ``grbm`` engine.
FLOW_PARAMS = ("stride", "levels", "max_motion", "min_texture", "max_patches", "iterations",
               "finest", "refine_stride", "coarse_iterations", "converged", "texture_scale",
               "search", "search_below", "start_tolerance", "start_model")


@dataclass(frozen=True)
class GrbmConfig:
    """The gated-RBM front end's own settings (the readout's are a :class:`FlowConfig`)."""

    model: str = setting("natural", "gated RBM: a shipped model name or an .npz path (from "
                                    "Python also a GatedRBM, or any object with its "
                                    "patch_motion contract)")
    contrast_floor: float = setting(0.005, "patch pairs with a lower RMS contrast (gray in "
                                           "[0, 1]) are flat and not read (0 = the model's "
                                           "own, 0.02 for the shipped models)", low=0)
    coarser_below: float = setting(0.5, "when fewer than this fraction of the final readout's "
                                        "patches agree with the fitted motion (motion blur), "
                                        "also read up to two levels coarser and keep the "
                                        "best-supported (0 = never)", low=0)
    coarser_stride: int = setting(16, "patch grid step (working-size pixels) of those coarser "
                                      "readouts (0 = stride): 2 x stride is as dense in a "
                                      "half-size image as stride in the full one", low=0)
    prior_levels: int = setting(1, "pyramid levels read from the final one up, pre-warped "
                                    "by the previous frame's motion, before the full pyramid "
                                    "(0 = always the full pyramid)", low=0)
    refine_window: int = setting(13, "side (working-size px) of the window in which each "
                                     "vector is refined to sub-pixel precision by Lucas-Kanade "
                                     "iterations before the camera fit (the patch size; 0 = "
                                     "the gated RBM's vectors as read)", low=0, high=63)
    refine_within: float = setting(1.5, "a refined vector that moved this many px or more "
                                        "from the gated RBM's reading keeps the reading",
                                   above=0)
    retry_below: float = setting(0.6, "with prior_levels > 0: when fewer than this fraction of "
                                      "the patches agree with the motion read on the reduced "
                                      "pyramid, the frame is read with the full one",
                                 low=0)
    retry_wait: int = setting(32, "after a reduced readout fails, the next 1, 2, 4, ... (at "
                                  "most this many) frames are read with the full pyramid "
                                  "only (0 = try the reduced pyramid every frame)", low=0)

    def __post_init__(self) -> None:
        check_settings(self)
        if 0 < self.refine_window < MIN_REFINE_WINDOW:
            raise InputError(f"parameter 'refine_window' must be 0 (no refinement) or at least "
                             f"{MIN_REFINE_WINDOW}, not {self.refine_window!r}")


class RetryWait:
    """When to try the reduced pyramid: every frame while its readouts are accepted; after a
    refusal, not for the next 1, 2, 4, ... frames (at most ``longest``). Footage the finest
    level cannot read alone (blur, a shaking camera, water) then costs a probe every
    ``longest`` frames instead of a wasted readout every frame."""

    def __init__(self, longest: int) -> None:
        self.longest = int(longest)
        self._wait = 0  # frames still to read with the full pyramid
        self._next = 1  # the wait after the next refusal

    def due(self) -> bool:
        """Whether this frame tries the reduced pyramid (counts the frame)."""
        if self._wait > 0:
            self._wait -= 1
            return False
        return True

    def record(self, accepted: bool) -> None:
        """The outcome of a try."""
        if accepted:
            self._next = 1
        else:
            self._wait = min(self._next, self.longest)
            self._next = min(2 * self._next, max(self.longest, 1))


class Reading(NamedTuple):
    """One readout: the patch motion, the camera motion fitted to it and the fraction of its
    usable patches that agree with that motion (its support, 0 without a fit).

    ``refined``: the displacements the motion was fitted to, ``(N, 2) float32``, when they are
    the readout's refined to sub-pixel precision (None: ``flow.disp`` as read); ``settled``:
    refining has been tried (what a failed fit to the refined vectors leaves as read)."""

    flow: FlowEstimate
    motion: GlobalMotion
    support: float
    refined: Optional[np.ndarray] = None
    settled: bool = False

    @property
    def disp(self) -> np.ndarray:
        """``(N, 2) float32``: the displacements the motion was fitted to."""
        return self.flow.disp if self.refined is None else self.refined


class GrbmFrontEnd(MotionFrontEnd):
    """Patch motion from the gated RBM, coarse to fine, over :class:`FramePyramid` frames.

    ``config`` holds the front end's own settings, ``flow`` the readout's (its ``levels``,
    ``finest`` and ``stride`` are varied per readout; ``warn_range`` is off: ``max_motion`` only
    plans the pyramid here, and beyond its reach the engine reads from the previous frame's
    motion). :attr:`last_flow` is the readout behind the last :meth:`measure`.
    """

    name = "grbm"
    description = ("moving camera: gated-RBM patch motion (coarse to fine) + RANSAC camera "
                   "motion + compensated background model (the paper's method)")
    config_type = GrbmConfig
    common_params = ("model", "stride", "max_motion", *MotionFrontEnd.common_params)
    #: The base presets, with a ``fast`` of the gated RBM's own: at half the working size, a
    #: patch grid of half the density in each direction (stride 16), no search for frame-fixed
    #: overlays, and the distances in working pixels halved with it (the RANSAC and violation
    #: thresholds, the edge windows' radius). At that size a frame's deferred work is smaller
    #: than the cost of handing it to a second thread, so ``fast`` runs in one (``overlap=0``),
    #: and its still-camera model learns nothing while the camera moves (``still_pause``). Its
    #: vectors, a sixteenth of ``balanced``'s, are coarse evidence: they boost the background
    #: score less (``flow_boost``), and a blob grows over its objects' colours a little more
    #: readily (``grow_above``). A model at this size takes longer to find its objects, so the
    #: twin that makes the first masks reads further ahead (``lookback``). Its ``accurate``
    #: fits the edge placement's guided filter on every pixel of the mask and frame
    #: (``edge_step=1``) and completes the mask by its objects' colours (``colour_cut``): a
    #: larger working size takes the subjects the camera follows into the parallax field and
    #: scores below ``balanced`` on real footage (docs/decisions.md).
    presets = MappingProxyType({
        **MotionFrontEnd.presets,
        "fast": {"work_width": 160, "stride": 16, "overlay": 0, "edge_radius": 4,
                 "ransac_threshold": 0.5, "violation_threshold": 0.375, "overlap": 0,
                 "still_pause": 1, "flow_boost": 1.0, "grow_above": 0.8,
                 "lookback": 45},
        "accurate": {"edge_step": 1, "colour_cut": 9},
    })

    def __init__(self, config: Optional[GrbmConfig] = None, *,
                 flow: Optional[FlowConfig] = None) -> None:
        super().__init__(config)
        self.flow = dataclasses.replace(flow or FlowConfig(), warn_range=False)
        self.model = _load(self.config.model, self.config.contrast_floor)
        self.last_flow: Optional[FlowEstimate] = None
        self._retry = RetryWait(self.config.retry_wait)
        self._configs: Dict[tuple, FlowConfig] = {}

    @classmethod
    def params(cls) -> Dict[str, Param]:
        return {**config_params(GrbmConfig), **config_params(FlowConfig, FLOW_PARAMS)}

    @classmethod
    def from_params(cls, **values: Any) -> "GrbmFrontEnd":
        own = {f.name for f in dataclasses.fields(GrbmConfig)}
        return cls(GrbmConfig(**{k: v for k, v in values.items() if k in own}),
                   flow=FlowConfig(**{k: v for k, v in values.items() if k not in own}))

    def frame_data(self, gray: np.ndarray) -> FramePyramid:
        return FramePyramid(gray)

    def prepare(self, data: FramePyramid) -> None:
        if not reads_raw(self.model):
            # With prior_levels, the next pair is normally read from the previous motion on
            # the reduced pyramid: prepare that; a read without a prior (or a retry) cuts the
            # other levels when it needs them.
            levels = self.flow.levels or self._reduced_levels()
            prepare_first_frame(data, self._flow_config(levels, self.flow.finest),
                                model=self.model)

    def check_size(self, gray: np.ndarray) -> None:
        patch = int(getattr(self.model, "patch_size", 0) or 0)
        if min(gray.shape) < patch:
            # Every frame would fall back to "no correspondences": a model for other footage.
            h, w = gray.shape
            raise InputError(f"frames of {w}x{h} (working size) are smaller than the model's "
                             f"{patch}x{patch} patches")

    def flow_colour(self, shape: tuple) -> Optional[np.ndarray]:
        if self.last_flow is None:
            return None
        dense = dense_from_patches(self.last_flow, shape=shape,
                                   patch_size=int(self.model.patch_size))
        return flow_to_color(dense, max_magnitude=self.colour_scale())

    def colour_scale(self) -> float:
        return max(4.0, self.flow.max_motion / 4)

    def read(self, prev: FramePyramid, cur: FramePyramid, prior: Optional[np.ndarray], *,
             finest: int, fit: CameraFit, levels: Optional[int] = None,
             stride: Optional[int] = None, refine: bool = False) -> Reading:
        """A readout with its final level ``finest``, on a grid of ``stride`` working-size
        pixels (default ``flow.stride``), over ``levels`` pyramid levels (default
        ``flow.levels``), started from ``prior`` ((3, 3) or None); with ``refine``, the camera
        is fitted to its vectors refined to sub-pixel precision (to them as read when that fit
        fails)."""
        levels = self.flow.levels if levels is None else levels
        flow = estimate_flow(prev, cur, self._flow_config(levels, finest, stride),
                             model=self.model, prior=prior)
        if refine:
            refined = self._refit(flow, prev, cur, fit)
            return refined or _fitted(flow, None, fit, cur.shape)._replace(settled=True)
        return _fitted(flow, None, fit, cur.shape)

    def measure(self, prev: FramePyramid, cur: FramePyramid, *, prior: Optional[np.ndarray],
                fit: CameraFit) -> MotionResult:
        best = self._reduced(prev, cur, prior, fit)
        if best is None:
            best = self._coarser_if_blurred(prev, cur, prior, fit)
        if not best.settled and best.motion.ok:  # (a coarser readout)
            best = self._refit(best.flow, prev, cur, fit) or best
        self.last_flow = best.flow
        return _result(best)

    def read_layer(self, prev: FramePyramid, cur: FramePyramid, result: MotionResult, *,
                   prior: np.ndarray, layer: NearLayer, fit: CameraFit) -> MotionResult:
        """The reduced pyramid read again, pre-warped by ``layer.prior(prior)``: inside the
        layer's region each patch keeps the read of the higher confidence, and the camera is
        fitted again to the merged vectors. ``result`` as it is when the reduced pyramid is
        off, the second read takes no patch or that fit fails."""
        levels = self._reduced_levels()
        first = self.last_flow
        if not levels or first is None:
            return result
        second = self.read(prev, cur, layer.prior(prior), finest=self.flow.finest, fit=fit,
                           levels=levels).flow
        merged = _merged(first, second, where=layer.covers(first.centres),
                         spread=layer.spread)
        if merged is None:
            return result
        reading = self._refit(merged, prev, cur, fit) or _fitted(merged, None, fit, cur.shape)
        if not reading.motion.ok:
            return result
        self.last_flow = reading.flow
        return _result(reading)

    def _reduced(self, prev: FramePyramid, cur: FramePyramid, prior: Optional[np.ndarray],
                 fit: CameraFit) -> Optional[Reading]:
        """The readout of the reduced pyramid (``prior_levels``, pre-warped by ``prior``) when
        it is due and well supported, else None: the frame is then read as without it."""
        levels = self._reduced_levels()
        if prior is None or not levels or not self._retry.due():
            return None
        # The previous frame's motion predicts this one to within a few pixels, which the
        # finest level reads. A camera that changes course, or blur the finest level cannot
        # read, fails the support test.
        reading = self.read(prev, cur, prior, finest=self.flow.finest, fit=fit, levels=levels,
                            refine=True)
        accepted = reading.motion.ok and reading.support >= self.config.retry_below
        self._retry.record(accepted)
        return reading if accepted else None

    def _reduced_levels(self) -> int:
        """The reduced pyramid's levels, counted from level 0 to its top (the final level and
        ``prior_levels`` up from it); 0 when it is not read (``prior_levels=0``, or a fixed
        ``levels``)."""
        if self.flow.levels or not self.config.prior_levels:
            return 0
        return self.flow.finest + self.config.prior_levels

    def _refit(self, flow: FlowEstimate, prev: FramePyramid, cur: FramePyramid,
               fit: CameraFit) -> Optional[Reading]:
        """The :class:`Reading` of ``flow`` with its usable vectors refined to sub-pixel
        precision (:func:`~bgsub.motion.refine.refine_vectors` on the working-size frames)
        and the camera fitted to them; None when refinement is off, no vector is usable or
        that fit fails."""
        usable = flow.weights > 0
        if self.config.refine_window == 0 or not usable.any():
            return None
        disp = flow.disp.copy()
        disp[usable] = self._refine(prev.gray8(), cur.gray8(), flow.centres[usable],
                                    flow.disp[usable])
        reading = _fitted(flow, disp, fit, cur.images[0].shape)
        return reading if reading.motion.ok else None

    def _coarser_if_blurred(self, prev: FramePyramid, cur: FramePyramid,
                            prior: Optional[np.ndarray], fit: CameraFit) -> Reading:
        """The readout at the final level, or, when few of its patches agree with its fit, the
        best supported of it and the readouts one and two levels coarser.

        Low support at the final level means the model cannot read it (motion blur, heavy
        compression) while a reduced image, where the blur is halved, reads consistently. The
        re-reads use a sparser grid (``coarser_stride``): as dense in the half-size image's own
        pixels as the first readout's in the full one, which also reads better there and costs
        a quarter.
        """
        finest = self.flow.finest
        # The final level's vectors are refined before the camera is fitted to them; when that
        # one fit is well supported (the usual frame) there is nothing more to read.
        final = self.read(prev, cur, prior, finest=finest, fit=fit, refine=True)
        if final.support >= self.config.coarser_below:
            return final
        # Judged as read, as the coarser readouts are: where a large object covers much of the
        # frame, its vectors outnumber the camera's among the refined ones, which is no blur.
        best = final if final.refined is None else _fitted(final.flow, None, fit, cur.shape)
        as_read, level = best, finest
        while (best.support < self.config.coarser_below and level < finest + 2
               and level + 1 < best.flow.levels):
            level += 1
            coarser = self.read(prev, cur, prior, finest=level, fit=fit,
                                stride=self.config.coarser_stride or self.flow.stride)
            if coarser.motion.ok and (coarser.support > best.support or not best.motion.ok):
                best = coarser
        return final if best is as_read else best

    def _refine(self, prev: np.ndarray, cur: np.ndarray, points: np.ndarray,
                disp: np.ndarray) -> np.ndarray:
        """:func:`~bgsub.motion.refine.refine_vectors` of ``(N, 2)`` ``points`` / ``disp``.

        In the calling thread: when the vectors are refined, the engine's second thread is
        still busy with the last frame's update and this frame's preparation, so work handed
        to it would wait for those (``docs/BENCHMARKS.md``)."""
        return refine_vectors(prev, cur, points, disp,
                              window=self.config.refine_window,
                              within=self.config.refine_within)

    def _flow_config(self, levels: int, finest: int, stride: Optional[int] = None) -> FlowConfig:
        key = (levels, finest, stride)
        if key not in self._configs:
            self._configs[key] = dataclasses.replace(
                self.flow, levels=levels, finest=finest,
                stride=self.flow.stride if stride is None else stride)
        return self._configs[key]


def _fitted(flow: FlowEstimate, refined: Optional[np.ndarray], fit: CameraFit,
            shape: tuple) -> Reading:
    """The :class:`Reading` of ``flow`` with the camera fitted to its displacements, or to the
    ``refined`` ones ``(N, 2) float32`` when given, in a frame of ``shape`` (h, w)."""
    disp = flow.disp if refined is None else refined
    motion = fit(flow.centres, disp, flow.weights, shape)
    used = max(int(np.count_nonzero(flow.weights > 0)), 1)
    return Reading(flow, motion, motion.n_inliers / used if motion.ok else 0.0, refined,
                   settled=refined is not None)


def _merged(first: FlowEstimate, second: FlowEstimate, *, where: np.ndarray,
            spread: float = np.inf) -> Optional[FlowEstimate]:
    """``first`` with the patches ``where`` ((N,) bool) that ``second`` (the same grid read
    with another pre-warp) read with more confidence, or where only it read them, taken from
    it; None when the grids differ, it reads no patch better, or the vectors it would give
    lie further than ``spread`` px (median) from their median."""
    if (second.centres.shape != first.centres.shape
            or not np.allclose(second.centres, first.centres)):
        return None
    take = where & second.valid & (~first.valid | (second.confidence > first.confidence))
    if not take.any():
        return None
    if np.isfinite(spread):
        taken = second.disp[take]
        if float(np.median(np.hypot(*(taken - np.median(taken, axis=0)).T))) > spread:
            return None

    def pick(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.where(take.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)

    return dataclasses.replace(
        first, disp=pick(second.disp, first.disp), valid=first.valid | take,
        confidence=pick(second.confidence, first.confidence),
        residual=pick(second.residual, first.residual),
        beyond=None if first.beyond is None else first.beyond & ~take)


def _result(reading: Reading) -> MotionResult:
    """The engine's view of a readout; violation evidence also counts textured patches whose
    residual is beyond the model's range (they moved relative to the camera by more than it
    can see)."""
    flow = reading.flow
    evidence = flow.weights.copy()
    if flow.beyond is not None:
        evidence[flow.beyond] = flow.texture[flow.beyond]
    return MotionResult(flow.centres, reading.disp, flow.weights, reading.motion, evidence)


def _load(model: Any, contrast_floor: float) -> Any:
    """The patch-motion model: a name or path loaded, a GatedRBM or a
    :class:`~bgsub.motion.patches.PatchMotion` as it is. A ``contrast_floor`` other than a
    contrast-normalised model's own gives a copy with its own readout caches (the model object
    may be shared: a caller's)."""
    from bgsub.model.rbm import load_model

    model = model if reads_raw(model) else load_model(model)
    if (contrast_floor > 0 and getattr(model, "normalization", None) == "contrast"
            and contrast_floor != model.contrast_floor):
        model = dataclasses.replace(model, contrast_floor=float(contrast_floor), _cache={})
    if not reads_raw(model):
        # Per-model constants of the readout, once here rather than in the first frame.
        from bgsub.model.readout import precompute
        from bgsub.motion.flowfield import model_range

        precompute(model, max_disp=model_range(model))
    return model

