"""Colour cut: the parts of an object that showed no motion, added by its colours.

The motion evidence finds an object where it is textured; its flat parts (a cow's black flank,
a car's plain door) show no motion and the background model may have learnt them. Around the
placed mask, GrabCut (Rother, Kolmogorov and Blake) fits one colour model to the mask and one to
a band of background beyond it, and a graph cut gives the band's pixels to whichever explains
them, with smooth outlines. Only what it adds to the mask is kept: the motion evidence stays the
judge of what is foreground, the colours only complete it.

Its time grows with the objects: about a ``balanced`` frame's own with small objects, 2.5x with
an object across a third of the frame (docs/BENCHMARKS.md), so only the gated RBM's
``accurate`` uses it (``colour_cut``).
"""

from __future__ import annotations

import cv2
import numpy as np

from bgsub.background.morphology import around, kernel

__all__ = ["CUT_WIDTH", "colour_cut"]

# The width the cut works at: 320 / 480 / 640 px scored within 0.002 of each other on real
# footage (docs/decisions.md), and the cut's time grows with the pixels.
CUT_WIDTH = 480
# Fewer mask pixels than this at the cut's size give the colour model too little to learn from.
MIN_PIXELS = 30


def colour_cut(mask: np.ndarray, image: np.ndarray, *, radius: int) -> np.ndarray:
    """``mask`` ((H, W) uint8 0/255, placed on ``image``, (H, W, 3) or (H, W) uint8) with the
    pixels added that GrabCut gives to the objects within ``radius`` px of it (px of the frame
    shrunk to at most :data:`CUT_WIDTH` wide). A new (H, W) uint8 0/255 array; the mask as it
    is when it is empty or too small to learn colours from."""
    h, w = mask.shape
    scale = min(1.0, CUT_WIDTH / w)
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    small = cv2.resize(mask, size, interpolation=cv2.INTER_NEAREST) > 127
    if np.count_nonzero(small) < MIN_PIXELS:
        return mask.copy()
    # The box reaches a radius beyond the band: its background's colours are learnt there too.
    rows, cols = around(small.view(np.uint8), 2 * radius)
    found = small[rows, cols].view(np.uint8)
    band = cv2.dilate(found, kernel(cv2.MORPH_ELLIPSE, 2 * radius + 1))
    labels = np.full(found.shape, cv2.GC_BGD, np.uint8)
    labels[band > 0] = cv2.GC_PR_BGD
    labels[found > 0] = cv2.GC_PR_FGD
    if np.count_nonzero(labels != cv2.GC_PR_FGD) < MIN_PIXELS:
        return mask.copy()  # too little left to learn the background's colours from
    frame = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    if frame.ndim == 2:
        frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    # GrabCut seeds its colour models by k-means from OpenCV's random generator: the same
    # seed every frame, or a frame's mask would depend on what ran before it. One iteration
    # scores as two (docs/decisions.md).
    cv2.setRNGSeed(0)
    cv2.grabCut(np.ascontiguousarray(frame[rows, cols]), labels, None, np.zeros((1, 65)),
                np.zeros((1, 65)), 1, cv2.GC_INIT_WITH_MASK)
    cut = np.zeros(small.shape, np.uint8)
    cut[rows, cols] = ((labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)) * np.uint8(255)
    added = cv2.resize(cut, (w, h), interpolation=cv2.INTER_LINEAR)
    cv2.threshold(added, 0, 255, cv2.THRESH_BINARY, dst=added)
    return cv2.bitwise_or(mask, added)
