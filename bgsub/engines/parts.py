"""The moving-camera engine's special behaviours, each a small part with its own state:

* :class:`SmallRegionRule`: a fitted motion seen on only a small region is an object's;
* :class:`MotionHoldBack`: motion too small to warp the model by is added to the next frame's;
* :class:`FrozenModelRegistration`: a frozen model (``learning_rate=0``) is registered to the
  frame, so the errors of the frame-to-frame motions do not add up;
* :class:`SceneCut`: a new shot restarts the model;
* :class:`BlobPersistence`: a blob new in this frame, touching nothing of the last mask, is
  dropped (one frame's flicker is not an object);
* :class:`StillCameraSwitch`: while the camera is still, a never-warped sample model replaces
  the compensated one in the fusion (water and foam defeat a mean-and-variance model, and their
  drift would be taken for a pan);
* :class:`KnownMotion`: camera motion given (an IMU, a gimbal, a previous run) replaces the fit.
"""

from __future__ import annotations

import collections
import dataclasses
import os
from typing import Any, Optional, Tuple

import cv2
import numpy as np

from bgsub.background.compensated import CompensatedBackground
from bgsub.background.fusion import persistent_blobs
from bgsub.background.sample import SampleBackground
from bgsub.engines.frontend import NO_MOTION, MotionResult
from bgsub.errors import InputError
from bgsub.motion.global_motion import (GlobalMotion, apply_homography, corner_distances,
                                        fast_median, fit_global_motion)

__all__ = ["SMALL_REGION", "spans_frame", "SmallRegionRule", "MotionHoldBack",
           "FrozenModelRegistration", "match_exposure", "EXPOSURE_TOLERANCE", "SATURATED",
           "SceneCut", "BlobPersistence", "StillCameraSwitch",
           "motion_snr", "KnownMotion", "KNOWN_MOTION_HELP", "work_scale"]


def _translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def _shift_of(matrix: np.ndarray, shape: tuple) -> np.ndarray:
    """The translation (3, 3) that moves the centre of an ``(H, W)`` frame as ``matrix`` does."""
    h, w = shape[:2]
    centre = np.array([[(w - 1) / 2.0, (h - 1) / 2.0]])
    return _translation(*(apply_homography(matrix, centre) - centre)[0])


def largest_corner_shift(matrix: np.ndarray, shape: tuple) -> float:
    """How far (px) the (3, 3) ``matrix`` moves the farthest-moved corner of an ``(H, W)``
    frame."""
    h, w = shape[:2]
    return float(corner_distances(matrix, np.eye(3), width=w, height=h).max())


# ---------------------------------------------------------------------- small-region rule

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
    passes.
    """
    inl = result.motion.inliers & (result.weights > 0)
    if not inl.any():
        return True
    pts = result.points[inl]
    h, w = shape[:2]
    span_x = float(pts[:, 0].max() - pts[:, 0].min()) / max(w - 1, 1)
    span_y = float(pts[:, 1].max() - pts[:, 1].min()) / max(h - 1, 1)
    return max(span_x, span_y) >= min_extent


class SmallRegionRule:
    """Refuses a fit whose inliers span less than ``min_extent`` of the frame (0 = never):
    the camera is then taken as still for that frame (a previous motion may have been a
    mixture of the object's and the blank background's readings)."""

    def __init__(self, min_extent: float) -> None:
        self.min_extent = float(min_extent)

    def check(self, result: MotionResult, shape: tuple) -> tuple:
        """``(result, refused)``: ``result`` as it is, or with its motion refused (the
        identity, not ok, reason :data:`SMALL_REGION`) when it spans too small a region of an
        ``(h, w)`` frame."""
        if (self.min_extent <= 0 or not result.motion.ok
                or spans_frame(result, shape, self.min_extent)):
            return result, False
        refused = GlobalMotion.identity(len(result.points), ok=False, reason=SMALL_REGION)
        return dataclasses.replace(result, motion=refused), True


# ---------------------------------------------------------------------- motion hold-back

class MotionHoldBack:
    """Motion that moves no frame corner by ``still_below`` px is held back and added to the
    next frame's (0 = every motion is applied).

    A still camera's readings scatter by hundredths of a pixel: warping the model by each
    resamples (blurs) it every frame. Held back and added up instead, a slow pan (0.2 px per
    frame at the working size) still moves the model, in steps.
    """

    def __init__(self, still_below: float) -> None:
        self.still_below = float(still_below)
        self.unapplied = np.eye(3)  # (3, 3): the motion held back so far

    def reset(self) -> None:
        self.unapplied = np.eye(3)

    def total(self, matrix: np.ndarray) -> np.ndarray:
        """This frame's ``matrix`` (3, 3) with what earlier frames left unapplied."""
        return matrix @ self.unapplied

    def below(self, matrix: np.ndarray, shape: tuple) -> bool:
        """Whether ``matrix`` moves no corner of an ``(h, w)`` frame by ``still_below`` px."""
        return self.still_below > 0 and largest_corner_shift(matrix, shape) < self.still_below

    def release(self, total: np.ndarray, shape: tuple) -> np.ndarray:
        """The motion to warp the model by: ``total`` (from :meth:`total`), or the identity
        while it is :meth:`below` the limit (then it is kept for the next frame)."""
        if self.below(total, shape):
            self.unapplied = total
            return np.eye(3)
        self.unapplied = np.eye(3)
        return total


# ---------------------------------------------------------------------- frozen-model registration

class FrozenModelRegistration:
    """Registers a frozen background model (``learning_rate=0``) to the frame.

    A frozen model is tied to the scene by nothing but the chain of frame-to-frame motions,
    whose errors add up to a drift of pixels within seconds of a pan (false foreground along
    every edge). The model is itself an image of the scene in (nearly) this frame's coordinates,
    so the frame is registered to it: phase correlation finds the shift, then corners of the
    model tracked into the frame (pyramidal Lucas-Kanade from that shift) and a RANSAC fit of
    the engine's motion model to them correct the rest, rotation and zoom included. Objects in
    the frame are the fit's outliers. When the corners give no fit (a flat or changed scene),
    the shift alone is applied. Costs two whole-frame FFTs and a few hundred tracks a frame.
    """

    #: The largest correction (px, at any frame corner) the registration may add.
    max_correction = 3.0
    #: The smallest phase-correlation peak it trusts.
    min_response = 0.05
    #: Corner tracking: at most this many corners of the model, the Lucas-Kanade window side
    #: and pyramid levels above the base, and the RANSAC inlier distance (px) of the fit.
    corners, window, levels, threshold = 200, 15, 1, 1.0

    def __init__(self, motion_model: str) -> None:
        self.motion_model = motion_model
        self._window: Optional[np.ndarray] = None  # Hanning window of the phase correlation

    def register(self, matrix: np.ndarray, gray: np.ndarray, model: CompensatedBackground, *,
                 small: bool) -> np.ndarray:
        """``matrix`` (3, 3) followed by the motion (moving no frame corner by more than
        ``max_correction`` px) that best registers ``model``, warped by it, to ``gray`` ((h, w)
        uint8). A ``small`` motion (below the hold-back limit) is first reduced to its shift:
        a frozen model must not collect the fit's sub-pixel rotation and zoom noise."""
        if small:
            matrix = _shift_of(matrix, gray.shape)
        h, w = gray.shape
        mean = model.mean
        mean = mean[:, :, 0] if mean.shape[2] == 1 else cv2.cvtColor(mean, cv2.COLOR_BGR2GRAY)
        warped = cv2.warpPerspective(mean, matrix, (w, h), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REPLICATE)
        # (uint8 for the tracker, taken first: phaseCorrelate windows its inputs in place.)
        warped8 = np.clip(warped + np.float32(0.5), 0, 255).astype(np.uint8)
        if self._window is None or self._window.shape != (h, w):
            self._window = cv2.createHanningWindow((w, h), cv2.CV_32F)
        (dx, dy), response = cv2.phaseCorrelate(warped, gray.astype(np.float32), self._window)
        if response < self.min_response or np.hypot(dx, dy) > self.max_correction:
            dx = dy = 0.0  # no clear peak (a textureless or changed scene): keep the estimate
        seen = cv2.warpPerspective(model.age, matrix, (w, h), flags=cv2.INTER_NEAREST,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0) >= 1.0
        residual = self._residual(warped8, seen, gray, (dx, dy))
        if residual is None:
            return _translation(dx, dy) @ matrix if (dx, dy) != (0.0, 0.0) else matrix
        return residual @ matrix

    def _residual(self, model: np.ndarray, seen: np.ndarray, gray: np.ndarray,
                  shift: tuple) -> Optional[np.ndarray]:
        """The motion (3, 3) from ``model`` (the model's warped gray mean, (h, w) uint8) to
        ``gray``: corners of the model where it has a history (``seen``, (h, w) bool),
        tracked into the frame starting from ``shift``, and the motion model fitted to them
        by RANSAC. None when too few corners agree or the fit moves a frame corner by more
        than ``max_correction`` px."""
        h, w = gray.shape
        seen = cv2.erode(seen.astype(np.uint8), np.ones((7, 7), np.uint8))
        pts = cv2.goodFeaturesToTrack(model, maxCorners=self.corners, qualityLevel=0.01,
                                      minDistance=8, blockSize=7, mask=seen)
        if pts is None or len(pts) < 12:
            return None
        start = (pts + np.float32(shift)).astype(np.float32)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)
        found, status, _ = cv2.calcOpticalFlowPyrLK(model, gray, pts, start,
                                                    winSize=(self.window, self.window),
                                                    maxLevel=self.levels, criteria=crit,
                                                    flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        fit = fit_global_motion(pts.reshape(-1, 2), found.reshape(-1, 2),
                                weights=status.ravel().astype(np.float32),
                                model=self.motion_model, threshold=self.threshold,
                                frame_size=(w, h))
        if not fit.ok or largest_corner_shift(fit.matrix, gray.shape) > self.max_correction:
            return None
        return fit.matrix

    @staticmethod
    def forget_unseen(model: CompensatedBackground, applied: np.ndarray) -> None:
        """After a frozen ``model``'s warp by ``applied`` (3, 3): pixels that the previous
        frame saw only in part (their source lies beyond its border, filled by replicating the
        edge) lose their history, so that the model's update gives them this frame.

        The warp interpolates the age, so a pixel half beyond the border inherits half of its
        neighbour's: at 1 or more it would count as learnt, and a frozen model would keep the
        replicated edge (streaks along the border the camera moves towards).
        """
        if model.age is None or np.array_equal(applied, np.eye(3)):
            return
        h, w = model.age.shape
        inside = cv2.warpPerspective(np.ones((h, w), np.float32), applied, (w, h),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                     borderValue=0)
        model.age[inside < 0.999] = 0.0


# ---------------------------------------------------------------------- exposure

#: Gains this close to 1 leave the frame as it is (under a rounding's worth at mid-gray).
EXPOSURE_TOLERANCE = 0.005
#: Gray levels at which a camera's value may be clipped.
SATURATED = 250


def match_exposure(frame: np.ndarray, model: CompensatedBackground) -> Tuple[np.ndarray, float]:
    """``(exposed, gain)``: ``frame`` ((h, w) or (h, w, C) uint8) divided by its brightness gain
    against ``model`` (:meth:`~bgsub.background.compensated.CompensatedBackground.exposure_gain`),
    rounded and saturated, and that gain; ``(frame, 1.0)`` when the gain is within
    :data:`EXPOSURE_TOLERANCE` of 1.

    A camera's auto exposure scales the whole frame by a few percent a frame; the model,
    learning at ``alpha``, lags behind and calls every bright pixel foreground. Brought to the
    model's exposure, frames keep the model's colours. A value clipped at :data:`SATURATED` or
    above says only that the scene is at least that bright, so it takes the model's value where
    that is brighter than the divided one."""
    gain = model.exposure_gain(frame)
    if abs(gain - 1.0) <= EXPOSURE_TOLERANCE:
        return frame, 1.0
    exposed = cv2.convertScaleAbs(frame, alpha=1.0 / gain)
    clipped = np.asarray(frame) >= SATURATED
    if clipped.any():
        mean = cv2.convertScaleAbs(model.mean).reshape(exposed.shape)
        np.maximum(exposed, mean, out=exposed, where=clipped)
    return exposed, gain


# ---------------------------------------------------------------------- scene cut

class SceneCut:
    """A new shot: after compensation more than ``scene_cut`` of the pixels with history still
    differ from the model while fewer than ``cut_support`` of the motion vectors agree with the
    fitted motion (a new shot has no consistent motion), or more than 80 % differ whatever the
    motion says."""

    def __init__(self, scene_cut: float, cut_support: float) -> None:
        self.scene_cut = float(scene_cut)
        self.cut_support = float(cut_support)

    def is_cut(self, score: np.ndarray, young: np.ndarray, result: MotionResult) -> bool:
        """Whether the frame starts a new shot, given the background ``score`` ((h, w)
        float32, above 1 = differs), the pixels without history ``young`` ((h, w) bool, not
        counted) and the frame's motion ``result`` (:data:`NO_MOTION`, a repeated frame's,
        is no new shot)."""
        old = max(int(np.count_nonzero(~young)), 1)
        used = max(int(np.count_nonzero(result.weights > 0)), 1)
        support = result.motion.n_inliers / used if result.motion.ok else 0.0
        if result is NO_MOTION:
            support = 1.0
        changed = np.count_nonzero((score > 1.0) & ~young) / old
        return (changed > self.scene_cut and support < self.cut_support) or changed > 0.8


class BlobPersistence:
    """A blob of the mask must overlap the previous frame's mask, moved by the camera and grown
    by ``radius`` px (:func:`~bgsub.background.fusion.persistent_blobs`; ``radius`` 0 = off).
    The first mask with foreground after a (re)start has nothing to overlap and is kept whole:
    a young model often finds nothing in its first frames, and what it first finds is the
    objects already in view."""

    def __init__(self, radius: int) -> None:
        self.radius = int(radius)
        self._previous: Optional[np.ndarray] = None  # the last mask before this filter

    def reset(self) -> None:
        self._previous = None

    def filter(self, mask: np.ndarray, matrix: np.ndarray) -> np.ndarray:
        """``mask`` ((h, w) uint8 0/255) less its blobs new since the last frame; ``matrix``
        (3, 3) is the camera motion from that frame."""
        if self.radius <= 0:
            return mask
        previous = self._previous
        if previous is None or previous.shape != mask.shape:
            # Nothing found yet since the (re)start: the first mask with foreground is kept
            # whole. (A copy: the engine may hand this very array to the caller.)
            self._previous = mask.copy() if mask.any() else None
            return mask
        self._previous = mask.copy()
        return persistent_blobs(mask, previous, matrix, radius=self.radius)


# ---------------------------------------------------------------------- still-camera switch

def motion_snr(result: MotionResult, *, min_vectors: int = 8) -> float:
    """How far the fitted camera motion stands out of the motion vectors' disagreement with it:
    the median displacement it predicts at the vectors' positions over the robust standard
    deviation (1.4826 MAD) of their residuals; 0 without a fit or with fewer than
    ``min_vectors`` usable vectors.

    A camera moves the whole background rigidly: its motion is many times the residuals
    (panning and shaking cameras: medians 9-100 on the development data). Water or foam seen by
    a still camera drifts coherently enough for RANSAC to fit a "motion", but its vectors
    scatter about it by about as much (medians 0.5-2.2).
    """
    if not result.motion.ok:
        return 0.0
    usable = result.weights > 0
    if np.count_nonzero(usable) < min_vectors:
        return 0.0
    pts = result.points[usable].astype(np.float64)
    predicted = apply_homography(result.motion.matrix, pts) - pts
    residual = np.linalg.norm(result.disp[usable] - predicted, axis=1)
    scatter = 1.4826 * float(fast_median(residual))
    return float(fast_median(np.linalg.norm(predicted, axis=1))) / max(scatter, 1e-3)


#: The fraction of the compared pixels the sample model may call foreground beyond
#: ``still_versus`` times the compensated model's (:class:`StillCameraSwitch`).
SAMPLE_SLACK = 0.005
#: Gray levels: where the compensated model's decision threshold is wider (a spread of 30 at
#: k_sigma 2; water, flicker), it is blind rather than right, and the still-camera switch does
#: not compare the two models there.
BLIND_BEYOND = 60.0


class StillCameraSwitch:
    """A :class:`SampleBackground` that is never warped runs beside the compensated model; the
    camera is taken as still (:attr:`camera_still`), and that model's score used, while over
    the last ``window`` frames (medians):

    * the fitted motion is less than ``still_snr`` times the robust scatter of the motion
      vectors about it (:func:`motion_snr`): a shaking camera's motion is rigid however small;
    * the sample model calls less than ``still_model`` of the frame foreground: a pan makes it
      fail;
    * of the pixels where the compensated model is not blind (its threshold within
      ``BLIND_BEYOND`` gray levels), the sample model calls at most ``still_versus`` times the
      fraction the compensated model calls, plus ``SAMPLE_SLACK`` (a young compensated model
      calls nothing). A slow pan (half a pixel a frame) hides in the vectors' scatter, and over
      sparse fine texture (a star field) its drift makes the sample model call a small
      fraction of the frame that is still many times the compensated model's. Where the
      compensated model's spread is wide (water, flicker) it is blind rather than right, and
      the comparison does not look.
    """

    def __init__(self, *, still_model: float, still_snr: float, window: int,
                 still_versus: float = 0.0) -> None:
        self.still_model = float(still_model)
        self.still_snr = float(still_snr)
        self.still_versus = float(still_versus)
        self.window = max(int(window), 1)
        self.model = SampleBackground()
        # (fraction the sample model calls foreground, motion_snr, how far it calls more than
        # still_versus times the compensated model where that one is not blind) of the last
        # frames.
        self._votes: collections.deque = collections.deque(maxlen=self.window)
        self.camera_still = False

    def reset(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` (a restart of the engine's model)."""
        self.model.reset(frame)
        self._votes.clear()
        self.camera_still = False

    def update(self, frame: np.ndarray, learn_slowly: np.ndarray, rate: float) -> None:
        """Learn ``frame`` (:meth:`SampleBackground.update`'s conventions)."""
        self.model.update(frame, learn_slowly, rate)

    def judge(self, frame: np.ndarray, result: MotionResult, *,
              compensated: Optional[CompensatedBackground] = None,
              compensated_score: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        """Whether the camera is taken as still for ``frame`` (working size) with motion
        ``result``: the sample model's ``(h, w) float32`` score of it if so, else None.
        ``compensated`` and ``compensated_score`` are the compensated model, warped to the
        frame, and its ``(h, w)`` score of it (None: no comparison with it)."""
        snr = motion_snr(result)
        snrs = [v[1] for v in self._votes] + [snr]
        if fast_median(np.asarray(snrs[-self.window:], np.float64)) >= self.still_snr:
            # A rigid motion: the camera moves whatever the sample model says. Not scoring it
            # saves ~1 ms a frame; the frame counts as one the sample model does not explain.
            self._votes.append((1.0, snr, 1.0))
            self.camera_still = False
            return None
        score = self.model.score(frame)
        fraction = _foreground_fraction(score)
        excess = -np.inf
        if compensated is not None and compensated_score is not None and self.still_versus > 0:
            seeing = compensated.sensitive(within=BLIND_BEYOND)
            if seeing.shape != score.shape:  # (a model without a frame yet: nothing to compare)
                seeing = np.zeros(score.shape, bool)
            excess = (_foreground_fraction(score, seeing)
                      - self.still_versus * _foreground_fraction(compensated_score, seeing))
        self._votes.append((fraction, snr, excess))
        fraction, _, excess = np.median(np.array(self._votes), axis=0)
        self.camera_still = bool(fraction < self.still_model and excess <= SAMPLE_SLACK)
        return score if self.camera_still else None


def _foreground_fraction(score: np.ndarray, where: Optional[np.ndarray] = None) -> float:
    """The fraction of an ``(h, w)`` background score above the decision threshold (1), over
    the ``(h, w) bool`` pixels ``where`` (default all; 0 when ``where`` is empty)."""
    if where is None:
        return float(np.count_nonzero(score > 1.0)) / score.size
    n = int(np.count_nonzero(where))
    return float(np.count_nonzero((score > 1.0) & where)) / n if n else 0.0


# ---------------------------------------------------------------------- known camera motion

#: What the ``known_motion`` parameter of the moving-camera engines means (``bgsub methods``).
KNOWN_MOTION_HELP = ("camera motion to use instead of fitting it: an (N, 3, 3) .npy file as "
                     "--motion writes it (entry k maps input pixels of frame k-1 to frame k, "
                     "frames counted from 0 as the engine is given them) or, from Python, the "
                     "array; entries all NaN, and frames past its end, are fitted as usual "
                     "(empty = fit every frame)")


def _load_motion(path: str) -> np.ndarray:
    """The array in the ``.npy`` file ``path`` (``allow_pickle=False``)."""
    if not os.path.isfile(path):
        what = "is a folder" if os.path.isdir(path) else "no such file"
        raise InputError(f"{path}: {what} (the known camera motion, an .npy file)")
    expected = ("the known camera motion is an (N, 3, 3) float array saved by numpy.save as "
                "an .npy file, without pickled objects, as bgsub run --motion writes it")
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
        if magic != b"\x93NUMPY":
            what = "an .npz archive" if magic[:2] == b"PK" else "not an .npy file"
            raise InputError(f"{path}: {what}; {expected}")
        array = np.load(path, allow_pickle=False)
    except (OSError, EOFError) as err:
        raise InputError(f"{path}: cannot read the known camera motion "
                         f"({str(err).splitlines()[0] if str(err) else type(err).__name__})"
                         ) from None
    except ValueError:  # pickled objects, or a damaged header
        raise InputError(f"{path}: not a plain numeric .npy array; {expected}") from None
    return array


class KnownMotion:
    """Camera motion given, not fitted: ``matrices`` ``(N, 3, 3)``, entry ``k`` mapping pixel
    coordinates of the input's frame ``k - 1`` to frame ``k`` (frames counted as the engine is
    given them, from 0; the layout ``bgsub run --motion`` writes, so a run with the same
    ``--start``/``--step`` reads its own file back). Entries all NaN are fitted as usual, and
    so are frames past the last entry (:attr:`frames_past_end` counts them).

    The front end still measures local motion (the motion evidence needs it); the camera fit it
    is handed (:meth:`fit`) returns the given motion, with the vectors that agree with it
    within the RANSAC threshold as its inliers."""

    def __init__(self, matrices: Any, *, name: str = "the known camera motion") -> None:
        array = np.asarray(matrices)
        if array.ndim != 3 or array.shape[1:] != (3, 3) or not len(array) \
                or array.dtype.kind not in "iuf":
            raise InputError(f"{name} must be an (N, 3, 3) array of numbers, one matrix per "
                             f"frame, not {array.dtype} of shape {array.shape}")
        array = array.astype(np.float64)
        unknown = np.isnan(array).all(axis=(1, 2))
        bad = ~unknown & ~np.isfinite(array).all(axis=(1, 2))
        if bad.any():
            raise InputError(f"{name}: entry {int(np.flatnonzero(bad)[0])} is partly not "
                             "finite (only entries all NaN mean 'fit this frame')")
        scale = array[:, 2, 2]
        singular = ~unknown & ((np.abs(scale) < 1e-12) | (np.abs(np.linalg.det(
            np.where(unknown[:, None, None], np.eye(3), array))) < 1e-12))
        if singular.any():
            raise InputError(f"{name}: entry {int(np.flatnonzero(singular)[0])} is singular, "
                             "not a camera motion")
        self.matrices = np.where(unknown[:, None, None], np.nan,
                                 array / np.where(unknown, 1.0, scale)[:, None, None])
        self.name = name
        self.frame = -1  # the frame being processed (0-based), -1 before the first
        self.frames_past_end = 0

    @classmethod
    def from_value(cls, value: Any) -> "KnownMotion":
        """From an ``.npy`` file's path, an array, or a :class:`KnownMotion` (a fresh copy,
        its frame count at the start)."""
        if isinstance(value, KnownMotion):
            return cls(value.matrices, name=value.name)
        if isinstance(value, (str, os.PathLike)):
            path = os.fspath(value)
            return cls(_load_motion(path), name=path)
        return cls(value)

    def next_frame(self) -> None:
        """Count a frame given to the engine."""
        self.frame += 1
        if self.frame >= len(self.matrices):
            self.frames_past_end += 1

    def matrix(self, in_shape: tuple, work_shape: tuple) -> Optional[np.ndarray]:
        """The given motion of the current frame ``(3, 3) float64`` in working-size pixels
        (frames of ``in_shape`` ``(H, W, ...)`` processed at ``work_shape`` ``(h, w)``), or
        None where it is to be fitted."""
        if not 0 < self.frame < len(self.matrices) or np.isnan(self.matrices[self.frame, 0, 0]):
            return None
        scale = work_scale(in_shape, work_shape)
        return scale @ self.matrices[self.frame] @ np.linalg.inv(scale)

    @staticmethod
    def fit(matrix: np.ndarray, threshold: float) -> Any:
        """A camera fit (``fit(points, disp, weights, shape)``, as
        :class:`~bgsub.engines.frontend.CameraFit`) that returns ``matrix`` (3, 3), with the
        usable vectors within ``threshold`` px of it as inliers."""

        def given(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                  shape: tuple) -> GlobalMotion:
            pts = np.asarray(points, np.float64).reshape(-1, 2)
            moved = pts + np.asarray(disp, np.float64).reshape(-1, 2)
            error = np.hypot(*(apply_homography(matrix, pts) - moved).T) if len(pts) else \
                np.zeros(0)
            return GlobalMotion(matrix.copy(), (np.asarray(weights) > 0) & (error < threshold),
                                True)

        return given


def work_scale(in_shape: tuple, work_shape: tuple) -> np.ndarray:
    """``(3, 3) float64``: input pixel coordinates of ``in_shape`` ``(H, W, ...)`` frames to
    those of their ``work_shape`` ``(h, w)`` resized copies (``cv2.resize``'s pixel centres)."""
    sx, sy = work_shape[1] / in_shape[1], work_shape[0] / in_shape[0]
    return np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)],
                     [0.0, 0.0, 1.0]])
