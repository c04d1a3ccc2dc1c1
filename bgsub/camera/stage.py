"""The camera stage of the moving-camera engine: from the front end's vectors to the motion the
background model is warped by, every decision on the camera's motion in one place.

Each frame, :meth:`CameraStage.fit_for` hands the front end its fit (RANSAC, or the known
motion) and prior; :meth:`CameraStage.decide` then takes what the front end measured:

1. a fit whose inliers sit in a compact box is checked by a dense read of the rest of the
   frame (:class:`~bgsub.camera.flat_read.FlatRead`: a subject followed over a flat
   background); a fit seen on only a small region is refused
   (:class:`~bgsub.camera.rules.SmallRegionRule`) and the camera taken as still; any other
   refused fit is replaced by the last good one;
2. motion that moves no frame corner by ``still_below`` px is held back and added to the next
   frame's (:class:`~bgsub.camera.rules.MotionHoldBack`);
3. a frozen model (``learning_rate=0``) is registered to the frame
   (:class:`~bgsub.camera.registration.FrozenModelRegistration`).
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple, Optional, Tuple, Union

import numpy as np

from bgsub.camera.config import CameraConfig, CameraFit
from bgsub.camera.flat_read import FlatRead
from bgsub.camera.known import KnownMotion, NoKnownMotion
from bgsub.camera.registration import FrozenModelRegistration
from bgsub.camera.rules import MotionHoldBack, SmallRegionRule, keep_plane
from bgsub.motion.result import MotionResult

__all__ = ["CameraDecision", "CameraStage"]


class CameraDecision(NamedTuple):
    """The camera stage's decision on one frame."""

    result: MotionResult  # what the front end measured, its fit refused if the rule refused it
    matrix: np.ndarray  # (3, 3) float64: the camera's motion from the previous frame
    applied: np.ndarray  # (3, 3) float64: what the background model is warped by
    status: str  # "ok" or "fallback: <why the fit was not used>"
    refused: bool  # the fit was refused for its small region (one consistent object motion)


class CameraStage:
    """The camera-motion decision (module docstring) with its settings ``config`` and the
    motion given, if any (``known``: a :class:`KnownMotion`, else every frame is fitted).

    Attributes
    ----------
    fit, flat_read, small_region, hold_back, registration, known
        Its parts. :attr:`last_good` is the last frame's fit when it was good, the prior of
        the next frame's reading.
    """

    def __init__(self, config: CameraConfig,
                 known: Union[KnownMotion, NoKnownMotion, None] = None) -> None:
        self.config = config
        self.fit = CameraFit(config)
        self.flat_read = FlatRead(box_share=config.flat_read,
                                  least_correlation=config.flat_correlation,
                                  threshold=config.ransac_threshold)
        self.small_region = SmallRegionRule(config.min_extent)
        self.hold_back = MotionHoldBack(config.still_below)
        self.registration = FrozenModelRegistration(config.motion_model)
        self.known = known or NoKnownMotion()
        self.last_good: Optional[np.ndarray] = None

    def restart(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` (a restart of the engine's model): no prior, nothing held
        back."""
        self.last_good = None
        self.hold_back.reset()
        self.flat_read.restart(frame)

    def fit_for(self, in_shape: tuple, shape: tuple, *,
                hold: float = 0.0) -> Tuple[Callable[..., Any], Optional[np.ndarray]]:
        """``(fit, prior)`` for a frame of working ``shape`` (input frames of ``in_shape``): the
        RANSAC fit and the last good motion, or the known motion as both. With ``hold`` > 0
        (a 3-D scene), the fit keeps the last good motion's plane while its vectors are at
        least that share of the best fit's inliers (:func:`~bgsub.camera.rules.keep_plane`)."""
        known = self.known.matrix(in_shape, shape)
        if known is not None:
            return KnownMotion.fit(known, self.config.ransac_threshold), known
        if hold > 0 and self.last_good is not None:
            return keep_plane(self.fit, self.last_good, threshold=self.config.ransac_threshold,
                              share=hold), self.last_good
        return self.fit, self.last_good

    def decide(self, measured: MotionResult, gray: np.ndarray, model: Any, *,
               frozen: bool) -> CameraDecision:
        """The :class:`CameraDecision` for the frame ``gray`` ((h, w) uint8) whose motion the
        front end ``measured``; a ``frozen`` ``model`` (the compensated background) is
        registered to the frame."""
        result, read = measured, False
        if isinstance(self.known, NoKnownMotion):
            result, read = self.flat_read.check(measured, gray, self.last_good)
        # (a dense read spans the frame outside the box by construction)
        result, refused = (result, False) if read else self.small_region.check(result, gray.shape)
        matrix, status = self._matrix(result, refused)
        total = self.hold_back.total(matrix)
        if frozen and result.motion.ok:
            total = self.registration.register(
                total, gray, model, small=self.hold_back.below(total, gray.shape))
        applied = self.hold_back.release(total, gray.shape)
        if result.motion.ok:
            self.last_good = result.motion.matrix
        return CameraDecision(result, matrix, applied, status, refused)

    def _matrix(self, result: MotionResult, refused: bool) -> Tuple[np.ndarray, str]:
        """``(matrix, status)``: the fit, or for a refused fit the last good motion (the
        identity when refused for its small region: the camera is taken as still)."""
        if result.motion.ok:  # "ok", or how the motion was read (flat_read.FLAT_READ)
            return result.motion.matrix, result.motion.reason
        status = f"fallback: {result.motion.reason}"
        if refused or self.last_good is None:
            return np.eye(3), status
        return self.last_good, status
