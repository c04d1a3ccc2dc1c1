"""The camera stage's rules on a fitted motion: a motion seen on only a small region is an
object's (:class:`SmallRegionRule`); motion too small to warp the model by is added to the next
frame's (:class:`MotionHoldBack`); in a 3-D scene the fit keeps the plane it had
(:func:`keep_plane`)."""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import numpy as np

from bgsub.motion.global_motion import GlobalMotion, apply_homography, corner_distances
from bgsub.motion.result import MotionResult

__all__ = ["SMALL_REGION", "spans_frame", "SmallRegionRule", "MotionHoldBack", "keep_plane",
           "largest_corner_shift", "shift_of", "translation"]


def translation(dx: float, dy: float) -> np.ndarray:
    return np.array([[1.0, 0.0, dx], [0.0, 1.0, dy], [0.0, 0.0, 1.0]])


def shift_of(matrix: np.ndarray, shape: tuple) -> np.ndarray:
    """The translation (3, 3) that moves the centre of an ``(H, W)`` frame as ``matrix`` does."""
    h, w = shape[:2]
    centre = np.array([[(w - 1) / 2.0, (h - 1) / 2.0]])
    return translation(*(apply_homography(matrix, centre) - centre)[0])


def largest_corner_shift(matrix: np.ndarray, shape: tuple) -> float:
    """How far (px) the (3, 3) ``matrix`` moves the farthest-moved corner of an ``(H, W)``
    frame."""
    h, w = shape[:2]
    return float(corner_distances(matrix, np.eye(3), width=w, height=h).max())


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


def keep_plane(fit: Callable[..., GlobalMotion], plane: np.ndarray, *, threshold: float,
               share: float) -> Callable[..., GlobalMotion]:
    """The camera ``fit(points, disp, weights, shape)`` made to keep the last frame's ``plane``
    ((3, 3) float64): when the vectors that ``plane`` explains (within ``threshold`` px) are at
    least ``share`` of the best fit's inliers and mostly not among them (another layer of the
    scene won the vote), the fit is made to those vectors alone. Which layer is the plane
    matters little to the parallax field that explains the others, but a plane that changes
    from frame to frame breaks the field and the background model's warp."""

    def kept(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
             shape: Any) -> GlobalMotion:
        best = fit(points, disp, weights, shape)
        if not best.ok:
            return best
        moved = apply_homography(plane, points) - points
        on_plane = (np.hypot(*(disp - moved).T) <= threshold) & (weights > 0)
        n = int(np.count_nonzero(on_plane))
        if (n < share * np.count_nonzero(best.inliers)
                or np.count_nonzero(best.inliers & on_plane) >= 0.5 * n):
            return best
        again = fit(points, disp, np.where(on_plane, weights, 0).astype(np.float32), shape)
        return again if again.ok else best

    return kept
