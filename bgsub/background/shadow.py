"""Cast shadows are background: :class:`ShadowVeto`.

A shadow moves with the object that casts it, so the motion evidence and the background model
both find it; CDnet's ground truth counts it as background, and so do BMS-26's and DAVIS's
(a car's shade on the road, a swan's on the water). A shadow is the background
darker: the same chromaticity and the same texture at a fraction of the brightness, which an
object seldom is (a texture of its own, or a colour)."""

from __future__ import annotations

import cv2
import numpy as np

from bgsub.background.compensated import CompensatedBackground
from bgsub.background.morphology import around

__all__ = ["ShadowVeto"]

#: Most of a shadow's brightness ratio to the background: a pixel within 5 % of it is noise or
#: the object's own, not shade.
HIGH = 0.95
#: The window (px, odd) over which the frame's and the model's textures are correlated.
WINDOW = 5
#: Below this standard deviation (gray levels, over the window) a texture is flat: two flat
#: windows correlate by noise, and a flat shade of a flat ground is still a shadow.
FLAT = 2.0
#: A pixel's brightness: the sum of its three channels (``cv2.transform``).
_SUM = np.ones((1, 3), np.float32)


class ShadowVeto:
    """Clears from a mask the pixels that look like the background in shade. A pixel is shadow
    where the compensated model has learnt it (age ``min_age`` or more) and the frame is

    * darker than the model's mean by a brightness ratio (sum of the channels) between ``low``
      and :data:`HIGH`;
    * of its chromaticity (each channel's share of the brightness) within ``chroma``;
    * of its texture: the brightness images correlate by ``texture`` or more over
      :data:`WINDOW` x :data:`WINDOW` windows, or both are flat there.

    ``low`` 0 turns the veto off. On gray frames the chromaticity says nothing, and the texture
    alone tells a gray object from shade.
    """

    def __init__(self, *, low: float, chroma: float, texture: float) -> None:
        self.low, self.chroma, self.texture = float(low), float(chroma), float(texture)

    def veto(self, mask: np.ndarray, frame: np.ndarray, bg: CompensatedBackground) -> np.ndarray:
        """``mask`` ((h, w) uint8 0/255, changed in place and returned) less its shadows in
        ``frame`` ((h, w, 3) uint8, at the model's exposure) against ``bg``, the compensated
        model warped to the frame. A gray ((h, w)) frame or model is left as it is."""
        mean = bg.mean
        # (The model is (h, w, c): a gray (h, w) frame never matches its shape.)
        if (self.low <= 0 or mean is None or mean.shape != frame.shape
                or not cv2.countNonZero(mask)):
            return mask
        # Only the mask's box, and the texture windows around it, can matter.
        box = around(mask, WINDOW // 2)
        f = frame[box].astype(np.float32)
        m = mean[box]
        bright_f = cv2.transform(f, _SUM) + np.float32(1)
        bright_m = cv2.transform(m, _SUM) + np.float32(1)
        ratio = bright_f / bright_m
        shade = ((ratio >= self.low) & (ratio <= HIGH) & (mask[box] > 0)
                 & (bg.age[box] >= bg.config.min_age))
        ys, xs = np.nonzero(shade)
        if ys.size == 0:
            return mask
        # The chromaticity of the candidates alone (a few of the box's pixels); the texture
        # needs their windows, so it is correlated over the box and read at the candidates.
        hue_f = f[ys, xs] / bright_f[ys, xs, None]
        hue_m = m[ys, xs] / bright_m[ys, xs, None]
        keep = np.abs(hue_f - hue_m).max(axis=1) <= self.chroma
        keep &= _same_texture(bright_f, bright_m, self.texture)[ys, xs]
        mask[box][ys[keep], xs[keep]] = 0
        return mask


def _same_texture(a: np.ndarray, b: np.ndarray, least: float) -> np.ndarray:
    """``(h, w) bool``: where the two ``(h, w) float32`` images correlate by ``least`` or more
    over :data:`WINDOW`-wide windows, or are both flat there (:data:`FLAT`; the images are
    sums of three channels, so their deviations are three times a gray level's)."""
    size = (WINDOW, WINDOW)
    mean_a, mean_b = cv2.blur(a, size), cv2.blur(b, size)
    var_a = cv2.blur(a * a, size) - mean_a * mean_a
    var_b = cv2.blur(b * b, size) - mean_b * mean_b
    cov = cv2.blur(a * b, size) - mean_a * mean_b
    flat = np.float32((3 * FLAT) ** 2)
    both_flat = (var_a < flat) & (var_b < flat)
    corr = cov / np.sqrt(np.maximum(var_a * var_b, np.float32(1e-6)))
    return (corr >= least) | both_flat
