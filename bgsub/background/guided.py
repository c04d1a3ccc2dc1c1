"""The mask placed on the frame's own edges, at the input's size: :func:`guided_mask`.

The engines decide foreground at a working size (320 px wide by default) from scores pooled
over patches and cells and cleaned by morphology, so the fused mask's outline is blocky, and
scaled up to a larger input it is pixels off the object's edge. :func:`guided_mask` places it on
the frame's colour edges with the guided filter of He, Sun and Tang (2010), fitted at the
working size shrunk by ``step`` and applied at the input's (the "fast" guided filter of He and
Sun, 2015): within each window of the shrunk frame the mask is fitted as a linear function of
the colour (``mask ~ a . colour + b``, least squares with ridge ``eps``), the coefficients are
averaged over the windows that hold each pixel, scaled up to the input's size and applied to
the input frame's own colours; foreground is where the result exceeds one half. Where a window
holds an edge of the frame, the mask's edge moves onto it; where the frame is flat (colour
variance well below ``eps``) the mask keeps its local mean. The coefficients vary smoothly
(window averages), so a fit on the frame shrunk by 2 places the outline about as well.

The filter is linear in the mask and local: pixels farther than ``2 radius`` from the mask's
foreground come out 0, so only its bounding box, with a margin, is filtered.
"""

from __future__ import annotations

from typing import List, Optional, Tuple

import cv2
import numpy as np

from bgsub.errors import InputError

__all__ = ["guided_mask"]


def guided_mask(mask: np.ndarray, guide: np.ndarray, full_guide: np.ndarray, *,
                radius: int, eps: float, step: int = 1) -> np.ndarray:
    """``mask`` placed on the frame's edges, at ``full_guide``'s size.

    Parameters
    ----------
    mask : (h, w) uint8
        The mask, 0/255, at the working size.
    guide : (h, w, 3) or (h, w) uint8
        The frame the mask was made from (BGR or gray), at the working size.
    full_guide : (H, W, 3) or (H, W) uint8
        The same frame at the input size (H >= h, W >= w; ``guide`` itself when the sizes are
        equal), with ``guide``'s channels.
    radius : int
        Window radius of the filter, in working-size pixels (>= 1).
    eps : float
        Ridge of the per-window fit, a variance of colour values in [0, 1]: windows whose
        colours vary much less than this keep the mask's mean instead of following the edges.
    step : int
        The fit is made on the mask and frame shrunk by this factor (area averages; the window
        radius shrinks with them, to at least 1) and its coefficients scaled back up (>= 1).

    Returns
    -------
    (H, W) uint8
        0/255: foreground where the filtered mask exceeds one half.

    Raises
    ------
    InputError
        ``step`` below 1.
    """
    if step < 1:
        raise InputError(f"the edge filter's step must be 1 or more, not {step}")
    box = _box_of(mask, 3 * radius + 2, step)
    if box is None:
        return np.zeros(full_guide.shape[:2], np.uint8)
    y0, y1, x0, x1 = box
    crop = guide[y0:y1, x0:x1]
    fitted = _channels(_shrunk(crop, step))
    a, b = _coefficients(_shrunk(mask[y0:y1, x0:x1], step), fitted,
                         max(1, round(radius / step)), np.float32(eps))
    if full_guide.shape[:2] == mask.shape:
        out = np.zeros(mask.shape, np.uint8)
        colours = fitted if step == 1 else _channels(crop)
        out[y0:y1, x0:x1] = _apply(*_grown(a, b, crop.shape[:2]), colours)
        return out
    # Scaled up whole: the coefficients are 0 outside the box.
    h, w = -(-mask.shape[0] // step), -(-mask.shape[1] // step)
    size = (full_guide.shape[1], full_guide.shape[0])
    planes = []
    for part in a + [b]:
        whole = np.zeros((h, w), np.float32)
        whole[y0 // step:y0 // step + part.shape[0], x0 // step:x0 // step + part.shape[1]] = part
        planes.append(cv2.resize(whole, size, interpolation=cv2.INTER_LINEAR))
    # Beyond the box scaled up every plane is exactly 0, and so is the mask: the frame's
    # colours are read and weighed inside it only.
    rows = _reach(y0 // step, -(-y1 // step), h, size[1])
    cols = _reach(x0 // step, -(-x1 // step), w, size[0])
    out = np.zeros(size[::-1], np.uint8)
    out[rows, cols] = _apply([p[rows, cols] for p in planes[:-1]], planes[-1][rows, cols],
                             _channels(full_guide[rows, cols]))
    return out


def _reach(start: int, stop: int, n: int, size: int) -> slice:
    """The pixels, of ``size`` along an axis, that a bilinear scaling up from ``n`` pixels
    draws from the pixels ``start:stop`` (and one more on each side, for safety)."""
    scale = size / n  # output pixel x reads input (x + 0.5) / scale - 0.5 and its next one
    lo = int(np.floor((start - 0.5) * scale - 0.5)) - 1
    hi = int(np.ceil((stop + 0.5) * scale - 0.5)) + 2
    return slice(max(lo, 0), min(hi, size))


def _shrunk(image: np.ndarray, step: int) -> np.ndarray:
    """``image`` shrunk by ``step`` (area averages; a partial block at the end counts as a
    block), or itself for 1."""
    if step == 1:
        return image
    h, w = image.shape[:2]
    return cv2.resize(image, (-(-w // step), -(-h // step)), interpolation=cv2.INTER_AREA)


def _grown(a: List[np.ndarray], b: np.ndarray, shape: tuple) -> tuple:
    """``(a, b)`` scaled up bilinearly to ``shape`` (h, w), as they are when of that shape."""
    if b.shape == shape:
        return a, b
    size = (shape[1], shape[0])
    return ([cv2.resize(x, size, interpolation=cv2.INTER_LINEAR) for x in a],
            cv2.resize(b, size, interpolation=cv2.INTER_LINEAR))


def _box_of(mask: np.ndarray, margin: int,
            step: int = 1) -> Optional[Tuple[int, int, int, int]]:
    """``(y0, y1, x0, x1)``: the bounding box of ``mask``'s foreground grown by ``margin``,
    its start on a multiple of ``step`` and clipped to the mask, or None for an empty mask."""
    x, y, w, h = cv2.boundingRect(mask)
    if w == 0 or h == 0:
        return None
    rows, cols = mask.shape
    y0, x0 = max(0, y - margin), max(0, x - margin)
    return (y0 - y0 % step, min(rows, y + h + margin),
            x0 - x0 % step, min(cols, x + w + margin))


def _coefficients(mask: np.ndarray, colours: List[np.ndarray], radius: int,
                  eps: np.float32) -> Tuple[List[np.ndarray], np.ndarray]:
    """The window-averaged ``(a, b)`` of the fit ``mask ~ a . colours + b`` (``colours``: the
    guide's ``(h, w) float32`` planes, :func:`_channels`): ``a`` one plane per colour, ``b``
    one plane."""
    k = (2 * radius + 1, 2 * radius + 1)

    def box(x: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(x, -1, k, borderType=cv2.BORDER_REFLECT)

    p = mask.astype(np.float32) * np.float32(1.0 / 255.0)
    n = len(colours)
    means = [box(c) for c in colours]
    mean_p = box(p)
    cov = [box(c * p) - m * mean_p for c, m in zip(colours, means)]
    var = {(i, j): box(colours[i] * colours[j]) - means[i] * means[j]
           for i in range(n) for j in range(i, n)}
    a = _ridge_solve(var, cov, eps)
    b = mean_p
    for ai, m in zip(a, means):
        b -= ai * m
    return [box(ai) for ai in a], box(b)


def _apply(a: List[np.ndarray], b: np.ndarray, colours: List[np.ndarray]) -> np.ndarray:
    """``(H, W) uint8`` 0/255: where ``a . colours + b`` exceeds one half."""
    out = b.copy()
    for ai, c in zip(a, colours):
        cv2.accumulateProduct(ai, c, out)  # (one pass, no temporary at the input's size)
    return cv2.compare(out, 0.5, cv2.CMP_GT)


def _channels(image: np.ndarray) -> List[np.ndarray]:
    """The channels of a uint8 image as float32 planes in [0, 1]."""
    planes = cv2.split(image) if image.ndim == 3 else [image]
    return [np.multiply(plane, _UNIT, dtype=np.float32) for plane in planes]


_UNIT = np.float32(1.0 / 255.0)


def _ridge_solve(var: dict, cov: List[np.ndarray], eps: np.float32) -> List[np.ndarray]:
    """Per pixel, ``x = (V + eps I)^-1 c`` for the symmetric 1x1 or 3x3 ``V`` (``var[i, j]``,
    ``i <= j``, ``(h, w) float32`` planes) and the vector ``cov``: the solution's planes, by
    cofactors (a few array passes, no per-pixel loop)."""
    if len(cov) == 1:
        return [cov[0] / (var[0, 0] + eps)]
    a11, a12, a13 = var[0, 0] + eps, var[0, 1], var[0, 2]
    a22, a23, a33 = var[1, 1] + eps, var[1, 2], var[2, 2] + eps
    c11, c12, c13 = a22 * a33 - a23 * a23, a13 * a23 - a12 * a33, a12 * a23 - a13 * a22
    c22, c23, c33 = a11 * a33 - a13 * a13, a12 * a13 - a11 * a23, a11 * a22 - a12 * a12
    # V + eps I is positive definite: the determinant is > 0.
    inv_det = np.float32(1.0) / (a11 * c11 + a12 * c12 + a13 * c13)
    return [(c11 * cov[0] + c12 * cov[1] + c13 * cov[2]) * inv_det,
            (c12 * cov[0] + c22 * cov[1] + c23 * cov[2]) * inv_det,
            (c13 * cov[0] + c23 * cov[1] + c33 * cov[2]) * inv_det]
