"""A few frames of one input for the HTML report of `bgsub compare`: the input, the ground truth
(when there is one) and each method's mask, shrunk and encoded (JPEG for the input, PNG for the
rest), kept while the frame loop runs.

Which frames: with ground truth, frames that are scored; without, every frame but the first
(the engines have seen nothing before it). The length of the input need not be known: every
``stride``-th candidate is kept and, when more than :data:`_KEEP_AT_MOST` are held, every second
one is dropped and the stride doubles; at the end :data:`FRAMES_SHOWN` evenly spaced ones are
chosen from those held.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, List, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.evaluation.groundtruth import GroundTruth
from bgsub.evaluation.side_by_side import TRUTH_LABEL, truth_picture
from bgsub.io.loop import Consumer, FrameResult

#: Frames shown per input, and their width in pixels (frames are never enlarged).
FRAMES_SHOWN = 3
THUMB_WIDTH = 240
_KEEP_AT_MOST = 4 * FRAMES_SHOWN
_JPEG_QUALITY = 75


@dataclass(frozen=True)
class Picture:
    """One encoded picture: ``mime`` (``image/png`` or ``image/jpeg``) and its bytes."""

    mime: str
    data: bytes


@dataclass(frozen=True)
class FrameTiles:
    """One frame: its number (1-based) and its pictures by label (``"input"``, ``"ground
    truth"``, then one per method), in that order."""

    number: int
    pictures: Tuple[Tuple[str, Picture], ...]


@dataclass(frozen=True)
class SequenceFrames:
    """The frames shown of one input (sequence ``name`` of family ``family``), and its
    side-by-side video's path relative to the report folder ("" when none was written)."""

    name: str
    family: str
    frames: Tuple[FrameTiles, ...] = field(default_factory=tuple)
    video: str = ""


def encode_picture(image: np.ndarray, *, width: int = THUMB_WIDTH, jpeg: bool = False
                   ) -> Picture:
    """``image`` ((H, W) or (H, W, 3) BGR uint8) shrunk to at most ``width`` pixels wide
    (area averaging for photographs, nearest neighbour for masks, so they stay 0/255) and
    encoded as JPEG or PNG: a gray PNG when the three channels are equal, a 1-bit one when
    it holds only 0 and 255 (a mask takes a third of the bytes)."""
    h, w = image.shape[:2]
    if image.ndim == 3 and not jpeg and (image[..., 0] == image[..., 1]).all() \
            and (image[..., 0] == image[..., 2]).all():
        image = image[..., 0]
    if w > width:
        size = (width, max(1, round(h * width / w)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA if jpeg
                           else cv2.INTER_NEAREST)
    if jpeg:
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, _JPEG_QUALITY])
        mime = "image/jpeg"
    else:
        flags = [cv2.IMWRITE_PNG_COMPRESSION, 9]
        if image.ndim == 2 and not np.any((image != 0) & (image != 255)):
            flags += [cv2.IMWRITE_PNG_BILEVEL, 1]
        ok, data = cv2.imencode(".png", image, flags)
        mime = "image/png"
    if not ok:  # (OpenCV encodes any uint8 picture; kept as a plain error, never expected)
        raise ValueError(f"cannot encode a {w}x{h} picture")
    return Picture(mime, data.tobytes())


def spread(items: Sequence, count: int) -> List:
    """``count`` items of ``items`` evenly spaced, the last one included (all when fewer)."""
    if len(items) <= count:
        return list(items)
    last = len(items) - 1
    return [items[round(last * (k + 1) / count)] for k in range(count)]


class ReportFrames(Consumer):
    """A consumer of :class:`bgsub.io.loop.FrameLoop` keeping a few encoded frames of one input
    (see the module docstring) for :class:`SequenceFrames`.

    Parameters
    ----------
    methods : sequence of str
        The engines whose masks are shown, in order.
    truth : GroundTruth, optional
        Shown as a tile (:func:`bgsub.evaluation.side_by_side.truth_picture`).
    numbers : iterable of int, optional
        The frame numbers (1-based) worth showing, e.g. those scored; default every frame but
        the first one processed.
    """

    def __init__(self, methods: Sequence[str], *, truth: Optional[GroundTruth] = None,
                 numbers: Optional[Iterable[int]] = None) -> None:
        self.methods = list(methods)
        self.truth = truth
        self.numbers = set(numbers) if numbers is not None else None
        self._held: List[FrameTiles] = []
        self._candidates = 0
        self._stride = 1
        self._seen_any = False
        self._pending: Optional[FrameTiles] = None

    def _wanted(self, number: int) -> bool:
        if self.numbers is not None:
            return number in self.numbers
        return self._seen_any

    def prepare(self, result: FrameResult) -> None:
        # Encoded here (interruptible), kept in add(): the frame is shown only if every output
        # got it.
        keep = self._wanted(result.index + 1) and self._candidates % self._stride == 0
        self._pending = self._tiles(result) if keep else None

    def add(self, result: FrameResult) -> None:
        if self._wanted(result.index + 1):
            self._candidates += 1
        self._seen_any = True
        if self._pending is None:
            return
        self._held.append(self._pending)
        if len(self._held) > _KEEP_AT_MOST:
            self._held = self._held[::2]
            self._stride *= 2

    def _tiles(self, result: FrameResult) -> FrameTiles:
        number = result.index + 1
        pictures = [("input", encode_picture(result.frame, jpeg=True))]
        if self.truth is not None:
            pictures.append((TRUTH_LABEL, encode_picture(truth_picture(self.truth, number))))
        pictures += [(m, encode_picture(result.masks[m])) for m in self.methods]
        return FrameTiles(number, tuple(pictures))

    def result(self, *, name: str, family: str, video: str = "") -> SequenceFrames:
        """The frames chosen, as :class:`SequenceFrames` of input ``name``."""
        return SequenceFrames(name, family, tuple(spread(self._held, FRAMES_SHOWN)), video)
