"""A dense read of a flat background: the camera's motion where the patches read only its subject.

A camera that follows its subject over sky, fog, snow or calm water sees one textured thing, the
subject, which holds nearly still in the image. The background is too flat for a 13 px patch:
its vectors carry no weight, the fit takes the subject's motion (about none) for the camera's,
and the subject is never found. The background still holds what the patches cannot use:
gradients too faint and too wide for a patch.

When the fit's inlier weight sits in a compact box (:func:`inlier_box`) and the rest of the
frame is flat (:func:`is_flat`), :class:`FlatRead` reads the translation of the rest densely
(:func:`read_translation`: OpenCV's enhanced correlation coefficient, ECC, on the blurred
frames, started from the last good motion, the camera's continuity), and takes it
as the camera's when the reading is clear, differs from the fit, and leaves no more than twice
the misfit of the fit or of no motion (:func:`misfit`: a read along a smooth ramp of sky, which
ECC cannot pin down, leaves many times more). A still camera over a blank
wall reads no motion there, as the fit did; where the rest of the frame is textured, its own
vectors have said what they could, and the fit stands.
"""

from __future__ import annotations

import dataclasses
from typing import Optional, Tuple

import cv2
import numpy as np

from bgsub._util import weighted_quantiles
from bgsub.camera.rules import shift_of, translation
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.result import MotionResult

__all__ = ["FLAT_READ", "FlatRead", "blurred", "inlier_box", "is_flat", "misfit", "outside",
           "read_translation"]

#: ``last_status`` of a frame whose camera motion was read densely from a flat background.
FLAT_READ = "ok: camera motion read from a flat background"
#: The frames are blurred by this sigma (working px) before the read: the faint, wide gradients
#: of a flat background are what is read, not its pixel noise.
SIGMA = 2.0
#: The box is grown by this many working px before it is left out of the read.
MARGIN = 12
#: At least this share of the frame must be left to read.
LEAST_FREE = 0.3
#: The rest of the frame is flat when its median gradient is under this (gray levels per px,
#: after a blur of sigma 1): fog and sky measure 0.2-0.7, a crowd, ice with boards or water
#: 1.6-2.4. Where the rest is textured, its vectors have said what they could.
FLAT_GRADIENT = 1.0
#: The read replaces the fit only when the two differ by more than this (working px)...
LEAST_DIFFERENCE = 1.0
#: ... and when it leaves at most this many times the misfit (mean squared difference of the
#: blurred frames, not normalised) of the fit or of no motion. ECC forgives an offset, so over a
#: smooth ramp of sky it reads any shift along the ramp, and the plain difference says so; over
#: the flattest fog the two misfits are the frames' noise, and the read is the better guide.
MISFIT_RATIO = 2.0
ZERO = np.zeros(2)


def inlier_box(result: MotionResult, shape: tuple) -> Optional[Tuple[int, int, int, int]]:
    """``(x0, y0, x1, y1)``, working px: the box holding the middle 80 % of the fit's inlier
    weight each way (of every weighted vector when the fit failed), or None without weight.
    ``shape`` is the frame's ``(h, w)``."""
    weights = result.weights.astype(np.float64)
    if result.motion.ok and result.motion.inliers.any():
        weights = weights * result.motion.inliers
    if len(weights) == 0 or weights.sum() <= 0:
        return None
    h, w = shape[:2]
    (x0, x1), (y0, y1) = (weighted_quantiles(result.points[:, i], weights, (0.1, 0.9))
                          for i in (0, 1))
    return (int(np.clip(x0, 0, w - 1)), int(np.clip(y0, 0, h - 1)),
            int(np.clip(x1, 0, w - 1)), int(np.clip(y1, 0, h - 1)))


def outside(box: Tuple[int, int, int, int], shape: tuple) -> np.ndarray:
    """``(h, w) uint8``: 1 outside ``box`` grown by :data:`MARGIN`, 0 within, for a frame of
    ``shape`` ``(h, w)``."""
    keep = np.ones(shape[:2], np.uint8)
    x0, y0, x1, y1 = box
    keep[max(y0 - MARGIN, 0):y1 + MARGIN + 1, max(x0 - MARGIN, 0):x1 + MARGIN + 1] = 0
    return keep


def is_flat(gray: np.ndarray, keep: np.ndarray) -> bool:
    """Whether the (h, w) uint8 frame ``gray`` is flat where ``keep`` ((h, w) uint8) is set:
    its median gradient there under :data:`FLAT_GRADIENT` (Sobel's gain of 8 taken out)."""
    smooth = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    gradient = np.hypot(cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1))
    return float(np.median(gradient[keep > 0])) < 8.0 * FLAT_GRADIENT


def blurred(frame: np.ndarray) -> np.ndarray:
    """``(h, w) float32``: the (h, w) uint8 ``frame`` blurred by :data:`SIGMA`, as both reads
    take it."""
    return cv2.GaussianBlur(frame.astype(np.float32), (0, 0), SIGMA)


def misfit(previous: np.ndarray, current: np.ndarray, keep: np.ndarray,
           shift: np.ndarray) -> float:
    """The mean squared difference (gray levels squared) between the ``current`` frame and the
    ``previous`` one moved by ``shift`` (2,), both (h, w) float32 (:func:`blurred`), where
    ``keep`` ((h, w) uint8) is set and the moved frame has pixels."""
    h, w = current.shape
    m = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
    moved = cv2.warpAffine(previous, m, (w, h), flags=cv2.INTER_LINEAR)
    covered = cv2.warpAffine(np.ones_like(previous), m, (w, h), flags=cv2.INTER_LINEAR)
    inside = (keep > 0) & (covered > 0.999)  # (not blended with the border)
    if not inside.any():
        return float("inf")
    return float(np.mean((moved[inside] - current[inside]) ** 2))


def read_translation(previous: np.ndarray, current: np.ndarray, keep: np.ndarray, *,
                     start: np.ndarray) -> Optional[Tuple[float, np.ndarray]]:
    """``(correlation, (dx, dy) float64)``: the translation (working px) that takes the
    ``previous`` frame to the ``current`` one ((h, w) float32 each, :func:`blurred`) where
    ``keep`` ((h, w) uint8) is set, by ECC from the translation ``start`` (2,); None when the
    read does not converge."""
    # ECC finds the warp that takes the current frame's pixels to the previous frame's.
    warp = np.float32([[1, 0, -start[0]], [0, 1, -start[1]]])
    stop = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 1e-3)
    try:
        cc, warp = cv2.findTransformECC(current, previous, warp, cv2.MOTION_TRANSLATION, stop,
                                        keep, 1)
    except cv2.error:  # no convergence, or nothing to correlate (a blank frame)
        return None
    return float(cc), -warp[:, 2].astype(np.float64)


class FlatRead:
    """The dense read of a flat background (module docstring): ``box_share``, the largest side
    of a compact box (a share of the frame's side; a band across the frame is not compact);
    ``least_correlation``, a clear reading."""

    def __init__(self, *, box_share: float, least_correlation: float,
                 threshold: float) -> None:
        self.box_share, self.least_correlation = float(box_share), float(least_correlation)
        self.threshold = float(threshold)
        self.previous: Optional[np.ndarray] = None  # (h, w) uint8: the last frame seen

    def restart(self, frame: np.ndarray) -> None:
        """Start over: nothing seen before ``frame``'s successor."""
        self.previous = None

    def check(self, measured: MotionResult, gray: np.ndarray,
              last_good: Optional[np.ndarray]) -> Tuple[MotionResult, bool]:
        """``(result, read)``: ``measured`` as it is and False, or with its motion replaced
        by the translation read densely outside its compact inlier box (reason
        :data:`FLAT_READ`; the vectors within ``threshold`` px of it are its inliers) and True.
        ``gray`` is the (h, w) uint8 frame, ``last_good`` the last good motion (3, 3) or
        None."""
        previous, self.previous = self.previous, gray
        if previous is None or previous.shape != gray.shape:
            return measured, False
        keep = self._flat_rest(measured, gray)
        if keep is None:
            return measured, False
        start = ZERO if last_good is None else shift_of(last_good, gray.shape)[:2, 2]
        frames = (blurred(previous), blurred(gray), keep)
        read = read_translation(*frames, start=start)
        fitted = shift_of(measured.motion.matrix, gray.shape)[:2, 2] if measured.motion.ok \
            else ZERO
        if read is None or not self._taken(read, fitted, frames):
            return measured, False
        shift = read[1]
        inliers = ((np.hypot(*(measured.disp - shift).T) < self.threshold)
                   & (measured.weights > 0))
        motion = GlobalMotion(translation(*shift), inliers, True, FLAT_READ)
        return dataclasses.replace(measured, motion=motion), True

    def _taken(self, read: Tuple[float, np.ndarray], fitted: np.ndarray, frames: tuple) -> bool:
        """Whether the ``read`` (correlation, shift (2,)) replaces the ``fitted`` shift (2,):
        clear, different, and no worse than :data:`MISFIT_RATIO` times the fit or no motion
        on ``frames`` (previous, current: :func:`blurred`; keep)."""
        correlation, shift = read
        if correlation < self.least_correlation or np.hypot(*(shift - fitted)) <= LEAST_DIFFERENCE:
            return False
        best = min(misfit(*frames, fitted), misfit(*frames, ZERO))
        return misfit(*frames, shift) <= MISFIT_RATIO * best

    def _flat_rest(self, measured: MotionResult, gray: np.ndarray) -> Optional[np.ndarray]:
        """``(h, w) uint8``: the rest of the frame (:func:`outside` the inlier box) when the
        box is compact and the rest is flat and large enough to read; else None."""
        box = None if self.box_share <= 0 else inlier_box(measured, gray.shape)
        h, w = gray.shape[:2]
        if (box is None or box[2] - box[0] + 1 >= self.box_share * w
                or box[3] - box[1] + 1 >= self.box_share * h):
            return None
        keep = outside(box, gray.shape)
        return keep if keep.mean() >= LEAST_FREE and is_flat(gray, keep) else None
