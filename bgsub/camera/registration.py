"""A frozen background model (``learning_rate=0``) registered to the frame
(:class:`FrozenModelRegistration`), so the errors of the frame-to-frame motions do not add up."""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional

import cv2
import numpy as np

from bgsub.camera.rules import largest_corner_shift, shift_of, translation
from bgsub.motion.global_motion import fit_global_motion

if TYPE_CHECKING:  # (the model is only read: the camera stage does not import the background)
    from bgsub.background.compensated import CompensatedBackground

__all__ = ["FrozenModelRegistration"]


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
            matrix = shift_of(matrix, gray.shape)
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
            return translation(dx, dy) @ matrix if (dx, dy) != (0.0, 0.0) else matrix
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
