"""The moving-camera engine: one class, :class:`MovingCameraEngine`, given a motion front end
(:mod:`bgsub.engines.frontend`). ``grbm`` (the default of ``bgsub run``) is it with the gated
RBM's patch motion, ``compensated`` with Lucas-Kanade corner tracks; comparing them isolates the
motion estimator. :func:`register_frontend` registers an engine for any front end.

Each frame passes six stages, at the working size (``work_width``; the mask is returned at the
input size):

1. motion: the front end measures local motion, and fits the camera's with the fit the camera
   stage hands it (:meth:`~bgsub.camera.CameraStage.fit_for`: RANSAC, or the known motion);
2. camera (:class:`~bgsub.camera.CameraStage`): a fit seen on only a small region is refused, a
   refused one replaced by the previous frame's motion (``last_status`` says why), small motion
   held back, a frozen model (``learning_rate=0``) registered to the frame;
3. compare (:meth:`~bgsub.background.foreground.Foreground.compare`): the compensated model,
   warped by that motion, scores the frame brought to its exposure, and the vectors give their
   violation map, while the second thread makes the frames' own motion evidence;
4. decide (:meth:`~bgsub.background.foreground.Foreground.decide`): a new shot restarts every
   stage; else the still-camera switch, the fusion, blob persistence, the last objects' colours
   and the holes the frame's edges close give the mask;
5. learn (:meth:`~bgsub.background.foreground.Foreground.learn`): the models' update, deferred
   to the next frame, where it runs in the second thread (``overlap=1``) beside the front end;
6. place (:func:`place_mask`): the mask is placed on the frame's own colour edges, at the
   input's size (:func:`~bgsub.background.guided.guided_mask`, ``edge_radius``), and completed
   by its objects' colours where asked (:mod:`~bgsub.background.colour_cut`, ``colour_cut``).

Frames that cannot be processed normally (blank, textureless, a scene cut) never raise: they
return an empty mask (or, for a scene cut, restart the model) and say why in ``last_status``.
"""

from __future__ import annotations

import collections
import functools
from dataclasses import dataclass
from typing import Any, Callable, Dict, Optional, Sequence, Type

import cv2
import numpy as np

from bgsub._util import FieldWarp
from bgsub.background.colour_cut import colour_cut
from bgsub.background.compensated import BackgroundConfig, CompensatedBackground
from bgsub.background.exposure import match_exposure, same_exposure
from bgsub.background.foreground import Foreground, ForegroundConfig
from bgsub.background.fusion import Fusion, FusionConfig
from bgsub.background.guided import guided_mask
from bgsub.background.layers import LayerWarps
from bgsub.background.object_colour import ObjectColours
from bgsub.background.overlay import OverlayConfig, OverlayDetector
from bgsub.background.persistence import BlobPersistence
from bgsub.background.scene_cut import SceneCut
from bgsub.background.shadow import ShadowVeto
from bgsub.background.still_switch import NoStillSwitch, StillCameraSwitch
from bgsub.camera.parallax import ParallaxConfig, ParallaxField, without_parallax
from bgsub.camera import KNOWN_MOTION_HELP, CameraConfig, CameraStage, KnownMotion, work_scale
from bgsub.engines.base import (Engine, Param, check_fgmask, check_frame, check_learning_rate,
                                get_engine_spec, opencv_keywords, register_engine)
from bgsub.engines.config import MIN_WORK_WIDTH, EngineConfig, engine_params, stage_configs
from bgsub.engines.frontend import MotionFrontEnd
from bgsub.engines.roi import WHOLE_FRAME, FrameLess
from bgsub.engines.threads import SecondThread, limited_threads
from bgsub.errors import InputError
from bgsub.io.flowio import add_colour_wheel, draw_flow_arrows
from bgsub.motion.global_motion import apply_homography
from bgsub.motion.result import NO_MOTION, MotionResult

__all__ = ["MovingCameraEngine", "Previous", "register_frontend", "work_size", "draw_debug",
           "place_mask", "SCENE_CUT"]

#: ``last_status`` of a frame taken for a new shot (the model restarts from it).
SCENE_CUT = "fallback: scene cut"


def work_size(width: int, height: int, work_width: int) -> tuple:
    """``(w, h)``: the working size of ``width`` x ``height`` frames. Frames wider than
    ``work_width`` (0 = none) are shrunk to it, but a wide, flat frame keeps a height of
    ``MIN_WORK_WIDTH`` (or its own, if less) rather than shrinking below what a patch grid can
    read."""
    if work_width <= 0 or width <= work_width:
        return width, height
    scale = max(work_width / width, min(1.0, MIN_WORK_WIDTH / height))
    return max(1, int(round(width * scale))), max(1, int(round(height * scale)))


def _to_work(image: np.ndarray, work_width: int) -> np.ndarray:
    """``image`` resized to its :func:`work_size` (itself when that is its size)."""
    h, w = image.shape[:2]
    ww, wh = work_size(w, h, work_width)
    if (ww, wh) == (w, h):
        return image
    return cv2.resize(image, (ww, wh), interpolation=cv2.INTER_AREA)


def _smoothed(work: np.ndarray, sigma: float) -> np.ndarray:
    """``work`` blurred by a Gaussian of ``sigma`` px (a new array), or itself for 0."""
    return cv2.GaussianBlur(work, (0, 0), sigma) if sigma > 0 else work


def _to_input(img: np.ndarray, in_shape: tuple, *, binary: bool = False) -> np.ndarray:
    """``img`` (working size) resized to the input's ``in_shape``; a ``binary`` mask stays
    0/255."""
    h, w = in_shape[:2]
    if img.shape[:2] == (h, w):
        return img
    up = cv2.resize(img, (w, h), interpolation=cv2.INTER_LINEAR)
    if binary:  # > 127 -> 255, else 0, in place
        cv2.threshold(up, 127, 255, cv2.THRESH_BINARY, dst=up)
    return up


def working_frames(image: np.ndarray, config: EngineConfig) -> tuple:
    """``(work, smoothed, gray)``: the input ``image`` at the working size (never the caller's
    buffer), blurred by ``smooth``, and that one's (h, w) uint8 gray image."""
    work = _to_work(image, config.work_width)
    if work is image:
        # The model keeps the frame past this call (the previous frame of the next pair, the
        # deferred update): not the caller's buffer, which a reading loop may reuse.
        work = image.copy()
    smoothed = _smoothed(work, config.smooth)
    gray = smoothed if smoothed.ndim == 2 else cv2.cvtColor(smoothed, cv2.COLOR_BGR2GRAY)
    return work, smoothed, gray


def place_mask(mask: np.ndarray, work: np.ndarray, image: np.ndarray,
               config: EngineConfig) -> np.ndarray:
    """The place stage: the fused working-size ``mask`` placed on the frame's colour edges at
    the size of the input ``image`` (:func:`~bgsub.background.guided.guided_mask`, with
    ``work``, the frame at the working size), or with ``edge_radius`` 0 as it is, scaled up
    bilinearly; with ``colour_cut``, completed by the objects' colours
    (:func:`~bgsub.background.colour_cut.colour_cut`). ``(H, W) uint8`` 0/255."""
    if config.edge_radius == 0:
        placed = _to_input(mask, image.shape, binary=True)
    else:
        full = work if work.shape == image.shape else image
        placed = guided_mask(mask, work, full, radius=config.edge_radius, eps=config.edge_eps,
                             step=config.edge_step)
    if config.colour_cut:
        return colour_cut(placed, image, radius=config.colour_cut)
    return placed


def to_input_motion(matrix: np.ndarray, in_shape: tuple, work_width: int) -> np.ndarray:
    """A working-size motion ``matrix`` (3, 3) in the pixel coordinates of input frames of
    ``in_shape`` ``(H, W, ...)`` (a copy)."""
    h, w = in_shape[:2]
    ww, wh = work_size(w, h, work_width)
    if (ww, wh) == (w, h):
        return matrix.copy()
    scale = work_scale((h, w), (wh, ww))
    return np.linalg.solve(scale, matrix @ scale)


@dataclass
class Previous:
    """What the engine keeps of the frames before the current one: the last frame it took (the
    first of the next pair) and what it saw of the last frame it was given."""

    data: Any = None  # the last frame taken, as the front end keeps it (None: no frame yet)
    gray: Optional[np.ndarray] = None  # ... its (h, w) uint8 gray image
    work: Optional[np.ndarray] = None  # ... and its working-size frame as the stages saw it
    result: Optional[MotionResult] = None  # the motion measured for the last frame given
    applied: Optional[np.ndarray] = None  # (3, 3): what it warped the model by
    gain: Optional[float] = None  # its exposure gain (set where a model scored it)
    parallax: Optional[float] = None  # the vectors' share its parallax field explained
    frame: Optional[np.ndarray] = None  # the last frame given, at the working size
    mask: Optional[np.ndarray] = None  # ... and its (h, w) uint8 0/255 mask (working size)


class MovingCameraEngine(Engine):
    """A background subtractor for a moving camera, built on the motion front end ``frontend``;
    a frame passes its stages motion, camera, compare, decide, learn (deferred to the next
    frame) and place (the module docstring). A stage setting left out takes its defaults, with
    those the front end replaces (``frontend.stage_defaults``)::

        engine = MovingCameraEngine(LucasKanadeFrontEnd(LucasKanadeConfig(max_corners=800)),
                                    fusion=FusionConfig(min_area=50))

    Attributes: ``last_status`` (``"ok"`` or ``"fallback: <reason>"`` for the last frame),
    ``frontend``, ``config`` (:class:`EngineConfig`), ``camera`` (the camera stage,
    :class:`~bgsub.camera.CameraStage`), ``foreground`` (the compare, decide and learn stages,
    :class:`~bgsub.background.foreground.Foreground`) with its compensated background model
    ``bg``, ``fusion`` and ``still_switch``, and ``previous`` (:class:`Previous`).
    """

    def __init__(self, frontend: MotionFrontEnd, *, engine: Optional[EngineConfig] = None,
                 camera: Optional[CameraConfig] = None,
                 background: Optional[BackgroundConfig] = None,
                 foreground: Optional[ForegroundConfig] = None,
                 fusion: Optional[FusionConfig] = None,
                 overlay: Optional[OverlayConfig] = None,
                 parallax: Optional[ParallaxConfig] = None,
                 known_motion: Optional[KnownMotion] = None) -> None:
        defaults = stage_configs({}, frontend.stage_defaults)
        self.frontend = frontend
        self.name = frontend.name or "moving-camera"
        self.config = engine or defaults[EngineConfig]
        self.camera = CameraStage(camera or defaults[CameraConfig], known_motion)
        self.bg = CompensatedBackground(background or defaults[BackgroundConfig])
        self.fusion = Fusion(fusion or defaults[FusionConfig])
        f = foreground or defaults[ForegroundConfig]
        self.still_switch = (StillCameraSwitch(still_model=f.still_model, still_snr=f.still_snr,
                                               window=f.still_window,
                                               still_versus=f.still_versus,
                                               steady=f.still_steady,
                                               radius=f.still_radius, spread=f.still_spread,
                                               pause=bool(f.still_pause))
                             if f.still_model > 0 else NoStillSwitch())
        self.thread = SecondThread(overlap=self.config.overlap, name=self.name)
        self.foreground = Foreground(
            self.bg, self.fusion, still_switch=self.still_switch,
            exposure=match_exposure if f.match_exposure else same_exposure,
            scene_cut=SceneCut(f.scene_cut, f.cut_support),
            persistence=BlobPersistence(self.fusion.config.persist),
            object_colours=ObjectColours(radius=self.fusion.config.grow_radius,
                                         above=self.fusion.config.grow_above),
            shadows=ShadowVeto(low=f.shadow, chroma=f.shadow_chroma, texture=f.shadow_texture),
            alongside=self.thread.alongside)
        self.overlays = OverlayDetector(overlay or defaults[OverlayConfig])
        self.parallax = ParallaxField(parallax or defaults[ParallaxConfig])
        self._frame_less = FrameLess()
        self.last_status = "ok"
        self.previous = Previous()
        self._in_shape: Optional[tuple] = None  # the input frames' (H, W) or (H, W, 3)
        #: ``() -> MovingCameraEngine``: a new engine of the same settings (set by the
        #: registered factory; None: :meth:`prime` does nothing).
        self.twin: Optional[Callable[[], "MovingCameraEngine"]] = None
        self._early: collections.deque = collections.deque()  # masks prime read ahead

    # ------------------------------------------------------------------ Engine API

    @opencv_keywords
    def apply(self, image: np.ndarray, fgmask: Optional[np.ndarray] = None,
              learning_rate: float = -1.0) -> np.ndarray:
        image = check_frame(image, shape=self._in_shape)
        rate = check_learning_rate(learning_rate, default=self.config.learning_rate)
        check_fgmask(fgmask, image.shape[:2])
        self._in_shape = image.shape
        self.camera.known.next_frame()
        with limited_threads(self.config.threads):
            work, smoothed, as_came = working_frames(image, self.config)
            # (a region of interest given replaces the overlays' detection)
            smoothed, gray = ((smoothed, as_came) if self.roi is not None
                              else self.overlays.unveil(smoothed, as_came))
            mask = self._step(smoothed, gray, rate, as_came=as_came)
            out = place_mask(mask, work, image, self.config)
        self.previous.frame, self.previous.mask = work, mask
        if self._early:
            twins, agree = self._early.popleft()
            out = cv2.bitwise_and(out, twins) if agree else twins
        if fgmask is not None:
            fgmask[...] = out
            return fgmask
        return out

    @property
    def lookback(self) -> int:
        """How many of a stream's first frames :meth:`prime` takes: ``lookback``, or 0 with a
        known camera motion (given frame by frame, from the first) or no way to build a twin
        (an engine not made by its registered factory)."""
        if isinstance(self.camera.known, KnownMotion) or self.twin is None:
            return 0
        return self.config.lookback

    def prime(self, frames: Sequence[np.ndarray]) -> None:
        """Read ahead before the first mask: a twin of this engine (same settings, its own
        state) runs the stream's first ``frames`` (each (H, W[, 3]) uint8, in order, at most
        :attr:`lookback`) backwards, and for the first frames, those it has seen more of the
        scene for than this engine will have, its masks are what :meth:`apply` returns (where
        the twin finds nothing in frame 1, only where this engine's own masks agree). This
        engine still processes every frame, so its own model grows as it would have; only
        those masks are replaced. Does nothing after the first frame or with fewer than three
        frames."""
        frames = list(frames)[:self.lookback]
        if self.previous.data is not None or len(frames) < 3:
            return
        twin = self.twin()
        try:
            backwards = [twin.apply(image) for image in reversed(frames)]
        finally:
            twin.close()
        n = len(frames)
        # Nothing moving in frame 1: this engine's model starts on the bare scene, while the
        # twin's started on frame n's objects and may keep their ghosts; and a young model
        # still takes near ground for foreground. Foreground then needs both to agree.
        agree = not backwards[-1].any()
        # Frame t (0-based) has t frames before it going forward, n - 1 - t going backward.
        self._early = collections.deque((backwards[n - 1 - t], agree)
                                        for t in range(n) if n - 1 - t > t)

    def close(self) -> None:
        """Stop the engine's second thread (``overlap=1``) now rather than when the engine is
        garbage-collected; a later :meth:`apply` starts it again."""
        self.thread.close()

    # ------------------------------------------------------------------ one frame

    def _step(self, work: np.ndarray, gray: np.ndarray, rate: float, *,
              as_came: np.ndarray) -> np.ndarray:
        """One frame at the working size through the stages: ``work`` is the frame (BGR or
        gray uint8, blurred by ``smooth``, a semi-transparent overlay taken out), ``gray`` its
        (h, w) uint8 gray image (``as_came`` before the overlay was taken out), ``rate`` the
        checked learning rate (0: a frozen model). Returns the (h, w) uint8 0/255 mask."""
        prev = self.previous
        prev.result = prev.applied = prev.gain = prev.parallax = None
        empty = np.zeros(gray.shape, np.uint8)
        if float(cv2.meanStdDev(gray)[1][0, 0]) < self.config.min_contrast:
            # Blank or textureless frame: no motion can be measured; keep the model as it is.
            self._learn()
            self.last_status = "fallback: blank or textureless frame"
            return empty
        if prev.data is None:
            self.frontend.check_size(gray)
            self._restart(work, gray, self.frontend.frame_data(gray))
            prev.applied = np.eye(3)  # no previous frame
            self.last_status = "ok"
            return empty
        frozen = rate == 0.0
        cur = self.frontend.frame_data(gray)
        seen = self.camera.decide(self._motion(cur, gray, as_came), gray, self.bg, frozen=frozen)
        prev.result = seen.result
        seen, parallax = self._parallax(seen, gray.shape)
        compared = self.foreground.compare(work, prev.work, seen.result, seen.matrix,
                                           seen.applied, frozen=frozen, fixed=seen.refused,
                                           parallax=parallax,
                                           layers=None if frozen else
                                           self._layers(seen, parallax, gray.shape))
        if parallax is not None:
            self.parallax.discount_edges(compared.score, compared.violation)
        if self.roi is None:
            self.overlays.discount(compared.score, as_came)
        young = self._region.unwatched(self.foreground.young())
        if self.foreground.is_cut(compared, seen.result, young):
            self._restart(work, gray, cur)
            self.last_status = SCENE_CUT
            return empty
        prev.applied, prev.gain = seen.applied, float(compared.gain)
        prev.parallax = self.parallax.share if parallax is not None else 0.0
        # (Outside a region of interest the mask is cleared by the engine's caller.)
        mask = self.foreground.decide(work, gray, seen.result, seen.matrix, compared, rate,
                                      region=WHOLE_FRAME if self.roi else self._region)
        prev.data, prev.gray, prev.work = cur, gray, work
        self.last_status = seen.status
        return mask

    def _parallax(self, seen: Any, shape: tuple) -> tuple:
        """``(seen, warp)``: the camera stage's decision ``seen`` with the background's parallax
        taken off its vectors, and the homography-plus-parallax warp
        (:class:`~bgsub._util.FieldWarp`), or ``(seen, None)`` where no parallax stands out
        (:class:`~bgsub.camera.parallax.ParallaxField`) or the camera is taken as still."""
        if seen.refused or self.camera_still:
            return seen, None
        r = seen.result
        field = self.parallax.estimate(r.points, r.disp, r.weights, seen.matrix, shape,
                                       foreground=self.previous.mask)
        if field is None:
            return seen, None
        return seen._replace(result=without_parallax(r, field)), FieldWarp(seen.matrix, field)

    def _layers(self, seen: Any, parallax: Optional[FieldWarp],
                shape: tuple) -> Optional[LayerWarps]:
        """The other warps the background may take, block by block, where a parallax field
        stands (:mod:`bgsub.background.layers`), or None."""
        warps = [] if parallax is None else self.parallax.neighbour_warps(seen.matrix, shape)
        if not warps:
            return None
        return LayerWarps(tuple(warps), self.parallax.config.parallax_layers,
                          self.previous.mask)

    @property
    def _region(self) -> Any:
        """The region of interest; without one, the frame less the frame-fixed overlays found
        so far (:class:`~bgsub.engines.roi.FrameLess`), or the whole frame."""
        return self.roi or self._frame_less.of(self.overlays.mask)

    def _motion(self, cur: Any, gray: np.ndarray, as_came: np.ndarray) -> MotionResult:
        """The motion stage: the front end's motion from the previous frame to ``cur``, while
        the second thread applies the last frame's update and prepares ``cur`` for the next
        pair; over the region of interest's vectors only; the overlay detector looks at the
        frame ``as_came`` (before a see-through overlay was taken out). In a 3-D scene (a
        parallax field lately) the fit keeps its plane (``parallax_hold``), and a near layer
        that moves beyond the read's reach is read again (``parallax_layer``)."""
        hold = self.parallax.config.parallax_hold if self.parallax.standing() else 0.0
        fit, prior = self.camera.fit_for(self._in_shape, gray.shape, hold=hold)
        fit = self._region.restrict_fit(fit)
        with self.thread.alongside(self._learn, lambda: self.frontend.prepare(cur)):
            if np.array_equal(gray, self.previous.gray):
                # A repeated frame (a frame-rate conversion's duplicate, a paused stream): the
                # camera did not move, whatever a noisy reading would say; a frozen model
                # would otherwise drift by that reading's error.
                return NO_MOTION
            result = self.frontend.measure(self.previous.data, cur, prior=prior, fit=fit)
            result = self._read_layer(cur, result, prior=prior, fit=fit, shape=gray.shape)
        if self.roi is None:  # (a region of interest given replaces the overlays' detection)
            self.overlays.observe(as_came, result.points, result.disp, result.weights,
                                  camera_still=self.camera_still,
                                  matrix=result.motion.matrix if result.motion.ok else None)
        return self._region.restrict(result, gray.shape)

    def _read_layer(self, cur: Any, result: MotionResult, *, prior: Optional[np.ndarray],
                    fit: Any, shape: tuple) -> MotionResult:
        """``result`` with a near layer read a second time: the one a recent parallax field
        showed, pre-warped from ``prior`` (``parallax_layer``), or, after a frame without one,
        the one the scattered vectors suggest, pre-warped from this fit
        (``parallax_probe``); ``result`` as it is without either."""
        layer = self.parallax.layer_to_read()
        if layer is not None and prior is not None:
            return self.frontend.read_layer(self.previous.data, cur, result, prior=prior,
                                            layer=layer, fit=fit)
        probe = self.parallax.layer_to_probe(result, shape)
        if probe is None:
            return result
        read = self.frontend.read_layer(self.previous.data, cur, result,
                                        prior=result.motion.matrix, layer=probe, fit=fit)
        self.parallax.probe_taken(read is not result)
        return read

    def _learn(self) -> None:
        """The learn stage: the last frame's deferred update of the models, after which the
        compensated model keeps no history of the overlays (a warp would drag it over the
        scene)."""
        self.foreground.learn()
        self.overlays.forget_in(self.bg)

    def _restart(self, work: np.ndarray, gray: np.ndarray, data: Any) -> None:
        """Start every stage over from ``work`` (the frame; ``gray`` its gray image, ``data``
        what the front end keeps of it): the first frame, a new shot."""
        for stage in (self.foreground, self.camera):
            stage.restart(work)
        self.parallax.restart()
        self.previous.data, self.previous.gray, self.previous.work = data, gray, work

    # ------------------------------------------------------------------ what the engine saw

    @property
    def fit(self) -> Any:
        """The camera stage's RANSAC fit (:class:`~bgsub.camera.CameraFit`), which a caller
        may replace."""
        return self.camera.fit

    @fit.setter
    def fit(self, fit: Any) -> None:
        self.camera.fit = fit

    @property
    def known_motion(self) -> Any:
        """The camera motion given (:class:`~bgsub.camera.KnownMotion`), or the stage's null
        one (every frame fitted)."""
        return self.camera.known

    @property
    def camera_still(self) -> bool:
        """Whether the last frame was taken as seen by a still camera (``still_model``)."""
        return self.still_switch.camera_still

    @property
    def overlay_box(self) -> Optional[tuple]:
        """``(x, y, w, h)`` in input pixels around the frame-fixed overlays found (a logo, a
        watermark, a timestamp, letterbox bars: taken as background), or None."""
        return self._input_box(self.overlays.box())

    def _input_box(self, box: Optional[tuple]) -> Optional[tuple]:
        """A ``(x, y, w, h)`` box of working-size pixels in input pixels."""
        if box is None or self._in_shape is None or self.previous.gray is None:
            return box
        scale = self._in_shape[1] / self.previous.gray.shape[1]
        return tuple(int(round(v * scale)) for v in box)

    @property
    def see_through_box(self) -> Optional[tuple]:
        """``(x, y, w, h)`` in input pixels around the semi-transparent overlay found (a
        watermark word), which each frame is mapped back to the scene under, or None."""
        return self._input_box(self.overlays.see_through_box())

    @property
    def last_result(self) -> Optional[MotionResult]:
        """What the front end measured for the last frame (working-size pixels; a fit the
        small-region rule refused shows as refused), or None where it measured nothing (the
        first, a blank frame)."""
        return self.previous.result

    @property
    def last_motion(self) -> Optional[np.ndarray]:
        """The camera motion from the previous frame to the last one, as the engine applied it
        to its background model: ``(3, 3) float64`` in the input's pixel coordinates (as
        :mod:`bgsub.motion.global_motion`). Normally the fit; on a frame whose fit was refused, the
        previous frame's motion, or the identity when it was seen on only a small region
        (``last_status`` says which); with ``learning_rate=0``, registered to the model. The
        identity on the first frame and while the motion since the last warp moves no corner
        by ``still_below`` px: that motion is then applied with a later frame's, so the
        product of the matrices is the camera's path. None where the engine measured none (a
        blank frame, a scene cut) and before the first frame."""
        matrix = self.previous.applied
        if matrix is None or self._in_shape is None:
            return None
        return to_input_motion(matrix, self._in_shape, self.config.work_width)

    def frame_stats(self) -> Dict[str, Any]:
        """What the engine saw of the last frame, for per-frame statistics (None where it has no
        such quantity on that frame: the first, a blank frame, a scene cut).

        ``status``: :attr:`last_status`; ``dx``, ``dy``: where :attr:`last_motion` (the motion
        as applied, as ``--motion`` writes it) moved the frame's centre (input pixels);
        ``rotation`` (degrees) and ``scale`` of that motion's linear part; ``inliers`` and
        ``vectors``: the motion vectors that agree with the fit, and all the front end
        measured; ``gain``: what the frame was divided by to match the model's exposure (1.0
        without ``match_exposure``); ``model``: ``"still"`` or ``"compensated"``, the
        background model that scored the frame; ``parallax``: the share of the vectors' weight
        its parallax field explained (0: the homography alone,
        :class:`~bgsub.camera.parallax.ParallaxField`).
        """
        return frame_stats(self.previous, self.last_motion, self._in_shape, self.last_status,
                           still=self.camera_still)

    def get_background_image(self) -> Optional[np.ndarray]:
        """The background model's mean in the current frame's coordinates, at the input size
        (like the input: gray or BGR uint8), or None before the first frame."""
        self.foreground.learn()
        model = self.still_switch.model if self.camera_still else self.bg
        img = model.background_image()
        if img is None or self._in_shape is None:
            return img
        return _to_input(img, self._in_shape)

    def debug_image(self) -> Optional[np.ndarray]:
        """The last frame (working size, scaled to the input) with the motion vectors drawn:
        green = RANSAC inliers, red = outliers, blue = the camera motion on a coarse grid; the
        foreground mask tints the frame magenta; a front end with a colour picture of its motion
        has it blended in, with its colour-wheel legend in the bottom-right corner.
        ``(H, W, 3) uint8``, None before two frames."""
        prev = self.previous
        if prev.frame is None or prev.result is None:
            return None
        return debug_picture(prev, self.frontend, self.last_status, self._in_shape)


def frame_stats(prev: Previous, motion: Optional[np.ndarray], in_shape: Optional[tuple],
                status: str, *, still: bool) -> Dict[str, Any]:
    """:meth:`MovingCameraEngine.frame_stats` of the last frame ``prev`` (:class:`Previous`),
    whose applied ``motion`` (3, 3) is in the pixels of input frames of ``in_shape``."""
    stats: Dict[str, Any] = dict.fromkeys(
        ("dx", "dy", "rotation", "scale", "inliers", "vectors", "gain", "model", "parallax"))
    stats["status"] = status
    if motion is not None and prev.result is not None:  # (the first frame measured none)
        h, w = in_shape[:2]
        centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0, 1.0])
        moved = motion @ centre
        stats["dx"], stats["dy"] = (moved[:2] / moved[2] - centre[:2]).tolist()
        stats["rotation"] = float(np.degrees(np.arctan2(motion[1, 0], motion[0, 0])))
        stats["scale"] = float(np.sqrt(abs(np.linalg.det(motion[:2, :2]))))
    if prev.result is not None:
        stats["inliers"] = prev.result.motion.n_inliers
        stats["vectors"] = int(len(prev.result.points))
    if prev.gain is not None:  # (set only where a model scored the frame)
        stats["gain"] = prev.gain
        stats["model"] = "still" if still else "compensated"
        stats["parallax"] = prev.parallax
    return stats


def debug_picture(prev: Previous, frontend: MotionFrontEnd, status: str,
                  in_shape: tuple) -> np.ndarray:
    """:meth:`MovingCameraEngine.debug_image` of the last frame ``prev`` (:class:`Previous`,
    with a frame and a result) seen through ``frontend``, with ``status`` written, at the size
    of ``in_shape``: ``(H, W, 3) uint8``."""
    colour = None if prev.result is NO_MOTION else frontend.flow_colour(prev.frame.shape[:2])
    canvas = _to_input(draw_debug(prev.frame, prev.mask, prev.result, colour, status), in_shape)
    scale = frontend.colour_scale()
    if colour is None or scale is None:
        return canvas
    # The legend speaks of the picture's pixels: the input's, not the working size's.
    return add_colour_wheel(canvas, scale * canvas.shape[1] / colour.shape[1])


def draw_debug(frame: np.ndarray, mask: Optional[np.ndarray], res: MotionResult,
               colour: Optional[np.ndarray], status: str) -> np.ndarray:
    """``frame`` ((h, w) or (h, w, 3) uint8) darkened, with the front end's motion picture
    ``colour`` blended in, ``mask`` tinting it magenta, the vectors of ``res`` drawn (green =
    RANSAC inliers, red = outliers), the camera motion on a coarse grid (blue) and ``status``
    written: ``(h, w, 3) uint8``."""
    canvas = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()
    canvas = (canvas * 0.6).astype(np.uint8)
    if colour is not None:
        canvas = cv2.addWeighted(canvas, 0.5, colour, 0.5, 0.0)
    if mask is not None:
        canvas[mask > 0] = (0.5 * canvas[mask > 0] + np.array([127, 0, 127])).astype(np.uint8)
    h, w = canvas.shape[:2]
    use = res.weights > 0
    inl = res.motion.inliers  # over all of res.points (GlobalMotion's contract)
    # Arrows end where the point went (drawn from the previous position).
    for chosen, colour_bgr in ((use & ~inl, (0, 0, 255)), (use & inl, (0, 255, 0))):
        canvas = draw_flow_arrows(canvas, res.points[chosen], res.disp[chosen], scale=3.0,
                                  color=colour_bgr, dot_color=None)
    step = max(16, w // 10)
    ys, xs = np.mgrid[step // 2:h:step, step // 2:w:step]
    grid = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    cam = apply_homography(res.motion.matrix if res.motion.ok else np.eye(3), grid) - grid
    canvas = draw_flow_arrows(canvas, grid, cam, scale=3.0, color=(255, 128, 0), thickness=2,
                              dot_color=(255, 128, 0))
    cv2.putText(canvas, status[:40], (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                (255, 255, 255), 1, cv2.LINE_AA)
    return canvas


# ---------------------------------------------------------------------- registration

def register_frontend(frontend_type: Type[MotionFrontEnd]) -> None:
    """Register the moving-camera engine built on ``frontend_type`` under its ``name``: its
    parameters are the front end's (:meth:`MotionFrontEnd.params`) and every stage setting
    (with the front end's ``stage_defaults``), its presets the front end's ``presets``,
    ``bgsub methods`` lists them and ``create_engine(name, **params)`` builds it."""
    name, overrides = frontend_type.name, dict(frontend_type.stage_defaults)
    front = frontend_type.params()
    params = {**engine_params(front, overrides), "known_motion": Param("", KNOWN_MOTION_HELP)}

    def factory(*, known_motion: Any, **values: Any) -> MovingCameraEngine:
        try:
            stages = stage_configs(values, overrides)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
        given = (None if isinstance(known_motion, str) and not known_motion
                 else KnownMotion.from_value(known_motion))
        frontend = frontend_type.from_params(**{k: v for k, v in values.items() if k in front})
        engine = MovingCameraEngine(frontend, engine=stages[EngineConfig],
                                    camera=stages[CameraConfig],
                                    background=stages[BackgroundConfig],
                                    foreground=stages[ForegroundConfig],
                                    fusion=stages[FusionConfig], overlay=stages[OverlayConfig],
                                    parallax=stages[ParallaxConfig], known_motion=given)
        engine.twin = functools.partial(_registered, name, known_motion=known_motion, **values)
        return engine

    factory.__module__ = frontend_type.__module__  # the engine is the front end's
    register_engine(name, frontend_type.description, params,
                    common=frontend_type.common_params, presets=frontend_type.presets)(factory)


def _registered(name: str, **values: Any) -> MovingCameraEngine:
    """A new engine from the registered factory of ``name`` (a module-level function, so an
    engine's ``twin`` pickles with it)."""
    return get_engine_spec(name).factory(**values)


def _register_builtins() -> None:
    from bgsub.engines.frontends.grbm import GrbmFrontEnd
    from bgsub.engines.frontends.lucas_kanade import LucasKanadeFrontEnd

    register_frontend(GrbmFrontEnd)
    register_frontend(LucasKanadeFrontEnd)


_register_builtins()
