"""Depth layers: in a 3-D scene the compensated model takes, block by block, the warp that
explains the frame best.

The parallax field (:mod:`bgsub.camera.parallax`) is a median over cells, smooth across an
occlusion where the scene is not: along a ground band's top edge, or a post's sides, it holds
a depth between the two layers', and the model warped by it carries one layer's colours into
the other. That is false foreground along every depth edge, and the model stays wrong there,
frame after frame. So the model is warped a few more ways (the plane alone, the field with
each cell's depth the least or the greatest of its neighbours': see
:meth:`~bgsub.camera.parallax.ParallaxField.neighbour_warps`), each is scored, and each block
of ``parallax_layers`` px keeps the warp of the lowest mean score, for its score and for the
model itself, which then follows the layer the block belongs to.

Pixels under the last mask keep the field's warp: the stale background an object hides,
carried by another layer's motion, would come out behind it as a trail.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub._util import FieldWarp
from bgsub.background.compensated import CompensatedBackground

__all__ = ["LayerWarps", "choose_layers"]

#: A pixel's score counts at most this much in its block's mean: one object's bright pixels do
#: not decide a block their background shares.
SCORE_CAP = 4.0


@dataclass(frozen=True)
class LayerWarps:
    """A frame's other warps of the background (module docstring) and how to choose."""

    warps: Tuple[Optional[FieldWarp], ...]  # beside the field's; None: the plane alone
    block: int  # the side of the blocks that choose (px)
    keep: Optional[np.ndarray]  # (h, w) uint8: the last mask, whose pixels keep the field's


def choose_layers(bg: CompensatedBackground, others: Sequence[CompensatedBackground],
                  frame: np.ndarray, score: np.ndarray, *, block: int,
                  keep: Optional[np.ndarray] = None) -> np.ndarray:
    """Score ``frame`` ((h, w[, 3]) uint8, at the model's exposure) against each of the models
    ``others`` (``bg`` warped other ways: :meth:`CompensatedBackground.warped_copy`) beside
    ``bg``'s own ``score`` ((h, w) float32); each ``block`` x ``block`` neighbourhood takes
    the model of the lowest mean score, but where ``keep`` ((h, w) uint8, the last mask) is
    set. ``bg`` adopts the chosen models (:meth:`CompensatedBackground.adopt`). Returns the
    chosen scores, (h, w) float32."""
    scores = [other.score(frame) for other in others]
    where = _lowest_blocks([score] + scores, block)
    if keep is not None:
        for w in where:
            w[keep > 0] = 0
    chosen = score.copy()
    for s, w in zip(scores, where):
        cv2.copyTo(s, w, chosen)
    bg.adopt(list(others), where)
    return chosen


def _lowest_blocks(scores: Sequence[np.ndarray], block: int) -> list:
    """For each of ``scores[1:]`` ((h, w) float32), ``(h, w) uint8``: 1 where its mean over
    the ``block`` x ``block`` neighbourhood is the lowest of all (ties to the earlier one)."""
    def mean(s: np.ndarray) -> np.ndarray:
        return cv2.blur(np.minimum(s, np.float32(SCORE_CAP)), (block, block))

    best, where = mean(scores[0]), []
    for s in scores[1:]:
        m = mean(s)
        lower = m < best
        np.minimum(best, m, out=best)
        for w in where:  # a later, lower one takes the pixel from an earlier one
            w[lower] = 0
        where.append(lower.view(np.uint8))
    return where
