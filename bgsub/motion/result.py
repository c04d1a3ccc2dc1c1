"""What a motion front end measures between two frames (:class:`MotionResult`), which the
camera stage (:mod:`bgsub.camera`) and the foreground stages (:mod:`bgsub.background`) read."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from bgsub.motion.global_motion import GlobalMotion

__all__ = ["MotionResult", "NO_MOTION"]


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
        The camera motion fitted to them (:class:`bgsub.camera.CameraFit`).
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

    @property
    def evidence_weights(self) -> np.ndarray:
        """``(N,) float32``: ``violation_weights`` when given, else ``weights``."""
        return self.weights if self.violation_weights is None else self.violation_weights


_NONE = np.zeros((0, 2), np.float32)
#: The motion of a repeated frame: none, measured from no correspondences.
NO_MOTION = MotionResult(_NONE, _NONE, np.zeros(0, np.float32), GlobalMotion.identity(0))
