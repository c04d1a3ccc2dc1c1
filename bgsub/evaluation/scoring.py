"""Where masks meet ground truth: one sequence's confusion counts, frame by frame.

:func:`bgsub.evaluation.cdnet.evaluate_sequence` feeds a :class:`SequenceScorer` the masks it
reads from files; `bgsub compare` feeds one the masks its engines produce. Both therefore count
with the same rules (labels, ``ROI.bmp``, sizes) and the same messages.
"""

from __future__ import annotations

from typing import Any, Dict, Iterable, List, Mapping, Optional

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.evaluation.groundtruth import GroundTruth
from bgsub.evaluation.metrics import Counts, count_frame, frame_size, is_uniform_scale
from bgsub.io.loop import Consumer, FrameResult


class SequenceScorer:
    """Confusion counts of one sequence's masks against its ground truth.

    Attributes
    ----------
    gt : GroundTruth
    counts : Counts
        Summed over the frames :meth:`score` or :meth:`add` took.
    scaled_from : str or None
        ``"WxH"`` of the first mask :meth:`score` brought to the ground truth's size.
    """

    def __init__(self, gt: GroundTruth) -> None:
        self.gt = gt
        self.counts = Counts()
        self.scaled_from: Optional[str] = None

    def count(self, number: int, mask: np.ndarray, *,
              labels: Optional[np.ndarray] = None) -> Counts:
        """Counts of frame ``number`` (1-based) for ``mask``, ``(H, W) uint8`` at the ground
        truth's size (foreground > 127); not added to :attr:`counts`. ``labels``: the frame's
        ``(H, W) uint8`` labels when already read (``gt.labels(number)``)."""
        return self._count(number, mask, self.gt.labels(number) if labels is None else labels)

    def add(self, counts: Counts) -> None:
        """Add one frame's counts (from :meth:`count`) to :attr:`counts`."""
        self.counts += counts

    def score(self, number: int, mask: np.ndarray, *, source: str) -> None:
        """Count a predicted mask read from ``source`` (named in errors) for frame ``number``.

        ``mask`` is ``(h, w) uint8`` 0/255; a uniform scale of the ground truth's size (the
        masks of ``bgsub run --width/--scale``) is resized to it with nearest neighbour, so it
        stays 0/255. Another size, or 0/1 values, are an :class:`InputError`.
        """
        labels = self.gt.labels(number)
        gt = self.gt
        if mask.shape != labels.shape:
            if not is_uniform_scale((mask.shape[1], mask.shape[0]), (gt.width, gt.height)):
                raise InputError(f"prediction {source} is {frame_size(mask)} but ground truth "
                                 f"{gt.frames[number]} is {frame_size(labels)}")
            self.scaled_from = self.scaled_from or frame_size(mask)
            mask = cv2.resize(mask, (gt.width, gt.height), interpolation=cv2.INTER_NEAREST)
        if int(mask.max()) == 1:
            # 0/1 masks (mask.astype(np.uint8)) would score as all background: a slip, not
            # a prediction.
            raise InputError(f"prediction {source} holds 0/1 values; masks are 0/255 "
                             "(foreground above 127): multiply by 255, or give bool masks")
        self.counts += self._count(number, mask, labels)

    def score_missing(self, number: int) -> None:
        """Count frame ``number`` as predicted all background (a missing mask)."""
        labels = self.gt.labels(number)
        self.counts += count_frame(np.zeros_like(labels), labels, self.gt.roi)

    def _count(self, number: int, mask: np.ndarray, labels: np.ndarray) -> Counts:
        try:
            return count_frame(mask, labels, self.gt.roi)
        except InputError as err:
            raise InputError(f"{self.gt.frames[number]}: {err}") from None


class GroundTruthScorer(Consumer):
    """A consumer of :class:`bgsub.io.loop.FrameLoop` that scores every engine's masks of the
    frames ``numbers`` against ``gt``, as :func:`bgsub.evaluation.cdnet.evaluate_sequence`
    would score them written to files.

    Frame ``index`` (0-based) is ground-truth frame ``index + 1``. The masks must be at the
    ground truth's size, ``(H, W) uint8`` 0/255. Counting happens in :meth:`prepare`, so an
    interrupt there leaves the frame out; :meth:`add` (signals held) adds the counts, so the
    figures cover exactly the frames every output of the loop got.

    Attributes
    ----------
    scorers : dict of str to SequenceScorer
        Per engine, by name (after :meth:`start`).
    scored : list of int
        Frame numbers added, in order.
    """

    def __init__(self, gt: GroundTruth, numbers: Iterable[int]) -> None:
        self.gt = gt
        self.numbers = set(numbers)
        self.scorers: Dict[str, SequenceScorer] = {}
        self.scored: List[int] = []
        self._pending: Optional[Dict[str, Counts]] = None

    def start(self, engines: Mapping[str, Any]) -> None:
        self.scorers = {name: SequenceScorer(self.gt) for name in engines}

    def prepare(self, result: FrameResult) -> None:
        number = result.index + 1
        self._pending = None
        if number in self.numbers:
            labels = self.gt.labels(number)
            self._pending = {name: self.scorers[name].count(number, mask, labels=labels)
                             for name, mask in result.masks.items()}

    def add(self, result: FrameResult) -> None:
        if self._pending is None:
            return
        for name, counts in self._pending.items():
            self.scorers[name].add(counts)
        self.scored.append(result.index + 1)

    def counts(self, name: str) -> Counts:
        """The counts of engine ``name`` over the frames added."""
        return self.scorers[name].counts if name in self.scorers else Counts()
