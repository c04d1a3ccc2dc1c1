"""A frame brought to the compensated background model's exposure (:func:`match_exposure`), so
auto exposure or a whole frame's flicker is not taken for foreground."""

from __future__ import annotations

from typing import Tuple

import cv2
import numpy as np

from bgsub.background.compensated import CompensatedBackground

__all__ = ["match_exposure", "same_exposure", "EXPOSURE_TOLERANCE", "SATURATED"]

#: Gains this close to 1 leave the frame as it is (under a rounding's worth at mid-gray).
EXPOSURE_TOLERANCE = 0.005
#: Gray levels at which a camera's value may be clipped.
SATURATED = 250


def match_exposure(frame: np.ndarray, model: CompensatedBackground) -> Tuple[np.ndarray, float]:
    """``(exposed, gain)``: ``frame`` ((h, w) or (h, w, C) uint8) divided by its brightness gain
    against ``model`` (:meth:`~bgsub.background.compensated.CompensatedBackground.exposure_gain`),
    rounded and saturated, and that gain; ``(frame, 1.0)`` when the gain is within
    :data:`EXPOSURE_TOLERANCE` of 1.

    A camera's auto exposure scales the whole frame by a few percent a frame; the model,
    learning at ``alpha``, lags behind and calls every bright pixel foreground. Brought to the
    model's exposure, frames keep the model's colours. A value clipped at :data:`SATURATED` or
    above says only that the scene is at least that bright, so it takes the model's value where
    that is brighter than the divided one."""
    gain = model.exposure_gain(frame)
    if abs(gain - 1.0) <= EXPOSURE_TOLERANCE:
        return frame, 1.0
    exposed = cv2.convertScaleAbs(frame, alpha=1.0 / gain)
    clipped = np.asarray(frame) >= SATURATED
    if clipped.any():
        mean = cv2.convertScaleAbs(model.mean).reshape(exposed.shape)
        np.maximum(exposed, mean, out=exposed, where=clipped)
    return exposed, gain


def same_exposure(frame: np.ndarray, model: CompensatedBackground) -> Tuple[np.ndarray, float]:
    """``(frame, 1.0)``: exposure matching turned off (``match_exposure`` false)."""
    return frame, 1.0
