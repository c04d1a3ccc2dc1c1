"""The region of interest: the part of the frame an engine watches.

Every engine takes it (``create_engine(name, roi=...)``, ``bgsub run --roi mask.png``): a mask
image whose white pixels are watched, of the frames' size or scaled to it (nearest neighbour).
Outside it an engine reports no foreground, and the moving-camera engine gives the motion
vectors there weight 0, so the camera-motion fit ignores what moves with the camera or on its
own outside it (a dashboard, a watermark, a robot's own arm)::

    engine = bgsub.create_engine("grbm", roi="roi.png")      # or an (H, W) array
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Callable, Dict, Tuple

import cv2
import numpy as np

from bgsub.errors import InputError

__all__ = ["RegionOfInterest", "WholeFrame", "WHOLE_FRAME", "FrameLess", "ROI_HELP"]

#: What the ``roi`` parameter every engine takes means (``bgsub methods``).
ROI_HELP = ("region of interest: a mask image (white = watched; the frames' size or their "
            "aspect ratio, scaled to them) or, from Python, an (H, W) array (non-zero = "
            "watched); no foreground outside it, and moving-camera engines leave its motion "
            "out of the camera fit (empty = the whole frame)")

# Aspect ratios that differ by less than this (relative) are the same: a mask drawn at another
# resolution rounds its size.
_ASPECT_TOLERANCE = 0.02


def _read_mask(path: str) -> np.ndarray:
    """The image file ``path`` as an ``(H, W) bool`` mask: gray level above 127 = watched."""
    from bgsub.io.sources import decode_image

    if not os.path.exists(path):
        raise InputError(f"{path}: no such file (the region of interest)")
    try:
        data = np.fromfile(path, np.uint8)
    except OSError as err:
        raise InputError(f"{path}: cannot read the region of interest "
                         f"({err.strerror or err})") from None
    image = decode_image(data, name=path)
    if image is None:
        raise InputError(f"{path}: cannot read the region of interest (not an image)")
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) > 127


class RegionOfInterest:
    """Where foreground is looked for: ``mask`` ``(H, W)``, true (non-zero) where watched.

    ``name`` says where it came from, in messages. :meth:`at` gives it at a frame size."""

    def __init__(self, mask: Any, *, name: str = "the region of interest") -> None:
        mask = np.asarray(mask)
        if mask.ndim == 3 and mask.shape[2] in (1, 3, 4):
            mask = mask.any(axis=2)
        if mask.ndim != 2 or mask.size == 0 or mask.dtype.kind not in "biuf":
            raise InputError(f"{name} must be an (H, W) image or array, not "
                             f"{mask.dtype} of shape {mask.shape}")
        self.mask = mask != 0
        self.name = name
        if not self.mask.any():
            raise InputError(f"{name} is all black: nothing would be watched (white = watched)")
        self._sizes: Dict[Tuple[int, int], np.ndarray] = {}

    @classmethod
    def from_value(cls, value: Any) -> "RegionOfInterest":
        """A region from an image file's path, an array, or a region (returned as it is)."""
        if isinstance(value, RegionOfInterest):
            return value
        if isinstance(value, (str, os.PathLike)):
            path = os.fspath(value)
            return cls(_read_mask(path), name=path)
        return cls(value)

    def at(self, shape: Tuple[int, ...]) -> np.ndarray:
        """The region at frames of ``shape`` ``(h, w, ...)``: ``(h, w) bool``, scaled with
        nearest neighbour. :class:`InputError` when its aspect ratio is not the frames'."""
        h, w = int(shape[0]), int(shape[1])
        found = self._sizes.get((h, w))
        if found is not None:
            return found
        mh, mw = self.mask.shape
        if abs((mw / mh) / (w / h) - 1.0) > _ASPECT_TOLERANCE:
            raise InputError(f"{self.name} is {mw}x{mh} but the frames are {w}x{h}: a region "
                             "of interest must have the frames' aspect ratio (it is scaled to "
                             "them)")
        scaled = self.mask if (mh, mw) == (h, w) else cv2.resize(
            self.mask.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
        if not scaled.any():
            raise InputError(f"{self.name} watches nothing once scaled to {w}x{h}")
        self._sizes[(h, w)] = scaled
        return scaled

    def clear_outside(self, mask: np.ndarray) -> None:
        """Set the ``(H, W) uint8`` foreground ``mask`` to 0 outside the region, in place."""
        mask[~self.at(mask.shape)] = 0

    def inside(self, points: np.ndarray, shape: Tuple[int, ...]) -> np.ndarray:
        """``(N,) bool``: which ``(N, 2)`` points ``(x, y)`` of an ``(h, w)`` frame lie in the
        region (points off the frame do not)."""
        region = self.at(shape)
        h, w = region.shape
        xy = np.rint(np.asarray(points, np.float64).reshape(-1, 2))
        ok = np.isfinite(xy).all(axis=1)
        ok &= (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
        out = np.zeros(len(xy), bool)
        idx = xy[ok].astype(np.intp)
        out[ok] = region[idx[:, 1], idx[:, 0]]
        return out

    def restrict_fit(self, fit: Callable[..., Any]) -> Callable[..., Any]:
        """The camera fit ``fit(points, disp, weights, shape)`` with the vectors outside the
        region given weight 0."""

        def restricted(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                       shape: tuple) -> Any:
            return fit(points, disp, self.weights(points, weights, shape), shape)

        return restricted

    def weights(self, points: np.ndarray, weights: np.ndarray, shape: tuple) -> np.ndarray:
        """``weights`` ``(N,) float32`` with those of points outside the region set to 0 (a
        copy)."""
        return np.where(self.inside(points, shape), weights, 0).astype(np.float32)

    def restrict(self, result: Any, shape: tuple) -> Any:
        """A front end's :class:`~bgsub.motion.result.MotionResult` in an ``(h, w)`` frame
        with the vectors outside the region unused (weight and evidence weight 0)."""
        if not len(result.points):
            return result
        evidence = None if result.violation_weights is None else self.weights(
            result.points, result.violation_weights, shape)
        return dataclasses.replace(result, weights=self.weights(result.points, result.weights,
                                                                shape),
                                   violation_weights=evidence)

    def unwatched(self, young: np.ndarray) -> np.ndarray:
        """``young`` ((h, w) bool) with every pixel outside the region set (``young | ~at``):
        what changes there is no new shot."""
        return young | ~self.at(young.shape)


class WholeFrame:
    """No region of interest: the whole frame is watched (what an engine uses for ``roi``
    None)."""

    @staticmethod
    def restrict_fit(fit: Callable[..., Any]) -> Callable[..., Any]:
        return fit

    @staticmethod
    def restrict(result: Any, shape: tuple) -> Any:
        return result

    @staticmethod
    def unwatched(young: np.ndarray) -> np.ndarray:
        return young

    @staticmethod
    def clear_outside(mask: np.ndarray) -> None:
        pass


#: The region of interest of an engine without one.
WHOLE_FRAME = WholeFrame()


class FrameLess:
    """The frame less the ``(h, w) bool`` pixels an engine found it must not watch (frame-fixed
    overlays, :mod:`bgsub.background.overlay`), as a region of interest: :meth:`of` gives it
    for the latest such mask, made anew only when the mask changes."""

    def __init__(self) -> None:
        self._mask: Any = None
        self._region: Any = WHOLE_FRAME

    def of(self, excluded: Any) -> Any:
        """The region without the ``excluded`` pixels ((h, w) bool), or :data:`WHOLE_FRAME`
        for None."""
        if excluded is not self._mask:
            self._mask = excluded
            self._region = (WHOLE_FRAME if excluded is None
                            else RegionOfInterest(~excluded, name="the frame less its overlays"))
        return self._region
