"""Sub-pixel refinement of patch motion: Lucas-Kanade iterations started from each vector.

The gated RBM reads a patch's displacement from a discrete set of candidate motions, and the
coarse-to-fine readout leaves it a fraction of a pixel off (on rotating and zooming views more
than half a pixel at the median). The camera fit and the violation test need better than that:
a background model warped by a motion 0.5 px off lights up along every strong edge. Gradient
descent on the frames themselves, started at the gated RBM's answer, converges to the nearest
minimum, which is the right one once the start is within a pixel or so; the gated RBM keeps
the part it does well (finding the motion among many, over a large range) and this step adds
the precision.
"""

from __future__ import annotations

import cv2
import numpy as np

from bgsub.errors import InputError

__all__ = ["MIN_REFINE_WINDOW", "as_uint8", "refine_vectors"]

#: The smallest window the tracker accepts (OpenCV needs more than 2 px).
MIN_REFINE_WINDOW = 3

_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.01)


def refine_vectors(prev: np.ndarray, cur: np.ndarray, points: np.ndarray, disp: np.ndarray, *,
                   window: int, within: float) -> np.ndarray:
    """Each displacement moved to the nearest minimum of the patch's squared difference.

    Parameters
    ----------
    prev, cur : (H, W) uint8 or float32 in [0, 1]
        The two gray frames (float32 is scaled to uint8: the tracker takes 8-bit images).
    points : (N, 2) float
        Patch centres ``(x, y)`` in ``prev``.
    disp : (N, 2) float
        Their displacements to ``cur``: the start of the iterations.
    window : int
        Side of the square window the difference is summed over (the patch size), at least
        :data:`MIN_REFINE_WINDOW`.
    within : float
        A refined vector that moved by this many pixels or more from its start converged to
        another minimum (a flat patch slid along, a repeated texture): the start is kept.

    Returns
    -------
    (N, 2) float32: refined where the iterations converged within ``within`` px, else ``disp``.

    Raises
    ------
    InputError
        The frames differ in size, ``points`` and ``disp`` are not both ``(N, 2)``, or
        ``window`` is below :data:`MIN_REFINE_WINDOW`.
    """
    if window < MIN_REFINE_WINDOW:
        raise InputError(f"refine_vectors needs a window of at least {MIN_REFINE_WINDOW} px, "
                         f"not {window!r}")
    if np.shape(prev) != np.shape(cur) or np.ndim(prev) != 2:
        raise InputError(f"refine_vectors needs two gray frames of one size, not "
                         f"{np.shape(prev)} and {np.shape(cur)}")
    if np.shape(points) != np.shape(disp) or np.ndim(points) != 2 or np.shape(points)[1] != 2:
        raise InputError(f"refine_vectors needs points and disp of shape (N, 2), not "
                         f"{np.shape(points)} and {np.shape(disp)}")
    start = np.asarray(disp, np.float32)
    if len(start) == 0:
        return start.copy()
    p0 = np.ascontiguousarray(points, np.float32).reshape(-1, 1, 2)
    p1 = (p0 + start.reshape(-1, 1, 2)).astype(np.float32)
    p1, status, _ = cv2.calcOpticalFlowPyrLK(as_uint8(prev), as_uint8(cur), p0, p1,
                                             winSize=(window, window), maxLevel=0,
                                             criteria=_CRITERIA,
                                             flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
    refined = (p1 - p0).reshape(-1, 2)
    moved = np.hypot(*(refined - start).T)
    keep = (status.ravel() == 1) & np.isfinite(moved) & (moved < within)
    return np.where(keep[:, None], refined, start).astype(np.float32)


def as_uint8(image: np.ndarray) -> np.ndarray:
    """``image`` as (H, W) uint8 (float32 in [0, 1] scaled by 255, rounded, saturated)."""
    if image.dtype == np.uint8:
        return image
    return cv2.convertScaleAbs(np.asarray(image, np.float32), alpha=255.0)
