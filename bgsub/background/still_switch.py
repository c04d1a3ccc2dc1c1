"""While the camera is still, a never-warped sample model replaces the compensated one in the
fusion (:class:`StillCameraSwitch`): water and foam defeat a mean-and-variance model, and their
drift would be taken for a pan."""

from __future__ import annotations

import collections
from typing import Optional

import numpy as np

from bgsub._util import fast_median, weighted_quantiles
from bgsub.background.compensated import CompensatedBackground
from bgsub.background.sample import SampleBackground
from bgsub.camera.rules import shift_of
from bgsub.motion.global_motion import apply_homography
from bgsub.motion.result import MotionResult

__all__ = ["motion_snr", "SAMPLE_SLACK", "BLIND_BEYOND", "STEADY_PX", "StillCameraSwitch",
           "NoStillSwitch"]


def motion_snr(result: MotionResult, *, min_vectors: int = 8) -> float:
    """How far the fitted camera motion stands out of the motion vectors' disagreement with it:
    the median displacement it predicts at the vectors' positions over the robust standard
    deviation (1.4826 MAD, each residual counting its vector's weight) of their residuals; 0
    without a fit or with fewer than ``min_vectors`` usable vectors.

    A camera moves the whole background rigidly: its motion is many times the residuals
    (panning and shaking cameras: medians 9-100 on the development data). Water or foam seen by
    a still camera drifts coherently enough for RANSAC to fit a "motion", but its vectors
    scatter about it by about as much (medians 0.5-2.2). The weights keep a plain sky's
    vectors, which read noise, from passing for that scatter under a camera that pans over it.
    """
    if not result.motion.ok:
        return 0.0
    usable = result.weights > 0
    if np.count_nonzero(usable) < min_vectors:
        return 0.0
    pts = result.points[usable].astype(np.float64)
    predicted = apply_homography(result.motion.matrix, pts) - pts
    residual = np.linalg.norm(result.disp[usable] - predicted, axis=1)
    weights = result.weights[usable].astype(np.float64)
    scatter = 1.4826 * float(weighted_quantiles(residual, weights, 0.5))
    return float(fast_median(np.linalg.norm(predicted, axis=1))) / max(scatter, 1e-3)


#: The fraction of the compared pixels the sample model may call foreground beyond
#: ``still_versus`` times the compensated model's (:class:`StillCameraSwitch`).
SAMPLE_SLACK = 0.005
#: A camera's motion is steady from frame to frame to a few hundredths of its size (pans: 1-3 %
#: of a 1-2 px step); water's flow, read as a "motion", varies by 5-40 %. Steps under this
#: many px are not judged: a still camera's readings scatter about zero.
STEADY_PX = 0.5
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
    * the fitted motion does not keep one step of at least :data:`STEADY_PX` over the window,
      each frame's within ``steady`` of it (median): a pan over water or a flat region, whose
      vectors scatter, is still a pan;
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
                 still_versus: float = 0.0, steady: float = 0.0, radius: float = 20.0,
                 spread: float = 0.0, pause: bool = False) -> None:
        self.still_model = float(still_model)
        self.still_snr = float(still_snr)
        self.still_versus = float(still_versus)
        self.steady = float(steady)
        self.window = max(int(window), 1)
        self.pause = bool(pause)
        # Each pixel's radius: ``radius`` where it holds still, wider by ``spread`` times its
        # usual distance to its samples (0: one radius of 20 for all).
        self.model = (SampleBackground(radius_min=radius, radius_gain=spread) if spread > 0
                      else SampleBackground())
        # (fraction the sample model calls foreground, motion_snr, how far it calls more than
        # still_versus times the compensated model where that one is not blind) of the last
        # frames.
        self._votes: collections.deque = collections.deque(maxlen=self.window)
        self._steps: collections.deque = collections.deque(maxlen=self.window)  # (2,) each
        self.camera_still = False
        self._rigid = False  # the last frame judged was seen moving rigidly (not scored)

    def reset(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` (a restart of the engine's model)."""
        self.model.reset(frame)
        self._votes.clear()
        self._steps.clear()
        self.camera_still = self._rigid = False

    restart = reset  # (the engine's restart from a frame)

    def update(self, frame: np.ndarray, learn_slowly: np.ndarray, rate: float) -> None:
        """Learn ``frame`` (:meth:`SampleBackground.update`'s conventions); with ``pause``, not
        while the last frame judged was seen moving rigidly (its view is gone by the time the
        camera stops: ``still_pause``, a cost saved)."""
        if not (self.pause and self._rigid):
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
        steady = self._steady(result, frame.shape)
        if fast_median(np.asarray(snrs[-self.window:], np.float64)) >= self.still_snr or steady:
            # A rigid motion: the camera moves whatever the sample model says, so the frame is
            # not scored, and counts as one the sample model does not explain.
            self._votes.append((1.0, snr, 1.0))
            self.camera_still, self._rigid = False, True
            return None
        self._rigid = False
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
        fraction, _, excess = fast_median(np.array(self._votes))
        self.camera_still = bool(fraction < self.still_model and excess <= SAMPLE_SLACK)
        return score if self.camera_still else None

    def _steady(self, result: MotionResult, shape: tuple) -> bool:
        """Record the fitted step of the ``(h, w)`` frame's centre (NaN without a fit) and say
        whether the window's steps keep one of at least :data:`STEADY_PX`, the median frame's
        within ``steady`` of it."""
        fitted = result.motion.ok
        self._steps.append(shift_of(result.motion.matrix, shape)[:2, 2] if fitted
                           else np.full(2, np.nan))
        if self.steady <= 0 or len(self._steps) < self.window:
            return False
        steps = np.array(self._steps)
        if not np.isfinite(steps).all():
            return False
        typical = fast_median(steps)
        size = float(np.hypot(*typical))
        spread = float(fast_median(np.hypot(*(steps - typical).T)))
        return size >= STEADY_PX and spread <= self.steady * size


def _foreground_fraction(score: np.ndarray, where: Optional[np.ndarray] = None) -> float:
    """The fraction of an ``(h, w)`` background score above the decision threshold (1), over
    the ``(h, w) bool`` pixels ``where`` (default all; 0 when ``where`` is empty)."""
    if where is None:
        return float(np.count_nonzero(score > 1.0)) / score.size
    n = int(np.count_nonzero(where))
    return float(np.count_nonzero((score > 1.0) & where)) / n if n else 0.0


class NoStillSwitch:
    """The still-camera switch turned off (``still_model`` 0): the camera is never taken as
    still, and the compensated model's score is always used."""

    camera_still = False
    model = None

    def restart(self, frame: np.ndarray) -> None:
        """Nothing to start over."""

    def update(self, frame: np.ndarray, learn_slowly: np.ndarray, rate: float) -> None:
        """Nothing to learn."""

    def judge(self, frame: np.ndarray, result: MotionResult, *,
              compensated: Optional[CompensatedBackground] = None,
              compensated_score: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        """None: the compensated model's score stands."""
        return None
