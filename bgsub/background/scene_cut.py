"""A new shot restarts the model (:class:`SceneCut`)."""

from __future__ import annotations

import numpy as np

from bgsub.motion.result import NO_MOTION, MotionResult

__all__ = ["SceneCut"]


class SceneCut:
    """A new shot: after compensation more than ``scene_cut`` of the pixels with history still
    differ from the model while fewer than ``cut_support`` of the motion vectors agree with the
    fitted motion (a new shot has no consistent motion), or more than 80 % differ whatever the
    motion says."""

    def __init__(self, scene_cut: float, cut_support: float) -> None:
        self.scene_cut = float(scene_cut)
        self.cut_support = float(cut_support)

    def is_cut(self, score: np.ndarray, young: np.ndarray, result: MotionResult) -> bool:
        """Whether the frame starts a new shot, given the background ``score`` ((h, w)
        float32, above 1 = differs), the pixels without history ``young`` ((h, w) bool, not
        counted) and the frame's motion ``result`` (:data:`NO_MOTION`, a repeated frame's,
        is no new shot)."""
        old = max(int(np.count_nonzero(~young)), 1)
        used = max(int(np.count_nonzero(result.weights > 0)), 1)
        support = result.motion.n_inliers / used if result.motion.ok else 0.0
        if result is NO_MOTION:
            support = 1.0
        changed = np.count_nonzero((score > 1.0) & ~young) / old
        return (changed > self.scene_cut and support < self.cut_support) or changed > 0.8
