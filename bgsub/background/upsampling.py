"""The mask at the input's size, its edges placed on the input frame's own edges.

The engines decide foreground at a working size (320 px wide by default). Scaled up bilinearly,
the mask of a 854 x 480 frame keeps the working size's coarse outline, pixels off the object's
edge. :func:`guided_upsample` scales it up with the fast guided filter of He and Sun (2015):
within each window of the working-size frame the mask is fitted as a linear function of the
colour (``mask ~ a . colour + b``, least squares, ridge ``eps``), the coefficients are averaged
over the windows that hold each pixel, scaled up, and applied to the input frame's own colours.
Where a window holds an edge of the frame, the mask's edge follows it; where the frame is flat
(colour variance well below ``eps``) the mask keeps its local mean, its smooth upscaling.
"""

from __future__ import annotations

from typing import List

import cv2
import numpy as np

__all__ = ["guided_upsample"]


def guided_upsample(mask: np.ndarray, guide: np.ndarray, full_guide: np.ndarray, *,
                    radius: int, eps: float) -> np.ndarray:
    """``mask`` scaled up to ``full_guide``'s size, its edges on the full guide's edges.

    Parameters
    ----------
    mask : (h, w) uint8
        The mask, 0/255, at the working size.
    guide : (h, w, 3) or (h, w) uint8
        The frame the mask was made from (BGR or gray), at the working size.
    full_guide : (H, W, 3) or (H, W) uint8
        The same frame at the input size, with ``guide``'s channels.
    radius : int
        Window radius of the filter, in working-size pixels (>= 1).
    eps : float
        Ridge of the per-window fit, a variance of colour values in [0, 1]: windows whose
        colours vary much less than this keep the mask's mean instead of following the edges.

    Returns
    -------
    (H, W) uint8
        0/255: foreground where the filtered mask exceeds one half.
    """
    big = full_guide.shape[:2]
    if not mask.any():
        return np.zeros(big, np.uint8)
    k = (2 * radius + 1, 2 * radius + 1)

    def box(x: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(x, -1, k, borderType=cv2.BORDER_REFLECT)

    p = mask.astype(np.float32) * np.float32(1.0 / 255.0)
    colours = _channels(guide)
    means = [box(c) for c in colours]
    mean_p = box(p)
    cov = [box(c * p) - m * mean_p for c, m in zip(colours, means)]
    var = [[box(colours[i] * colours[j]) - means[i] * means[j] for j in range(len(colours))]
           for i in range(len(colours))]
    a = _ridge_solve(var, cov, np.float32(eps))
    b = mean_p - sum(ai * m for ai, m in zip(a, means))
    size = (big[1], big[0])
    out = cv2.resize(box(b), size, interpolation=cv2.INTER_LINEAR)
    for ai, c in zip(a, _channels(full_guide)):
        out += cv2.resize(box(ai), size, interpolation=cv2.INTER_LINEAR) * c
    return np.where(out > np.float32(0.5), np.uint8(255), np.uint8(0))


def _channels(image: np.ndarray) -> List[np.ndarray]:
    """The channels of a uint8 image as float32 planes in [0, 1]."""
    planes = cv2.split(image) if image.ndim == 3 else [image]
    return [plane.astype(np.float32) * np.float32(1.0 / 255.0) for plane in planes]


def _ridge_solve(var: List[List[np.ndarray]], cov: List[np.ndarray],
                 eps: np.float32) -> List[np.ndarray]:
    """Per pixel, ``x = (V + eps I)^-1 c`` for the symmetric 1x1 or 3x3 ``var`` (nested lists
    of ``(h, w) float32`` planes) and the vector ``cov``: the solution's planes, by cofactors
    (a few array passes, no per-pixel loop)."""
    if len(cov) == 1:
        return [cov[0] / (var[0][0] + eps)]
    a11, a12, a13 = var[0][0] + eps, var[0][1], var[0][2]
    a22, a23, a33 = var[1][1] + eps, var[1][2], var[2][2] + eps
    c11, c12, c13 = a22 * a33 - a23 * a23, a13 * a23 - a12 * a33, a12 * a23 - a13 * a22
    c22, c23, c33 = a11 * a33 - a13 * a13, a12 * a13 - a11 * a23, a11 * a22 - a12 * a12
    inv_det = 1.0 / (a11 * c11 + a12 * c12 + a13 * c13)  # > 0: V is positive semi-definite
    return [(c11 * cov[0] + c12 * cov[1] + c13 * cov[2]) * inv_det,
            (c12 * cov[0] + c22 * cov[1] + c23 * cov[2]) * inv_det,
            (c13 * cov[0] + c23 * cov[1] + c33 * cov[2]) * inv_det]
