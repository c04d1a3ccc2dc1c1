"""The image pyramid the patch motion is read on, and how far it reads.

One 13x13 patch pair can only show a displacement of a few pixels (the model's range, +-3 or +-4
px), but a panning camera moves 5-20 px per frame. The reader therefore works on an image
pyramid (``cv2.pyrDown``): at the coarsest level motions are small enough for the model.

Coordinates: a pyramid level ``l`` pixel ``x_l`` is ``x / 2**l`` in full-resolution pixels
(``pyrDown`` centres output pixel ``i`` on input pixel ``2 i``).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any, List, Optional

import cv2
import numpy as np

from bgsub.model.tiling import to_gray
from bgsub._util import is_affine
from bgsub.motion.refine import as_uint8

__all__ = ["FramePyramid", "MotionRangeWarning", "PyramidReach", "auto_levels", "model_range",
           "motion_reach", "pyramid_reach", "scale_homography", "warp_back"]


class MotionRangeWarning(UserWarning):
    """:func:`~bgsub.motion.estimate_flow`'s automatic pyramid cannot reach the ``max_motion``
    asked for: the frame is too small for the levels it needs, and larger motions are misread."""


def model_range(model: Any) -> int:
    """Largest displacement (px, per axis) the model was trained for: its ``meta["max_disp"]``
    (or ``meta["max_shift"]``), else 3."""
    meta = getattr(model, "meta", {}) or {}
    for key in ("max_disp", "max_shift", "max_displacement"):
        if key in meta:
            try:
                return max(1, int(round(float(meta[key]))))
            except (TypeError, ValueError):
                pass
    return 3


def auto_levels(shape: tuple, *, max_motion: float, model_disp: int, patch_size: int) -> int:
    """Pyramid levels so that ``max_motion`` px at full size is within ``model_disp`` at the
    coarsest level, while that level still holds a few patches across (its short side at least
    ``4 * patch_size``): on small frames fewer levels than ``max_motion`` needs (see
    :class:`MotionRangeWarning`)."""
    h, w = shape[:2]
    levels = 1
    # One pixel of margin: readings at the edge of the range are ambiguous (clipped or not).
    while max_motion / 2 ** (levels - 1) > model_disp - 1 and min(h, w) / 2**levels >= 4 * patch_size:
        levels += 1
    return levels


def motion_reach(levels: int, *, model_disp: int, search: int = 0) -> int:
    """Largest motion (px per axis, full resolution) ``levels`` pyramid levels read from their
    start: the model's range less :func:`auto_levels`' one-pixel margin at the coarsest level,
    widened by the ``search`` grid of starts there (steps of that much)."""
    step = max(1, model_disp - 1) * 2 ** (levels - 1)
    return step * (1 + max(0, int(search)) if levels > 1 else 1)


@dataclass(frozen=True)
class PyramidReach:
    """The pyramid frames of one size are read with, and how far it reads: what
    :func:`pyramid_reach` returns, so that a caller who plans the ``search`` or says the reach
    in its own words (``bgsub flow``) counts as :func:`~bgsub.motion.estimate_flow` does.

    Attributes
    ----------
    levels : int
        Pyramid levels read.
    model_disp : int
        The model's displacement range.
    """

    levels: int
    model_disp: int

    def reach(self, search: int = 0) -> int:
        """Largest motion read from the start with the ``search`` grid (:func:`motion_reach`)."""
        return motion_reach(self.levels, model_disp=self.model_disp, search=search)

    def search_for(self, max_motion: float, *, limit: int) -> int:
        """The smallest ``search`` whose reach covers ``max_motion``, at most ``limit`` (0 with
        one level, where no grid of starts is read)."""
        step = self.reach()
        if self.levels <= 1 or step >= max_motion:
            return 0
        return min(int(limit), math.ceil(max_motion / step) - 1)


def pyramid_reach(shape: tuple, *, max_motion: float, model_disp: int, patch_size: int,
                  levels: Optional[int] = None) -> PyramidReach:
    """The pyramid frames of ``shape`` (H, W) are read with: ``levels`` (default
    :func:`auto_levels`), fewer where a level would be less than two patches across (as
    :meth:`FramePyramid.levels` stops)."""
    if levels is None:
        levels = auto_levels(shape, max_motion=max_motion, model_disp=model_disp,
                             patch_size=patch_size)
    wanted, levels = max(1, int(levels)), 1
    h, w = shape[:2]
    while levels < wanted and min(h, w) >= 2 * patch_size:
        h, w, levels = (h + 1) // 2, (w + 1) // 2, levels + 1
    return PyramidReach(levels=levels, model_disp=model_disp)


class FramePyramid:
    """A frame's gray image pyramid (``cv2.pyrDown``), built once and used as the second frame
    of one pair and the first of the next.

    It also keeps what the reader cuts from a *first* frame (per model and patch settings, a
    :class:`~bgsub.motion.patches.PatchGrids`), so a video's consecutive pairs build each
    frame's pyramid once, and :func:`~bgsub.motion.prepare_first_frame` can do that work ahead
    of time (e.g. in another thread, while the previous pair is read).

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) gray uint8, or (H, W) float32 gray in [0, 1]

    Attributes
    ----------
    images : list of (H_l, W_l) float32
        Level 0 (the frame, gray in [0, 1]) and the coarser levels built so far.
    """

    def __init__(self, frame: np.ndarray) -> None:
        self.images: List[np.ndarray] = [to_gray(frame)]
        self._gray8: Optional[np.ndarray] = None
        self._caches: dict = {}
        self._lock = threading.Lock()  # levels() may be called from two threads at once

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        del state["_lock"]  # locks cannot be pickled; a copy gets its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    @property
    def shape(self) -> tuple:
        """``(H, W)`` of level 0."""
        return self.images[0].shape

    def levels(self, n: int, patch_size: int) -> List[np.ndarray]:
        """The first ``n`` levels, fewer when a level would be less than two patches across."""
        with self._lock:
            while len(self.images) < n and min(self.images[-1].shape) >= 2 * patch_size:
                self.images.append(cv2.pyrDown(self.images[-1]))
            return self.images[:n]

    def gray8(self) -> np.ndarray:
        """Level 0 as ``(H, W) uint8`` (OpenCV's trackers take 8-bit images), converted once: a
        video's frame serves two pairs. An 8-bit frame's gray levels come back exactly."""
        if self._gray8 is None:
            self._gray8 = as_uint8(self.images[0])
        return self._gray8

    def cache(self, model: Any, settings: tuple, make: Any) -> Any:
        """The first-frame cache for one model and patch ``settings``, made by ``make()`` on
        first use; the model is kept alive with it so its ``id`` stays unique."""
        with self._lock:
            key = (id(model), settings)
            if key not in self._caches:
                self._caches[key] = (model, make())
            return self._caches[key][1]


def warp_back(image: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``out(x) = image(matrix @ x)``: a second frame ``(H, W) float32`` resampled into the first
    frame's grid by the ``(3, 3)`` motion ``matrix`` (edge pixels replicated)."""
    h, w = image.shape[:2]
    m = np.asarray(matrix, np.float64)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    if is_affine(m):
        # Affine pre-warps (the coarse levels fit affine motion): the same map, cheaper.
        return cv2.warpAffine(image, m[:2] / m[2, 2], (w, h), flags=flags,
                              borderMode=cv2.BORDER_REPLICATE)
    return cv2.warpPerspective(image, m, (w, h), flags=flags, borderMode=cv2.BORDER_REPLICATE)


def scale_homography(matrix: np.ndarray, factor: float) -> np.ndarray:
    """The ``(3, 3)`` homography ``matrix`` in pixels scaled by ``factor`` (``0.5**l``: full
    resolution to level ``l``; ``2**l`` back)."""
    # diag(f, f, 1) @ matrix @ diag(1/f, 1/f, 1), written out.
    out = np.array(matrix, dtype=np.float64)
    out[:2, 2] *= factor
    out[2, :2] /= factor
    return out
