"""The classical motion front end (the ``compensated`` engine): Shi-Tomasi corners tracked by
pyramidal Lucas-Kanade, kept when they pass a forward-backward check."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from bgsub.engines.frontend import CameraFit, MotionFrontEnd, MotionResult
from bgsub.motion.global_motion import GlobalMotion, apply_homography
from bgsub.settings import check_settings, setting

__all__ = ["LucasKanadeConfig", "LucasKanadeFrontEnd", "LKFrame"]


@dataclass(frozen=True)
class LucasKanadeConfig:
    """Settings of :class:`LucasKanadeFrontEnd` (``cv2.goodFeaturesToTrack``'s corners,
    ``cv2.calcOpticalFlowPyrLK``'s tracker)."""

    max_corners: int = setting(400, "Shi-Tomasi corners tracked per frame", low=1, high=100_000)
    corner_quality: float = setting(0.01, "Shi-Tomasi quality level: corners weaker than this "
                                          "fraction of the strongest are not tracked",
                                    above=0, high=1)
    min_distance: int = setting(8, "smallest distance between tracked corners (px)", low=0)
    lk_window: int = setting(21, "Lucas-Kanade window side (px)", low=3, high=255)
    lk_levels: int = setting(3, "Lucas-Kanade pyramid levels above the base", low=0, high=10)
    fb_threshold: float = setting(1.0, "forward-backward tracking error (px) above which a "
                                       "track is dropped", above=0)

    def __post_init__(self) -> None:
        check_settings(self)


@dataclass
class LKFrame:
    """A frame as the Lucas-Kanade front end keeps it: ``gray`` (h, w) uint8 and, once
    prepared, its corners ``(N, 1, 2) float32`` (None: not found yet, or none)."""

    gray: np.ndarray
    corners: Optional[np.ndarray] = None


class LucasKanadeFrontEnd(MotionFrontEnd):
    """Corners of the previous frame tracked into the current one (started where the camera's
    last motion predicts), tracked back, and kept when they return to within
    ``fb_threshold`` px."""

    name = "compensated"
    description = ("moving camera: Lucas-Kanade corner tracks + RANSAC camera motion + "
                   "compensated background model (classical baseline of grbm)")
    config_type = LucasKanadeConfig
    common_params = ("max_corners", *MotionFrontEnd.common_params)
    # The stage defaults are the grbm engine's, set for its dense but noisy patch vectors.
    # Tracked corners are sparse and precise: their agreement with the camera damps a
    # background difference as much as a disagreement boosts it, at a fixed 1.5 px (the
    # corners' RANSAC inlier distance too). No parallax field: on the few corners an object
    # holds, its steady motion passes for near structure's (DAVIS blackswan, cows).
    stage_defaults = dict(ransac_threshold=1.5, flow_boost=0.8, flow_damp=0.8,
                          violation_threshold=1.5, violation_noise=0.0, parallax=0.0)

    def frame_data(self, gray: np.ndarray) -> LKFrame:
        return LKFrame(gray)

    def prepare(self, data: LKFrame) -> None:
        data.corners = self.corners(data.gray)

    def corners(self, gray: np.ndarray) -> Optional[np.ndarray]:
        """Shi-Tomasi corners of ``gray`` ((h, w) uint8): ``(N, 1, 2) float32`` or None."""
        c = self.config
        return cv2.goodFeaturesToTrack(gray, maxCorners=c.max_corners,
                                       qualityLevel=c.corner_quality,
                                       minDistance=c.min_distance, blockSize=7)

    def measure(self, prev: LKFrame, cur: LKFrame, *, prior: Optional[np.ndarray],
                fit: CameraFit) -> MotionResult:
        c = self.config
        prev_gray, gray = prev.gray, cur.gray
        pts = prev.corners if prev.corners is not None else self.corners(prev_gray)
        if pts is None or len(pts) < 4:
            empty = np.zeros((0, 2), np.float32)
            return MotionResult(empty, empty, np.zeros(0, np.float32),
                                GlobalMotion.identity(0, ok=False, reason="too few corners"))
        pts = pts.reshape(-1, 1, 2).astype(np.float32)
        win = (c.lk_window, c.lk_window)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)
        flags = 0
        guess = None
        if prior is not None:
            # Start the tracker where the camera's last motion predicts: fast pans stay in range.
            guess = apply_homography(prior, pts.reshape(-1, 2)).astype(np.float32).reshape(-1, 1, 2)
            flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        nxt, st, _ = cv2.calcOpticalFlowPyrLK(prev_gray, gray, pts, guess, winSize=win,
                                              maxLevel=c.lk_levels, criteria=crit, flags=flags)
        back, st2, _ = cv2.calcOpticalFlowPyrLK(gray, prev_gray, nxt, pts.copy(), winSize=win,
                                                maxLevel=c.lk_levels, criteria=crit,
                                                flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        fb = np.hypot(*(back - pts).reshape(-1, 2).T)
        good = (st.ravel() == 1) & (st2.ravel() == 1) & (fb < c.fb_threshold)
        p = pts.reshape(-1, 2)
        d = (nxt - pts).reshape(-1, 2)
        weights = good.astype(np.float32)
        return MotionResult(p, d, weights, fit(p, d, weights, gray.shape))
