"""The side-by-side picture of `bgsub compare`: the input frame, the ground truth (when there
is one) and one labelled mask per method, as tiles of one video frame.

The ground-truth tile shows the CDnet labels as they are stored, which reads as intended:
255 (moving object) white, 170 (unknown, object rims) light grey, 85 (outside the region of
interest) mid grey, 50 (hard shadow) dark grey, 0 black. Frames without a ground-truth file get
a dark blue tile (:data:`NO_TRUTH_BGR`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.evaluation.groundtruth import GroundTruth
from bgsub.io.loop import Consumer, FrameResult

# Side-by-side tiles are shrunk (never enlarged) to at most this height, and the whole picture
# to at most this width. OpenCV's mp4v writer has no bitrate control (about 0.26 bytes per pixel
# per frame measured on mask tiles), so the file size follows the picture size: 180 px tiles keep
# input + 4 methods on 320x240 frames near 55 KiB per frame.
TILE_HEIGHT = 180
_VIDEO_MAX_WIDTH = 1600
_TILES_PER_ROW = 5

#: The label of the ground-truth tile.
TRUTH_LABEL = "ground truth"
#: The ground-truth tile of a frame that has no ground truth (BGR).
NO_TRUTH_BGR = (64, 32, 0)


@dataclass(frozen=True)
class TileLayout:
    """Where each tile of the side-by-side picture goes.

    ``labels[0]`` is the input, then one label per method; tiles fill rows of at most
    :data:`_TILES_PER_ROW`, each ``tile_width x tile_height`` (even numbers, so every codec
    takes the picture).
    """

    labels: Tuple[str, ...]
    tile_width: int
    tile_height: int
    columns: int
    rows: int

    @property
    def width(self) -> int:
        return self.columns * self.tile_width

    @property
    def height(self) -> int:
        return self.rows * self.tile_height

    @classmethod
    def for_frames(cls, width: int, height: int, labels: Sequence[str], *,
                   tile_height: int = TILE_HEIGHT) -> "TileLayout":
        """Layout for frames of ``width x height``, one tile per label, tiles at most
        ``tile_height`` pixels high (frames are never enlarged)."""
        n = len(labels)
        rows = math.ceil(n / _TILES_PER_ROW)
        columns = math.ceil(n / rows)
        max_width = max(_VIDEO_MAX_WIDTH, columns * tile_height * width / height)
        scale = min(1.0, tile_height / height, max_width / (columns * width))
        tile_w = max(2, int(width * scale) // 2 * 2)
        tile_h = max(2, int(height * scale) // 2 * 2)
        return cls(tuple(labels), tile_w, tile_h, columns, rows)

    def compose(self, frame: np.ndarray, masks: Sequence[np.ndarray]) -> np.ndarray:
        """The picture: ``frame`` then ``masks`` as labelled tiles.

        Parameters
        ----------
        frame : (H, W, 3) uint8 BGR
        masks : sequence of (h, w) uint8 0/255 or (h, w, 3) uint8 BGR, one per further label
            (any size; resized to the tile)

        Returns
        -------
        (height, width, 3) uint8 BGR picture.
        """
        canvas = np.zeros((self.height, self.width, 3), np.uint8)
        size = (self.tile_width, self.tile_height)
        for k, (label, image) in enumerate(zip(self.labels, [frame, *masks])):
            shrink = image.shape[1] > self.tile_width
            tile = cv2.resize(image, size, interpolation=cv2.INTER_AREA if shrink
                              else cv2.INTER_NEAREST)
            if tile.ndim == 2:
                tile = cv2.cvtColor(tile, cv2.COLOR_GRAY2BGR)
            _draw_label(tile, label)
            # A thin gray frame keeps neighbouring white masks apart.
            cv2.rectangle(tile, (0, 0), (tile.shape[1] - 1, tile.shape[0] - 1), (96, 96, 96), 1)
            r, c = divmod(k, self.columns)
            y, x = r * self.tile_height, c * self.tile_width
            canvas[y:y + self.tile_height, x:x + self.tile_width] = tile
        return canvas


def truth_picture(gt: GroundTruth, number: int) -> np.ndarray:
    """The ground truth of frame ``number`` (1-based) as a picture: ``(H, W, 3) uint8`` BGR,
    the CDnet labels as gray levels (see the module docstring), pixels outside ``ROI.bmp`` as
    85 (outside the region of interest); a dark blue picture when the frame has no ground
    truth."""
    if number not in gt.frames:
        return np.full((gt.height, gt.width, 3), NO_TRUTH_BGR, np.uint8)
    labels = gt.labels(number)
    if gt.roi is not None:
        labels = np.where(gt.roi, labels, np.uint8(85))
    return cv2.cvtColor(labels, cv2.COLOR_GRAY2BGR)


def _draw_label(tile: np.ndarray, text: str) -> None:
    """Write ``text`` in the tile's top-left corner on a dark box (in place)."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    scale = max(0.35, min(0.7, tile.shape[0] / 400))
    thickness = 1
    (tw, th), base = cv2.getTextSize(text, font, scale, thickness)
    cv2.rectangle(tile, (0, 0), (min(tile.shape[1] - 1, tw + 6), th + base + 5), (0, 0, 0), -1)
    cv2.putText(tile, text, (3, th + 3), font, scale, (0, 255, 255), thickness, cv2.LINE_AA)


class SideBySideWriter(Consumer):
    """A consumer of :class:`bgsub.io.loop.FrameLoop` that writes, per frame, the input, the
    ground truth ``truth`` (when given; frame ``index`` is ground-truth frame ``index + 1``) and
    the masks of ``methods`` (in that order) as one picture laid out by ``layout`` (whose labels
    name those tiles) into ``sink`` (a :class:`bgsub.io.sinks.VideoSink` of the layout's size),
    and finishes the sink when the run ends."""

    def __init__(self, sink: Any, layout: TileLayout, methods: Sequence[str], *,
                 truth: Optional[GroundTruth] = None) -> None:
        self.sink = sink
        self.layout = layout
        self.methods = list(methods)
        self.truth = truth
        self._picture: Optional[np.ndarray] = None

    def prepare(self, result: FrameResult) -> None:
        # Drawn before any output is written: an interrupt here leaves the frame out of all.
        tiles = [result.masks[m] for m in self.methods]
        if self.truth is not None:
            tiles.insert(0, truth_picture(self.truth, result.index + 1))
        self._picture = self.layout.compose(result.frame, tiles)

    def add(self, result: FrameResult) -> None:
        self.sink.write(self._picture)

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        self.sink.finish(complete=complete, error=error)
