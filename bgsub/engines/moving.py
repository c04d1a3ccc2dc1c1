"""The moving-camera engines: ``grbm`` (the default of ``bgsub run``) and ``compensated``.

Both run the same per-frame steps and differ only in the motion front end, so comparing them
isolates the motion estimator:

1. the frame is converted to the working size (``work_width``; the mask is returned at the input
   size);
2. motion front end: ``grbm`` reads patch displacements off the gated RBM coarse to fine
   (:func:`bgsub.motion.flowfield.estimate_flow`); ``compensated`` tracks Shi-Tomasi corners with
   pyramidal Lucas-Kanade and keeps the tracks that pass a forward-backward check;
3. RANSAC fits the camera motion (:func:`bgsub.motion.global_motion.fit_global_motion`); when the fit
   is refused the previous frame's motion is reused and the frame is flagged in ``last_status``
   (a fit whose inliers cover only a small region is an object's: the camera is taken as still,
   :func:`spans_frame`); motion that moves no corner by ``still_below`` px is held back until
   the frames' total does;
   with ``learning_rate=0`` the fit is registered to the frozen model, so errors do not add up;
4. the compensated background model is warped by it, compared with the frame, fused with the
   flow-violation map and cleaned (:mod:`bgsub.background.foreground`), then updated. While the camera is
   judged still (``still_model``: a never-warped sample model explains the frame and no fitted
   motion stands out of the vectors' scatter), that sample model replaces it in the fusion:
   water and foam defeat a mean-and-variance model, and their drift would be taken for a pan.

Frames that cannot be processed normally (blank, textureless, a scene cut) never raise: they
return an empty mask (or, for a scene cut, restart the model) and say why in ``last_status``.
"""

from __future__ import annotations

import collections
import concurrent.futures
import contextlib
import dataclasses
from dataclasses import dataclass
from abc import abstractmethod
from typing import Any, Callable, Iterator, Optional

import cv2
import numpy as np

from bgsub.engines import (LEARNING_RATE, Engine, Param, check_fgmask, check_frame,
                           check_learning_rate, opencv_keywords, register_engine)
from bgsub.errors import InputError
from bgsub.motion.config import FlowConfig
from bgsub.motion.flowfield import FramePyramid, dense_from_patches, estimate_flow, prepare_first_frame
from bgsub.io.flowio import draw_flow_arrows, flow_to_color
from bgsub.background.foreground import (
    BackgroundParams,
    CompensatedBackground,
    SampleBackground,
    flow_violation_map,
    fuse_masks,
    still_in_image_map,
)
from bgsub.motion.global_motion import (MODELS, GlobalMotion, apply_homography, corner_distances,
                                 fit_global_motion)

__all__ = ["MovingCameraEngine", "GrbmEngine", "CompensatedEngine", "MotionResult",
           "GRBM_TUNED", "limited_threads", "spans_frame", "motion_snr"]


# The narrowest working frame: a few 13x13 patches across, so a motion can be read at all.
# Resizing to ``work_width`` never makes the short side smaller than this either.
MIN_WORK_WIDTH = 32


# ---------------------------------------------------------------------- worker threads
#
# One frame's work is many small matmuls (a few hundred to ~1100 patches x 169 x 200) and
# whole-frame OpenCV calls on 320x240 images. Handing those to worker threads costs more than it
# saves: on the shared 2-core development machine a multi-threaded OpenBLAS ran grbm at 4 frames/s
# instead of 15-30 (its threads spin-wait for a busy core), and OpenCV's 2 threads cost ~10 % of
# the CPU time of 1 (docs/BENCHMARKS.md, issue 4). So the engines run each frame with ``threads``
# (default 1) BLAS and OpenCV threads and restore the previous settings afterwards. The settings
# are process-wide: engines stepped concurrently from several Python threads should all use the
# same ``threads`` value.

_BLAS_SYMBOLS = (
    ("scipy_openblas_set_num_threads64_", "scipy_openblas_get_num_threads64_"),
    ("scipy_openblas_set_num_threads", "scipy_openblas_get_num_threads"),
    ("openblas_set_num_threads64_", "openblas_get_num_threads64_"),
    ("openblas_set_num_threads", "openblas_get_num_threads"),
)
_blas_api: Optional[tuple] = None  # (set, get) or () when not found


def _openblas() -> tuple:
    """``(set_num_threads, get_num_threads)`` of the OpenBLAS numpy uses, or ``()``."""
    global _blas_api
    if _blas_api is not None:
        return _blas_api
    _blas_api = ()
    import ctypes
    import glob
    import os

    # numpy's own first: wheels bundle scipy-openblas in numpy.libs (scipy may load another).
    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    candidates = sorted(glob.glob(os.path.join(libs, "*openblas*")))
    try:  # Linux: an OpenBLAS numpy was linked against elsewhere (opening it again shares it)
        with open("/proc/self/maps") as maps:
            candidates += sorted({line.split()[-1] for line in maps
                                  if "openblas" in line.lower()
                                  and line.split()[-1].startswith("/")})
    except OSError:
        pass
    for path in candidates:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for set_name, get_name in _BLAS_SYMBOLS:
            if hasattr(lib, set_name) and hasattr(lib, get_name):
                setter, getter = getattr(lib, set_name), getattr(lib, get_name)
                setter.argtypes, setter.restype = [ctypes.c_int], None
                getter.argtypes, getter.restype = [], ctypes.c_int
                _blas_api = (setter, getter)
                return _blas_api
    return _blas_api


class limited_threads:
    """Context manager: at most ``n`` OpenBLAS and OpenCV worker threads inside, the previous
    counts restored on exit (``n <= 0``: change nothing). Without an OpenBLAS that exposes
    ``openblas_set_num_threads`` only OpenCV is limited (set ``OPENBLAS_NUM_THREADS=1``)."""

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self._saved: Optional[tuple] = None

    def __enter__(self) -> "limited_threads":
        if self.n > 0:
            blas = _openblas()
            old_blas = blas[1]() if blas else None
            old_cv = cv2.getNumThreads()
            if blas and old_blas > self.n:
                blas[0](self.n)
            if old_cv > self.n:
                cv2.setNumThreads(self.n)
            self._saved = (old_blas, old_cv)
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._saved is None:
            return
        old_blas, old_cv = self._saved
        self._saved = None
        blas = _openblas()
        if blas and old_blas is not None and old_blas > self.n:
            blas[0](old_blas)
        if old_cv > self.n:
            cv2.setNumThreads(old_cv)


@dataclass
class MotionResult:
    """What a motion front end found between the previous and the current frame.

    Attributes
    ----------
    points : (N, 2) float32
        Positions in the previous frame (working size).
    disp : (N, 2) float32
        Their measured displacements.
    weights : (N,) float32
        Reliability (0 = unusable).
    motion : GlobalMotion
        RANSAC fit over them.
    violation_weights : (N,) float32, optional
        Reliability of each vector as evidence for the flow-violation map, when it differs
        from ``weights`` (the gated RBM's out-of-range readings are evidence of motion, but not
        usable by RANSAC).
    """

    points: np.ndarray
    disp: np.ndarray
    weights: np.ndarray
    motion: GlobalMotion
    violation_weights: Optional[np.ndarray] = None


#: Why a fit was refused by :func:`spans_frame` (``last_status`` reads "fallback: " + this).
SMALL_REGION = "motion seen on only a small part of the frame (an object's; camera taken as still)"


def spans_frame(result: MotionResult, shape: tuple, min_extent: float) -> bool:
    """Whether ``result``'s RANSAC inliers reach across at least ``min_extent`` of the frame's
    width or of its height (``shape`` is ``(H, W)``), as a camera's motion does.

    When only one compact region has texture (a textured object over sky, snow or a blank
    wall), its motion is the only one measured, and RANSAC fits it as the camera's: the object
    would then be the background and never found. Nothing in the frame tells a camera moving
    over such a scene from a still camera watching the object, and a background subtractor
    serves its user better by reporting the object. A fit with no inliers (a repeated frame's)
    passes. The engines then take the camera as still: a previous motion may have been a
    mixture of the object's and the blank background's readings.
    """
    inl = result.motion.inliers & (result.weights > 0)
    if not inl.any():
        return True
    pts = result.points[inl]
    h, w = shape[:2]
    span_x = float(pts[:, 0].max() - pts[:, 0].min()) / max(w - 1, 1)
    span_y = float(pts[:, 1].max() - pts[:, 1].min()) / max(h - 1, 1)
    return max(span_x, span_y) >= min_extent


def motion_snr(result: MotionResult, *, min_vectors: int = 8) -> float:
    """How far the fitted camera motion stands out of the motion vectors' disagreement with it:
    the median displacement it predicts at the vectors' positions over the robust standard
    deviation (1.4826 MAD) of their residuals; 0 without a fit or with fewer than
    ``min_vectors`` usable vectors.

    A camera moves the whole background rigidly: its motion is many times the residuals
    (panning and shaking cameras in the real set and the generated scenes: medians 9-100). Water
    or foam seen by a still camera drifts coherently enough for RANSAC to fit a "motion", but
    its vectors scatter about it by about as much (UCSD birds, bottle and surf: medians 0.5-2.2).
    """
    if not result.motion.ok:
        return 0.0
    usable = result.weights > 0
    if np.count_nonzero(usable) < min_vectors:
        return 0.0
    pts = result.points[usable].astype(np.float64)
    predicted = apply_homography(result.motion.matrix, pts) - pts
    residual = np.linalg.norm(result.disp[usable] - predicted, axis=1)
    scatter = 1.4826 * float(np.median(residual))
    return float(np.median(np.linalg.norm(predicted, axis=1))) / max(scatter, 1e-3)


def _translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _shift_of(matrix: np.ndarray, shape: tuple) -> np.ndarray:
    """The translation (3, 3) that moves the centre of an ``(H, W)`` frame as ``matrix`` does."""
    h, w = shape[:2]
    centre = np.array([[(w - 1) / 2.0, (h - 1) / 2.0]])
    return _translation(*(apply_homography(matrix, centre) - centre)[0])


def _largest_corner_shift(matrix: np.ndarray, shape: tuple) -> float:
    """How far (px) ``matrix`` moves the farthest-moved corner of an ``(H, W)`` frame."""
    h, w = shape[:2]
    return float(corner_distances(matrix, np.eye(3), width=w, height=h).max())


# Registration of a frozen model (MovingCameraEngine._registered_to_model): the largest
# correction (px, at any frame corner) it may add to the frame's motion, the smallest
# phase-correlation peak it trusts, and its corner tracking: at most this many corners of the
# model, tracked by pyramidal Lucas-Kanade (window side, pyramid levels above the base), and
# the RANSAC inlier distance (px) of the fit to them.
_MAX_REGISTRATION = 3.0
_MIN_REGISTRATION_RESPONSE = 0.05
_REGISTRATION_CORNERS = 200
_REGISTRATION_WINDOW = 15
_REGISTRATION_LEVELS = 1
_REGISTRATION_THRESHOLD = 1.0

_NONE = np.zeros((0, 2), np.float32)
#: The motion of a repeated frame: none, measured from no correspondences.
_NO_MOTION = MotionResult(_NONE, _NONE, np.zeros(0, np.float32), GlobalMotion.identity(0))


class MovingCameraEngine(Engine):
    """Shared per-frame logic; subclasses implement :meth:`_motion` (the front end).

    Parameters (keyword-only; ``bgsub methods`` prints the meaning of each, except
    ``min_contrast``, ``scene_cut`` and ``cut_support``, which only Python callers set)
    ----------
    work_width : int
        Frames wider than this are processed resized to it (0 = input size), keeping a height
        of at least ``MIN_WORK_WIDTH`` (or the frame's own).
    motion_model, ransac_threshold : RANSAC camera motion (:func:`fit_global_motion`).
    background : BackgroundParams
        The compensated background model's parameters.
    flow_boost, flow_damp, violation_threshold, violation_noise : flow-violation fusion
        (:func:`fuse_masks`, :func:`flow_violation_map`; ``violation_noise`` is its
        ``noise_scale``).
    threshold, min_area, close, fill_holes : the final decision and clean-up
        (:func:`clean_mask`).
    min_contrast : float
        Frames whose gray standard deviation is below this are "blank or textureless".
    scene_cut, cut_support : float
        A frame where more than ``scene_cut`` of the pixels with history differ from the
        compensated background while fewer than ``cut_support`` of the motion vectors agree
        with the fitted motion (or more than 80 % differ) restarts the model.
    heal_below : float
        Differences where the violation map is below this are learnt at the normal rate.
    learning_rate : float
        The background model's rate when :meth:`apply` is given none (negative: its own;
        see :meth:`CompensatedBackground.update`).
    still_below : float
        Motion that moves no frame corner by more than this (working px) is held back and
        added to the next frame's, so the model is warped only once the total reaches it (a
        still camera's reading noise; 0 = every frame).
    min_extent : float
        A fitted motion whose inliers span less than this fraction of the frame's width and of
        its height is refused as an object's (:func:`spans_frame`), and the camera is taken as
        still for that frame (0 = never refused).
    still_cue : float
        Weight of :func:`still_in_image_map` (an object the camera follows stays put in the
        image); the violation map is the larger of the two (0 = flow violation only).
    still_model, still_snr, still_window : the still-camera switch. A
        :class:`SampleBackground` that is never warped runs beside the compensated model; the
        camera is taken as still, and that model's score used, while over the last
        ``still_window`` frames (medians) it calls less than ``still_model`` of the frame
        foreground and the fitted motion is less than ``still_snr`` times the robust scatter
        of the motion vectors about it (:func:`motion_snr`). Both are needed: a pan makes the
        still model fail, and a shaking camera's motion is rigid however small (``still_model
        = 0``: off).
    threads : int
        OpenBLAS and OpenCV worker threads while a frame is processed (:class:`limited_threads`;
        0 = leave them as configured).
    overlap : int
        1: while a frame's motion is measured, a second thread updates the background model
        with the previous frame and prepares this frame for the next pair (:meth:`_prepare`);
        0: all in the calling thread. The masks are the same either way.

    Attributes
    ----------
    last_status : str
        ``"ok"`` or ``"fallback: <reason>"`` for the last frame.
    camera_still : bool
        Whether the last frame was taken as seen by a still camera (``still_model``).
    """

    name = "moving-camera"

    def __init__(
        self,
        *,
        work_width: int = 320,
        motion_model: str = "homography",
        ransac_threshold: float = 1.5,
        background: Optional[BackgroundParams] = None,
        flow_boost: float = 0.8,
        flow_damp: float = 0.8,
        violation_threshold: float = 1.5,
        threshold: float = 1.0,
        min_area: int = 30,
        close: int = 9,
        min_contrast: float = 4.0,
        scene_cut: float = 0.5,
        heal_below: float = 0.25,
        cut_support: float = 0.35,
        threads: int = 1,
        violation_noise: float = 0.0,
        fill_holes: int = 5000,
        overlap: int = 1,
        still_cue: float = 1.0,
        learning_rate: float = -1.0,
        min_extent: float = 0.33,
        still_below: float = 0.25,
        still_model: float = 0.15,
        still_snr: float = 4.0,
        still_window: int = 9,
    ) -> None:
        if 0 < work_width < MIN_WORK_WIDTH:
            # Refused here, before any output is opened, rather than at the first frame.
            raise InputError(f"{self.name}: parameter 'work_width' must be 0 (the input's width) "
                             f"or at least {MIN_WORK_WIDTH}, not {work_width!r}")
        self.work_width = int(work_width)
        self.motion_model = motion_model
        self.ransac_threshold = float(ransac_threshold)
        self.bg = CompensatedBackground(background or BackgroundParams())
        self.flow_boost = float(flow_boost)
        self.flow_damp = float(flow_damp)
        self.violation_threshold = float(violation_threshold)
        self.violation_noise = float(violation_noise)
        self.threshold = float(threshold)
        self.min_area = int(min_area)
        self.close_size = int(close)  # (not `close`: that is the method)
        self.fill_holes = int(fill_holes)
        self.min_contrast = float(min_contrast)
        self.scene_cut = float(scene_cut)
        self.heal_below = float(heal_below)
        self.cut_support = float(cut_support)
        self.threads = int(threads)
        self.overlap = int(overlap)
        self.still_cue = float(still_cue)
        self.learning_rate = float(learning_rate)
        self.min_extent = float(min_extent)
        self.still_below = float(still_below)
        self.still_model = float(still_model)
        self.still_snr = float(still_snr)
        self.still_bg = SampleBackground() if self.still_model > 0 else None
        # (fraction the still model calls foreground, motion_snr) of the last frames.
        self.still_window = max(int(still_window), 1)
        self._still_votes: collections.deque = collections.deque(maxlen=self.still_window)
        self.camera_still = False
        self.last_status = "ok"
        self._worker: Optional[concurrent.futures.ThreadPoolExecutor] = None
        # The previous frame as the front end keeps it (see _frame_data), working size.
        self._prev: Any = None
        self._prev_gray: Optional[np.ndarray] = None
        # The background update of the last frame, (frame, learn_slowly, rate): deferred to the
        # next frame, where it runs alongside the motion front end (see _alongside).
        self._pending: Optional[tuple] = None
        self._prev_motion: Optional[np.ndarray] = None  # last good (3, 3)
        self._last: Optional[MotionResult] = None
        self._last_matrix: Optional[np.ndarray] = None  # what the last frame applied (working size)
        self._last_flow: Any = None  # the front end's last dense readout, if any (debug views)
        self._last_frame: Optional[np.ndarray] = None
        self._last_mask: Optional[np.ndarray] = None
        self._in_shape: Optional[tuple] = None  # the input frames' shape, (H, W) or (H, W, 3)
        self._window: Optional[np.ndarray] = None  # Hanning window of _registered_to_model
        self._unapplied = np.eye(3)  # motion held back by still_below (see _to_apply)

    # ------------------------------------------------------------------ sizes

    def _work_size(self, w: int, h: int) -> tuple:
        if self.work_width <= 0 or w <= self.work_width:
            return w, h
        # A wide, flat frame keeps a height of MIN_WORK_WIDTH (or its own, if less) rather than
        # shrinking below what a patch grid can read.
        scale = max(self.work_width / w, min(1.0, MIN_WORK_WIDTH / h))
        return max(1, int(round(w * scale))), max(1, int(round(h * scale)))

    def _to_work(self, image: np.ndarray) -> np.ndarray:
        h, w = image.shape[:2]
        ww, wh = self._work_size(w, h)
        if (ww, wh) == (w, h):
            return image
        return cv2.resize(image, (ww, wh), interpolation=cv2.INTER_AREA)

    def _to_input(self, mask: np.ndarray) -> np.ndarray:
        h, w = self._in_shape[:2]
        if mask.shape == (h, w):
            return mask
        up = cv2.resize(mask, (w, h), interpolation=cv2.INTER_LINEAR)
        return np.where(up > 127, 255, 0).astype(np.uint8)

    # ------------------------------------------------------------------ the front end

    def _check_size(self, gray: np.ndarray) -> None:
        """Refuse a stream whose (working-size) frames the front end cannot read at all;
        called on the first frame, before any mask is returned."""

    @abstractmethod
    def _motion(self, prev: Any, cur: Any, prior: Optional[np.ndarray]) -> MotionResult:
        """The camera motion from the previous frame to the current one, given as
        :meth:`_frame_data` made them (the front end each engine brings)."""

    def _frame_data(self, gray: np.ndarray) -> Any:
        """What the front end keeps of a frame (``gray``: (h, w) uint8, working size, not
        modified later); cheap: the expensive part goes to :meth:`_prepare`."""
        return gray

    def _prepare(self, data: Any) -> None:
        """Work on a frame that only the *next* pair needs (it is that pair's first frame),
        done in place on ``data`` while this frame's motion is measured (``overlap``)."""

    def _fit(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
             shape: tuple) -> GlobalMotion:
        return fit_global_motion(points, points + disp, weights=weights, model=self.motion_model,
                                 threshold=self.ransac_threshold,
                                 frame_size=(shape[1], shape[0]))

    # ------------------------------------------------------------------ Engine API

    @opencv_keywords
    def apply(self, image: np.ndarray, fgmask: Optional[np.ndarray] = None,
              learning_rate: float = -1.0) -> np.ndarray:
        image = check_frame(image, shape=self._in_shape)
        rate = check_learning_rate(learning_rate, default=self.learning_rate)
        check_fgmask(fgmask, image.shape[:2])
        self._in_shape = image.shape
        with limited_threads(self.threads):
            work = self._to_work(image)
            if work is image:
                # The model keeps the frame past this call (the previous frame of the next pair,
                # the deferred update): not the caller's buffer, which a reading loop may reuse.
                work = image.copy()
            gray = work if work.ndim == 2 else cv2.cvtColor(work, cv2.COLOR_BGR2GRAY)
            mask = self._step(work, gray, rate)
        self._last_frame, self._last_mask = work, mask
        out = self._to_input(mask)
        if fgmask is not None:
            fgmask[...] = out
            return fgmask
        return out

    def _step(self, work: np.ndarray, gray: np.ndarray, rate: float) -> np.ndarray:
        """One frame at the working size: the steps of the module docstring. ``work`` is the
        frame (BGR or gray), ``gray`` its gray image, ``rate`` the checked learning rate."""
        empty = np.zeros(gray.shape, np.uint8)
        self._last = None
        self._last_matrix = None
        if float(cv2.meanStdDev(gray)[1][0, 0]) < self.min_contrast:
            # Blank or textureless frame: no motion can be measured; keep the model as it is.
            self._finish_update()
            self.last_status = "fallback: blank or textureless frame"
            return empty
        if self._prev is None:
            self._check_size(gray)
            self._restart(work, gray)
            self._last_matrix = np.eye(3)  # no previous frame (as samples' camera_motion.npy)
            self.last_status = "ok"
            return empty

        # 2-3. The camera's motion, while the other thread finishes the last frame's update.
        cur = self._frame_data(gray)
        with self._alongside(self._finish_update, lambda: self._prepare(cur)):
            if np.array_equal(gray, self._prev_gray):
                # A repeated frame (a frame-rate conversion's duplicate, a paused stream): the
                # camera did not move, whatever a noisy reading would say; a frozen model
                # (learning_rate=0) would otherwise drift by that reading's error.
                result = _NO_MOTION
                self._last_flow = None
            else:
                result = self._motion(self._prev, cur, self._prev_motion)
        small = (self.min_extent > 0 and result.motion.ok
                 and not spans_frame(result, gray.shape, self.min_extent))
        if small:
            result = dataclasses.replace(result, motion=GlobalMotion.identity(
                len(result.points), ok=False, reason=SMALL_REGION))
        self._last = result
        status = "ok"
        matrix = result.motion.matrix
        if not result.motion.ok:
            status = f"fallback: {result.motion.reason}"
            matrix = self._prev_motion if self._prev_motion is not None else np.eye(3)
            if small:
                matrix = np.eye(3)  # see spans_frame
        applied = self._to_apply(matrix, gray, register=rate == 0.0 and result.motion.ok)

        # 4. The background compared in this frame's coordinates, while the other thread
        # makes the violation map.
        violation: list = []
        prev_gray = self._prev_gray
        # The refused region's vectors are one consistent motion, not noise around the camera's:
        # their spread must not raise the violation threshold.
        noise = 0.0 if small else self.violation_noise
        with self._alongside(lambda: violation.append(
                self._violation_map(result, matrix, prev_gray, gray, noise))):
            self.bg.warp(applied, sharp=rate == 0.0)
            if rate == 0.0:
                self._forget_unseen(applied)
            score = self.bg.score(work)
        if self._is_scene_cut(score, result):
            self._restart(work, gray, cur)
            self.last_status = "fallback: scene cut"
            return empty
        self._last_matrix = applied
        violation = violation[0]
        still_score = self._judge_still(work, result) if self.still_bg is not None else None
        if still_score is not None:
            score = still_score
        mask = fuse_masks(score, violation, flow_boost=self.flow_boost, flow_damp=self.flow_damp,
                          threshold=self.threshold, min_area=self.min_area, close=self.close_size,
                          fill_holes=self.fill_holes)

        # The update is deferred to the next frame (its other thread).
        learn_slowly = mask > 0
        if violation is not None:
            # Where the local motion confidently agrees with the camera's, a background
            # difference is a ghost (background uncovered since the model learnt an object
            # there): let it heal at the normal rate.
            learn_slowly &= ~(violation < self.heal_below)
        self._pending = (work, learn_slowly, rate)
        self._prev = cur
        self._prev_gray = gray
        if result.motion.ok:
            self._prev_motion = result.motion.matrix
        self.last_status = status
        return mask

    def _to_apply(self, matrix: np.ndarray, gray: np.ndarray, *, register: bool) -> np.ndarray:
        """The motion to warp the background model by, given this frame's ``matrix`` (3, 3):
        it with what earlier frames left unapplied, registered to the model when ``register``
        (a frozen model), or the identity while that total moves no frame corner by
        ``still_below`` px (kept for the next frame).

        A still camera's readings scatter by hundredths of a pixel: warping by each resamples
        (blurs) the model every frame. Held back and added up instead, a slow pan (0.2 px per
        frame at the working size) still moves the model, in steps.
        """
        total = matrix @ self._unapplied
        if register:
            if self._below_still(total, gray.shape):
                # A frozen model must not collect the fit's sub-pixel rotation and zoom noise
                # (the registration below corrects only the shift when the model has too few
                # corners to track): a small motion is a shift.
                total = _shift_of(total, gray.shape)
            total = self._registered_to_model(total, gray)
        if self._below_still(total, gray.shape):
            self._unapplied = total
            return np.eye(3)
        self._unapplied = np.eye(3)
        return total

    def _below_still(self, matrix: np.ndarray, shape: tuple) -> bool:
        return self.still_below > 0 and _largest_corner_shift(matrix, shape) < self.still_below

    def _registered_to_model(self, matrix: np.ndarray, gray: np.ndarray) -> np.ndarray:
        """``matrix`` (3, 3) followed by the motion (moving no frame corner by more than
        ``_MAX_REGISTRATION`` px) that best registers the background model, warped by it, to
        ``gray``.

        A frozen model (learning_rate=0) is tied to the scene by nothing but the chain of
        frame-to-frame motions, whose errors add up: grbm's hundredths of a pixel per frame
        became a drift of pixels within two seconds of a pan (false foreground along every
        edge). The model is itself an image of the scene in (nearly) this frame's coordinates,
        so the frame is registered to it: phase correlation finds the shift, then corners of
        the model tracked into the frame (pyramidal Lucas-Kanade from that shift) and a RANSAC
        fit of the engine's motion model to them correct the rest, rotation and zoom included
        (a shift alone let grbm's per-frame zoom and rotation noise add up to 0.8 px at the
        corners within 35 frozen frames of a 3.3 px/frame pan). Objects in the frame are the
        fit's outliers. When the corners give no fit (a flat or changed scene), the shift alone
        is applied. Done only for a frozen model: two whole-frame FFTs and a few hundred tracks.
        """
        h, w = gray.shape
        mean = self.bg.mean
        model = mean[:, :, 0] if mean.shape[2] == 1 else cv2.cvtColor(mean, cv2.COLOR_BGR2GRAY)
        warped = cv2.warpPerspective(model, matrix, (w, h), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        # (uint8 for the tracker, taken first: phaseCorrelate windows its inputs in place.)
        warped8 = np.clip(warped + np.float32(0.5), 0, 255).astype(np.uint8)
        if self._window is None or self._window.shape != (h, w):
            self._window = cv2.createHanningWindow((w, h), cv2.CV_32F)
        (dx, dy), response = cv2.phaseCorrelate(warped, gray.astype(np.float32), self._window)
        if response < _MIN_REGISTRATION_RESPONSE or np.hypot(dx, dy) > _MAX_REGISTRATION:
            dx = dy = 0.0  # no clear peak (a textureless or changed scene): keep the estimate
        residual = self._model_residual(warped8, matrix, gray, (dx, dy))
        if residual is None:
            return _translation(dx, dy) @ matrix if (dx, dy) != (0.0, 0.0) else matrix
        return residual @ matrix

    def _model_residual(self, model: np.ndarray, matrix: np.ndarray, gray: np.ndarray,
                        shift: tuple) -> Optional[np.ndarray]:
        """The motion (3, 3) from ``model`` (the model's gray mean warped by ``matrix``, (h, w)
        uint8) to ``gray``: corners of the model where it has a history, tracked into the
        frame starting from ``shift``, and the engine's motion model fitted to them by RANSAC.
        None when too few corners agree or the fit moves a frame corner by more than
        ``_MAX_REGISTRATION`` px."""
        h, w = gray.shape
        seen = cv2.warpPerspective(self.bg.age, matrix, (w, h), flags=cv2.INTER_NEAREST,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0) >= 1.0
        seen = cv2.erode(seen.astype(np.uint8), np.ones((7, 7), np.uint8))
        pts = cv2.goodFeaturesToTrack(model, maxCorners=_REGISTRATION_CORNERS, qualityLevel=0.01,
                                      minDistance=8, blockSize=7, mask=seen)
        if pts is None or len(pts) < 12:
            return None
        start = (pts + np.float32(shift)).astype(np.float32)
        side = (_REGISTRATION_WINDOW, _REGISTRATION_WINDOW)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)
        found, status, _ = cv2.calcOpticalFlowPyrLK(model, gray, pts, start, winSize=side,
                                                    maxLevel=_REGISTRATION_LEVELS, criteria=crit,
                                                    flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        fit = fit_global_motion(pts.reshape(-1, 2), found.reshape(-1, 2),
                                weights=status.ravel().astype(np.float32),
                                model=self.motion_model, threshold=_REGISTRATION_THRESHOLD,
                                frame_size=(w, h))
        if not fit.ok or _largest_corner_shift(fit.matrix, gray.shape) > _MAX_REGISTRATION:
            return None
        return fit.matrix

    def _forget_unseen(self, applied: np.ndarray) -> None:
        """After a frozen model's warp by ``applied``: pixels that the previous frame saw only in
        part (their source lies beyond its border, filled by replicating the edge) have no
        history, so that :meth:`CompensatedBackground.update` gives them this frame.

        The warp interpolates the age, so a pixel half beyond the border inherits half of its
        neighbour's: at 1 or more it counts as learnt, and a frozen model never learns it again.
        On a pan with a slow sideways drift, each new row or column then kept the replicated
        edge: streaks along the border the camera moves towards (generated pan, seed 2, 76
        frozen frames: 6.7 % of the frame false foreground at the end, 1.6 % without them).
        """
        if self.bg.age is None or np.array_equal(applied, np.eye(3)):
            return
        h, w = self.bg.age.shape
        inside = cv2.warpPerspective(np.ones((h, w), np.float32), applied, (w, h),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                     borderValue=0)
        self.bg.age[inside < 0.999] = 0.0

    def _violation_map(self, result: MotionResult, matrix: np.ndarray, prev_gray: np.ndarray,
                       gray: np.ndarray, noise: float) -> Optional[np.ndarray]:
        """``(h, w) float32`` in [0, 1]: the evidence that a pixel moves otherwise than the
        camera (``matrix``): the flow violation of ``result``'s vectors (``noise``: the
        threshold's robust-sigma multiple) and the still-in-image cue of the two gray frames,
        whichever is larger. None when the fusion ignores it."""
        if self.flow_boost == 0.0 and self.flow_damp == 0.0:
            return None
        weights = result.weights if result.violation_weights is None else result.violation_weights
        v = flow_violation_map(result.points, result.disp, matrix, weights=weights,
                               shape=gray.shape, threshold=self.violation_threshold,
                               noise_scale=noise)
        if self.still_cue > 0:
            # Either kind of motion evidence counts: the cue is near 0 where it has none (a
            # still camera, the background), so it never lowers the flow's.
            still = still_in_image_map(prev_gray, gray, matrix)
            still *= np.float32(self.still_cue)
            np.maximum(v, still, out=v)
        return v

    def _judge_still(self, work: np.ndarray, result: MotionResult) -> Optional[np.ndarray]:
        """Whether the camera is taken as still for this frame (``camera_still``), given the
        frame at the working size and its motion ``result``: the still model's ``(h, w)
        float32`` score of it if so, else None."""
        snr = motion_snr(result)
        snrs = [v[1] for v in self._still_votes] + [snr]
        if np.median(snrs[-self.still_window:]) >= self.still_snr:
            # A rigid motion: the camera moves whatever the still model says. Not scoring it
            # saves ~1 ms a frame; the frame counts as one the still model does not explain.
            self._still_votes.append((1.0, snr))
            self.camera_still = False
            return None
        score = self.still_bg.score(work)
        fraction = float(np.count_nonzero(score > 1.0)) / score.size
        self._still_votes.append((fraction, snr))
        fractions = np.median([v[0] for v in self._still_votes])
        self.camera_still = bool(fractions < self.still_model)
        return score if self.camera_still else None

    def _is_scene_cut(self, score: np.ndarray, result: MotionResult) -> bool:
        """After compensation most of the frame still differs (a new shot) and the motion
        estimate has little support (a new shot has no consistent motion), or nearly all of it
        differs whatever the motion estimate says. Counted over the pixels with history."""
        young = self.bg.age < self.bg.params.min_age
        old = max(int(np.count_nonzero(~young)), 1)
        used = max(int(np.count_nonzero(result.weights > 0)), 1)
        support = result.motion.n_inliers / used if result.motion.ok else 0.0
        if result is _NO_MOTION:
            support = 1.0  # a repeated frame is no new shot
        changed = np.count_nonzero((score > 1.0) & ~young) / old
        return (changed > self.scene_cut and support < self.cut_support) or changed > 0.8

    def __getstate__(self) -> dict:
        # Picklable and deep-copyable like the rest of the engine: the worker thread is not
        # state, a copy makes its own when it needs one.
        state = dict(self.__dict__)
        state["_worker"] = None
        return state

    def _finish_update(self) -> None:
        """Apply the deferred background update of the last frame, if any."""
        if self._pending is not None:
            work, learn_slowly, rate = self._pending
            self._pending = None
            self.bg.update(work, learn_slowly, rate)
            if self.still_bg is not None:
                self.still_bg.update(work, learn_slowly, rate)

    @contextlib.contextmanager
    def _alongside(self, *jobs: Callable[[], None]) -> Iterator[None]:
        """``jobs`` run in order in the engine's second thread while the ``with`` body runs, or
        before the body when ``overlap`` is 0. Always joined before the block ends: the jobs
        change the engine's state, which must be settled when ``apply()`` returns or raises.
        Their error is raised unless the body raised one."""
        if self.overlap <= 0:
            for job in jobs:
                job()
            yield
            return
        if self._worker is None:
            self._worker = concurrent.futures.ThreadPoolExecutor(
                max_workers=1, thread_name_prefix=f"bgsub-{self.name}")
        future = self._worker.submit(lambda: [job() for job in jobs])
        try:
            yield
        except BaseException:
            future.exception()  # wait for it; the body's error is the one reported
            raise
        error = future.exception()
        if error is not None:
            raise error

    def close(self) -> None:
        """Stop the engine's second thread (``overlap=1``) now rather than when the engine is
        garbage-collected; a later :meth:`apply` starts it again."""
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.shutdown(wait=True)

    def _restart(self, work: np.ndarray, gray: np.ndarray, cur: Any = None) -> None:
        self._pending = None
        self.bg.reset(work)
        self.bg.update(work)
        if self.still_bg is not None:
            self.still_bg.reset(work)
            self._still_votes.clear()
            self.camera_still = False
        self._prev = cur if cur is not None else self._frame_data(gray)
        self._prev_gray = gray
        self._prev_motion = None
        self._unapplied = np.eye(3)

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
        matrix = self._last_matrix
        if matrix is None or self._in_shape is None:
            return None
        h, w = self._in_shape[:2]
        ww, wh = self._work_size(w, h)
        if (ww, wh) == (w, h):
            return matrix.copy()
        # Working-size pixel centres from the input's (cv2.resize's convention).
        sx, sy = ww / w, wh / h
        scale = np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)],
                          [0.0, 0.0, 1.0]])
        return np.linalg.solve(scale, matrix @ scale)

    def get_background_image(self) -> Optional[np.ndarray]:
        """The background model's mean in the current frame's coordinates, at the input size
        (like the input: gray or BGR uint8), or None before the first frame."""
        self._finish_update()
        model = self.still_bg if self.camera_still else self.bg
        img = model.background_image()
        if img is None or self._in_shape is None:
            return img
        return self._to_input_image(img)

    def debug_image(self) -> Optional[np.ndarray]:
        """The last frame (working size, scaled to the input) with the motion vectors drawn:
        green = RANSAC inliers, red = outliers, blue = the camera motion on a coarse grid; the
        foreground mask tints the frame magenta. ``(H, W, 3) uint8``, None before two frames."""
        if self._last_frame is None or self._last is None:
            return None
        frame = self._last_frame
        canvas = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()
        canvas = (canvas * 0.6).astype(np.uint8)
        colour = self._flow_colour(canvas.shape[:2])
        if colour is not None:
            canvas = cv2.addWeighted(canvas, 0.5, colour, 0.5, 0.0)
        if self._last_mask is not None:
            canvas[self._last_mask > 0] = (0.5 * canvas[self._last_mask > 0]
                                           + np.array([127, 0, 127])).astype(np.uint8)
        res = self._last
        h, w = canvas.shape[:2]
        scale = 3.0
        use = res.weights > 0
        inl = res.motion.inliers  # over all of res.points (GlobalMotion's contract)
        # Arrows end where the point went (drawn from the previous position).
        canvas = draw_flow_arrows(canvas, res.points[use & ~inl], res.disp[use & ~inl],
                                  scale=scale, color=(0, 0, 255), dot_color=None)
        canvas = draw_flow_arrows(canvas, res.points[use & inl], res.disp[use & inl],
                                  scale=scale, color=(0, 255, 0), dot_color=None)
        step = max(16, w // 10)
        ys, xs = np.mgrid[step // 2:h:step, step // 2:w:step]
        grid = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
        cam = apply_homography(res.motion.matrix if res.motion.ok else np.eye(3), grid) - grid
        canvas = draw_flow_arrows(canvas, grid, cam, scale=scale, color=(255, 128, 0), thickness=2,
                                  dot_color=(255, 128, 0))
        cv2.putText(canvas, self.last_status[:40], (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    (255, 255, 255), 1, cv2.LINE_AA)
        return self._to_input_image(canvas)

    def _flow_colour(self, shape: tuple) -> Optional[np.ndarray]:
        """A colour-coded (Middlebury wheel) picture of the local motion, or None."""
        return None

    def _to_input_image(self, img: np.ndarray) -> np.ndarray:
        h, w = self._in_shape[:2]
        if img.shape[:2] == (h, w):
            return img
        return cv2.resize(img, (w, h), interpolation=cv2.INTER_LINEAR)


class CompensatedEngine(MovingCameraEngine):
    """Classical front end: Shi-Tomasi corners + pyramidal Lucas-Kanade + forward-backward check.

    Parameters (keyword-only; with those of :class:`MovingCameraEngine`)
    ----------
    max_corners, corner_quality, min_distance : ``cv2.goodFeaturesToTrack``'s corners per frame
        (``corner_quality`` and ``min_distance`` are set from Python only).
    lk_window, lk_levels : ``cv2.calcOpticalFlowPyrLK``'s window side and pyramid levels.
    fb_threshold : float
        Tracks whose forward-backward error exceeds this (px) are dropped.
    """

    name = "compensated"

    def __init__(self, *, max_corners: int = 400, corner_quality: float = 0.01,
                 min_distance: int = 8, lk_window: int = 21, lk_levels: int = 3,
                 fb_threshold: float = 1.0, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.max_corners = int(max_corners)
        self.corner_quality = float(corner_quality)
        self.min_distance = int(min_distance)
        self.lk_window = int(lk_window)
        self.lk_levels = int(lk_levels)
        self.fb_threshold = float(fb_threshold)

    def _frame_data(self, gray: np.ndarray) -> "_LKFrame":
        return _LKFrame(gray)

    def _prepare(self, data: "_LKFrame") -> None:
        data.corners = self._corners(data.gray)

    def _corners(self, gray: np.ndarray) -> Optional[np.ndarray]:
        """Shi-Tomasi corners of ``gray``: ``(N, 1, 2) float32`` or None."""
        return cv2.goodFeaturesToTrack(gray, maxCorners=self.max_corners,
                                       qualityLevel=self.corner_quality,
                                       minDistance=self.min_distance, blockSize=7)

    def _motion(self, prev: "_LKFrame", cur: "_LKFrame",
                prior: Optional[np.ndarray]) -> MotionResult:
        prev_gray, gray = prev.gray, cur.gray
        pts = prev.corners if prev.corners is not None else self._corners(prev_gray)
        if pts is None or len(pts) < 4:
            empty = np.zeros((0, 2), np.float32)
            return MotionResult(empty, empty, np.zeros(0, np.float32),
                                GlobalMotion.identity(0, ok=False, reason="too few corners"))
        pts = pts.reshape(-1, 1, 2).astype(np.float32)
        win = (self.lk_window, self.lk_window)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)
        flags = 0
        guess = None
        if prior is not None:
            # Start the tracker where the camera's last motion predicts: fast pans stay in range.
            guess = apply_homography(prior, pts.reshape(-1, 2)).astype(np.float32).reshape(-1, 1, 2)
            flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        nxt, st, _ = cv2.calcOpticalFlowPyrLK(prev_gray, gray, pts, guess, winSize=win,
                                              maxLevel=self.lk_levels, criteria=crit, flags=flags)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(gray, prev_gray, nxt, pts.copy(), winSize=win,
                                                maxLevel=self.lk_levels, criteria=crit,
                                                flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        fb = np.hypot(*(back - pts).reshape(-1, 2).T)
        good = (st.ravel() == 1) & (st2.ravel() == 1) & (fb < self.fb_threshold)
        p = pts.reshape(-1, 2)
        d = (nxt - pts).reshape(-1, 2)
        weights = good.astype(np.float32)
        motion = self._fit(p, d, weights, gray.shape)
        return MotionResult(p, d, weights, motion)


@dataclass
class _LKFrame:
    """A frame as the Lucas-Kanade front end keeps it: ``gray`` (h, w) uint8 and, once
    prepared, its corners ``(N, 1, 2) float32`` (None: not found yet, or none)."""

    gray: np.ndarray
    corners: Optional[np.ndarray] = None


# The gated RBM's flow-violation evidence is dense but noisier than tracked corners: weakly
# textured object patches read the camera's motion and would damp true objects, so its engine
# leans on violation evidence to boost rather than to damp. How noisy its vectors are depends
# on the footage (sharp BMS-26 vs blurred CDnet traffic), so a violation is a disagreement of
# 0.75 px or 4 robust standard deviations of the frame's disagreements, whichever is larger
# (the same rule gives compensated nothing). With the coarsest level read to convergence its
# vectors support a homography at a tighter 1 px RANSAC threshold. Tuned on the real set
# (docs/BENCHMARKS.md, issue 4, "What was tried"). The defaults of GrbmEngine() and of
# create_engine("grbm") alike.
GRBM_TUNED = dict(ransac_threshold=1.0, flow_boost=1.5, flow_damp=0.2, violation_threshold=0.75,
                  violation_noise=4.0)


class GrbmEngine(MovingCameraEngine):
    """Gated-RBM front end: coarse-to-fine patch displacements from the factored 3-way RBM.

    Takes the parameters ``bgsub methods grbm`` lists (those of the background model as a
    :class:`BackgroundParams` ``background=``); the shared ones default to
    :data:`GRBM_TUNED` where it has them, as with ``create_engine("grbm")``.
    """

    name = "grbm"

    def __init__(self, *, model: Any = "natural", stride: int = 8, levels: int = 0,
                 max_motion: float = 32.0, min_texture: float = 0.02, max_patches: int = 0,
                 iterations: int = 1, retry_below: float = 0.6, prior_levels: int = 0,
                 search: int = 1, coarse_iterations: int = 3, finest: int = 0,
                 refine_stride: int = 16, coarser_below: float = 0.5,
                 texture_scale: float = 1e-5, contrast_floor: float = 0.005,
                 search_below: float = 0.9, coarser_stride: int = 16,
                 start_tolerance: float = 0.015, converged: float = 0.1,
                 start_model: str = "translation", **kwargs: Any) -> None:
        super().__init__(**{**GRBM_TUNED, **kwargs})
        from bgsub.model.rbm import load_model

        # A name or path, a GatedRBM, or any patch-motion model with the same contract (see
        # bgsub.motion.flowfield.patch_motion).
        self.model = model if hasattr(model, "patch_motion") else load_model(model)
        if (contrast_floor > 0 and getattr(self.model, "normalization", None) == "contrast"
                and contrast_floor != self.model.contrast_floor):
            # A copy with its own readout caches: the model object may be shared (a caller's).
            self.model = dataclasses.replace(self.model, contrast_floor=float(contrast_floor),
                                             _cache={})
        self.texture_scale = float(texture_scale)
        self.stride = int(stride)
        self.levels = int(levels) if levels > 0 else None
        self.max_motion = float(max_motion)
        self.min_texture = float(min_texture)
        self.max_patches = int(max_patches) if max_patches > 0 else None
        self.iterations = max(1, int(iterations))
        self.retry_below = float(retry_below)
        self.prior_levels = int(prior_levels)
        self.search = max(0, int(search))
        self.search_below = float(search_below)
        self.start_tolerance = max(0.0, float(start_tolerance))
        self.start_model = str(start_model)
        self.coarse_iterations = max(1, int(coarse_iterations))
        self.converged = max(0.0, float(converged))
        self.finest = max(0, int(finest))
        self.refine_stride = int(refine_stride) if refine_stride > 0 else None
        self.coarser_below = float(coarser_below)
        self.coarser_stride = int(coarser_stride) if coarser_stride > 0 else self.stride
        if not hasattr(self.model, "patch_motion"):
            # Per-model constants of the readout, once here rather than in the first frame.
            from bgsub.motion.flowfield import model_range
            from bgsub.model.readout import precompute

            precompute(self.model, max_disp=model_range(self.model))

    def _frame_data(self, gray: np.ndarray) -> FramePyramid:
        return FramePyramid(gray)

    def _prepare(self, data: FramePyramid) -> None:
        if not hasattr(self.model, "patch_motion"):
            prepare_first_frame(data, self._flow_config(self.levels, self.finest),
                                model=self.model)

    def _flow_config(self, levels: Optional[int], finest: int,
                     stride: Optional[int] = None) -> FlowConfig:
        """The :class:`FlowConfig` of :func:`estimate_flow` and :func:`prepare_first_frame`."""
        return FlowConfig(stride=self.stride if stride is None else stride, levels=levels or 0,
                          max_motion=self.max_motion, min_texture=self.min_texture,
                          texture_scale=self.texture_scale, max_patches=self.max_patches or 0,
                          iterations=self.iterations, finest=finest,
                          refine_stride=self.refine_stride or 0,
                          start_tolerance=self.start_tolerance, search=self.search,
                          coarse_iterations=self.coarse_iterations,
                          search_below=self.search_below, start_model=self.start_model,
                          converged=self.converged, warn_range=False)

    def _read(self, prev: FramePyramid, cur: FramePyramid, prior: Optional[np.ndarray],
              finest: int, stride: Optional[int] = None) -> tuple:
        """``(flow, motion, support)``: the readout with its final level ``finest`` (on a grid
        of ``stride`` working-size pixels, default the engine's), the camera motion fitted to
        it and the fraction of its usable patches that agree with it."""
        levels = self.levels
        if prior is not None and levels is None:
            # The previous frame's motion predicts this one to within a few pixels: two levels
            # cover that; a camera that changes course fails the support test and is retried
            # with the full pyramid.
            levels = self.prior_levels if self.prior_levels > 0 else None
        # (warn_range: max_motion only plans the pyramid here; beyond its reach the engine
        # reads from the previous frame's motion, and a poorly supported start retries coarser.)
        flow = estimate_flow(prev, cur, self._flow_config(levels, finest, stride),
                             model=self.model, prior=prior)
        motion = self._fit(flow.centres, flow.disp, flow.weights, cur.shape)
        used = max(int(np.count_nonzero(flow.weights > 0)), 1)
        return flow, motion, (motion.n_inliers / used if motion.ok else 0.0)

    def _flow_colour(self, shape: tuple) -> Optional[np.ndarray]:
        flow = self._last_flow
        if flow is None:
            return None
        dense = dense_from_patches(flow, shape=shape, patch_size=int(self.model.patch_size))
        return flow_to_color(dense, max_magnitude=max(4.0, self.max_motion / 4))

    @staticmethod
    def _vweights(flow) -> np.ndarray:
        """Violation evidence: valid readings, plus textured patches whose residual is beyond
        the model's range (they moved relative to the camera by more than it can see)."""
        w = flow.weights.copy()
        if flow.beyond is not None:
            w[flow.beyond] = flow.texture[flow.beyond]
        return w

    def _check_size(self, gray: np.ndarray) -> None:
        patch = int(getattr(self.model, "patch_size", 0) or 0)
        if min(gray.shape) < patch:
            # Every frame would fall back to "no correspondences": a model for other footage.
            h, w = gray.shape
            raise InputError(f"frames of {w}x{h} (working size) are smaller than the model's "
                             f"{patch}x{patch} patches")

    def _motion(self, prev: FramePyramid, cur: FramePyramid,
                prior: Optional[np.ndarray]) -> MotionResult:
        flow, motion, support = self._read(prev, cur, prior, self.finest)
        finest = self.finest
        # Low support at the final level means the model cannot read it (motion blur, heavy
        # compression: on CDnet traffic's shaking frames) while a reduced image, where the blur
        # is halved, reads consistently: try one or two levels coarser and keep the reading
        # the most patches agree with. Those re-reads use a sparser grid (coarser_stride): as
        # dense in the half-size image's own pixels as the first readout's in the full one,
        # which also reads better there (real set 0.546 -> 0.562 when it was introduced) and
        # costs a quarter.
        while (support < self.coarser_below and finest < self.finest + 2
               and finest + 1 < flow.levels):
            finest += 1
            coarser = self._read(prev, cur, prior, finest, self.coarser_stride)
            if coarser[1].ok and (coarser[2] > support or not motion.ok):
                flow, motion, support = coarser
        weights = flow.weights
        self._last_flow = flow
        first = MotionResult(flow.centres, flow.disp, weights, motion, self._vweights(flow))
        reduced = self.levels is None and self.prior_levels > 0
        if prior is None or not reduced or (motion.ok and support >= self.retry_below):
            return first
        # The prior may be wrong (the camera changed course): also try from scratch and keep
        # the reading more patches agree with.
        flow, retry, _ = self._read(prev, cur, None, self.finest)
        second = MotionResult(flow.centres, flow.disp, flow.weights, retry, self._vweights(flow))
        if second.motion.ok and (not motion.ok or second.motion.n_inliers > motion.n_inliers):
            self._last_flow = flow
            return second
        return first


# ---------------------------------------------------------------------- registration

_COMMON = {
    "work_width": Param(320, "process frames resized to this width (0 = input size, else at "
                             f"least {MIN_WORK_WIDTH}), but never to a height below "
                             f"{MIN_WORK_WIDTH}; the mask is returned at the input size",
                        low=0),
    "motion_model": Param("homography", "camera motion model fitted by RANSAC",
                          choices=MODELS),
    "ransac_threshold": Param(1.5, "RANSAC inlier distance in working-size pixels", above=0),
    "alpha": Param(0.1, "background learning rate of pixels with a long history", low=0, high=1),
    "fg_alpha": Param(0.01, "learning rate of pixels called foreground (lets ghosts fade)",
                      low=0, high=1),
    "k_sigma": Param(2.0, "foreground beyond this many background standard deviations ...", low=0),
    "min_diff": Param(10.0, "... and this many gray levels (0-255)", low=0),
    "envelope": Param(1, "a pixel is compared with the background's min/max over this "
                         "neighbourhood (3 tolerates a 1-px misregistration)",
                      low=1, high=31),
    "min_age": Param(1, "frames of history a pixel needs before a background difference "
                        "can make it foreground (see young_score)", low=0),
    "young_score": Param(0.6, "score of pixels younger than min_age (below 1: foreground only "
                              "where local motion evidence boosts it; 0 = never)", low=0, high=1),
    "flow_boost": Param(0.8, "where local motion violates the camera's, the background "
                             "difference is multiplied by up to 1 + this", low=0),
    "flow_damp": Param(0.8, "where local motion agrees with the camera's, it is multiplied by "
                            "down to 1 - this (0 and flow_boost 0 = background model only)",
                            low=0, high=1),
    "violation_threshold": Param(1.5, "disagreement with the camera motion (px) that counts as "
                                      "a violation", low=0),
    "violation_noise": Param(0.0, "... or this many robust standard deviations of the local "
                                  "vectors' disagreement, if more (0 = fixed threshold)", low=0),
    "min_area": Param(30, "blobs smaller than this (working-size pixels) are dropped", low=0),
    "close": Param(9, "morphological closing size (0 or 1 = none)", low=0, high=99),
    "fill_holes": Param(5000, "holes enclosed by a foreground blob, up to this many "
                              "working-size pixels, are filled (0 = none)", low=0),
    "threshold": Param(1.0, "foreground where the fused score exceeds this (lower = more "
                            "foreground)", low=0),
    "threads": Param(1, "BLAS and OpenCV worker threads while a frame is processed (0 = as "
                        "configured; more threads are slower for these small frames)", low=0),
    "overlap": Param(1, "1 = update the background and prepare the frame for the next pair "
                        "in a second thread while the motion is measured (same masks, faster "
                        "on 2 or more cores); 0 = one thread", low=0, high=1),
    "min_extent": Param(0.33, "a camera motion must be seen across at least this fraction of "
                              "the frame's width or height; one seen only on a smaller region "
                              "(a textured object over a blank background) is taken as the "
                              "object's, and the camera as still (0 = off)", low=0, high=1),
    "still_below": Param(0.25, "camera motion that moves no frame corner by more than this "
                              "(working px) is held back and added to the next frame's: a still "
                              "camera's sub-pixel reading noise would resample (blur) the model "
                              "every frame (0 = warp every frame)", low=0),
    "still_model": Param(0.15, "take the camera as still, and use a never-warped sample "
                               "background model (water, foam, leaves), while that model calls "
                               "less than this fraction of the frame foreground ... (0 = off)",
                         low=0, high=1),
    "still_snr": Param(4.0, "... and the fitted camera motion is less than this many times the "
                            "scatter of the motion vectors about it (no rigid motion stands "
                            "out)", low=0),
    "still_window": Param(9, "... both as medians over this many frames", low=1),
    "still_cue": Param(1.0, "weight of the evidence that a pixel stays put in the image while "
                            "the camera moves (an object the camera follows; 0 = off)",
                       low=0, high=1),
    "learning_rate": LEARNING_RATE,
    "heal_below": Param(0.25, "background differences where the local motion agrees with the "
                              "camera (violation below this) are learnt at the normal rate "
                              "(ghost healing)", low=0),
}


def _split(kwargs: dict) -> dict:
    bg = BackgroundParams(alpha=kwargs.pop("alpha"), fg_alpha=kwargs.pop("fg_alpha"),
                          k_sigma=kwargs.pop("k_sigma"), min_diff=kwargs.pop("min_diff"),
                          envelope=kwargs.pop("envelope"), min_age=kwargs.pop("min_age"),
                          young_score=kwargs.pop("young_score"))
    kwargs["background"] = bg
    return kwargs


def _with_defaults(common: dict, **overrides: Any) -> dict:
    """``common`` with some defaults replaced (same help text and bounds)."""
    out = dict(common)
    for name, value in overrides.items():
        out[name] = dataclasses.replace(out[name], default=value)
    return out


_GRBM_COMMON = _with_defaults(_COMMON, **GRBM_TUNED)


@register_engine(
    "grbm",
    "moving camera: gated-RBM patch motion (coarse to fine) + RANSAC camera motion + "
    "compensated background model (the paper's method)",
    params={
        "model": Param("natural", "gated RBM: a shipped model name or an .npz path"),
        "stride": Param(8, "patch grid step in working-size pixels", low=1),
        "levels": Param(0, "pyramid levels (0 = enough for max_motion)", low=0),
        "max_motion": Param(32.0, "largest camera motion per frame to plan for (working px)",
                            low=0),
        "min_texture": Param(0.02, "patches with a lower texture weight are not evaluated",
                             low=0, high=1),
        "max_patches": Param(0, "evaluate at most this many patches per level (0 = all)", low=0),
        "iterations": Param(1, "readouts at the finest level, each re-warped by the last fit "
                               "(more: a little more accurate, slower; docs/BENCHMARKS.md)",
                            low=1, high=10),
        "finest": Param(0, "pyramid level of the final readout (1 = half the working size: "
                           "faster, and better on blurry footage)", low=0),
        "refine_stride": Param(16, "patch grid step of the finest-level readouts that only "
                                   "refine the pre-warp (iterations > 1; 0 = stride): 2 x stride "
                                   "reads a quarter of the patches, ~15 % faster for the same "
                                   "accuracy", low=0),
        "coarse_iterations": Param(3, "readouts at the coarsest pyramid level, each re-warped "
                                      "by the last fit (finer levels start close and read once)",
                                      low=1, high=20),
        "converged": Param(0.1, "stop re-reading the coarsest level once a readout moved its "
                                "fitted motion by less than this many of that level's pixels "
                                "at the corners: a steady pan the previous motion predicts "
                                "reads it once, not coarse_iterations times (0 = always "
                                "coarse_iterations readouts)", low=0),
        "texture_scale": Param(1e-5, "structure-tensor eigenvalue (gray in [0, 1]) at which a "
                                     "patch's texture weight is 0.5: small = every textured "
                                     "patch counts alike, only near-flat and edge-only ones are "
                                     "down-weighted (suits blurred footage)", above=0),
        "contrast_floor": Param(0.005, "patch pairs with a lower RMS contrast (gray in [0, 1]) "
                                       "are flat and not read (0 = the model's own, 0.02 for "
                                       "the shipped models)", low=0),
        "coarser_below": Param(0.5, "when fewer than this fraction of the final readout's "
                                    "patches agree with the fitted motion (motion blur), also "
                                    "read up to two levels coarser and keep the best-supported "
                                    "(0 = never)", low=0),
        "coarser_stride": Param(16, "patch grid step (working-size pixels) of those coarser "
                                    "readouts (0 = stride): 2 x stride is as dense in a "
                                    "half-size image as stride in the full one", low=0),
        "search": Param(1, "also start the coarsest level from a (2 search + 1)^2 grid of "
                           "shifts (shaking cameras); 0 = prior and identity only", low=0, high=8),
        "search_below": Param(0.9, "with search > 0: read the grid of shifts only when fewer "
                                   "than this fraction of the coarsest patches agree with the "
                                   "better of the previous motion and no motion (1 = always; "
                                   "always on a first frame)", low=0),
        "start_tolerance": Param(0.015, "choose the coarsest level's start by photometric "
                                        "agreement: the fraction of textured pixels whose gray "
                                        "value (0-1) the next frame repeats to within this "
                                        "(0 = by the number of agreeing patches)", low=0),
        "start_model": Param("translation", "motion model fitted to each start's readout at the "
                                            "coarsest level (its few patches fit a richer "
                                            "model's zoom to noise; the re-reads that follow "
                                            "fit the full model)",
                             choices=MODELS),
        "prior_levels": Param(0, "pyramid levels used when the previous frame's motion "
                                 "predicts this one (0 = always the full pyramid)", low=0),
        "retry_below": Param(0.6, "with prior_levels > 0: when fewer than this fraction of the "
                                  "patches agree with the motion found from the previous "
                                  "frame's, also search with the full pyramid", low=0),
        **_GRBM_COMMON,
    },
)
def _make_grbm(**kwargs: Any) -> Engine:
    return GrbmEngine(**_split(kwargs))


@register_engine(
    "compensated",
    "moving camera: Lucas-Kanade corner tracks + RANSAC camera motion + compensated background "
    "model (classical baseline of grbm)",
    params={
        "max_corners": Param(400, "Shi-Tomasi corners tracked per frame", low=1, high=100_000),
        "lk_window": Param(21, "Lucas-Kanade window side (px)", low=3, high=255),
        "lk_levels": Param(3, "Lucas-Kanade pyramid levels above the base", low=0, high=10),
        "fb_threshold": Param(1.0, "forward-backward tracking error (px) above which a track "
                                   "is dropped", above=0),
        **_COMMON,
    },
)
def _make_compensated(**kwargs: Any) -> Engine:
    return CompensatedEngine(**_split(kwargs))
