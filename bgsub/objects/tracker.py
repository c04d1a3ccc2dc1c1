"""Connected foreground regions of a mask, and a tracker that keeps their ids across frames.

The tracker is greedy and simple on purpose: each region of the new frame takes the id of the
track whose predicted box (its last box moved by its last velocity) overlaps it most (IoU),
then, for the regions and tracks still unmatched, of the nearest predicted centre within
``max_distance``. A track unseen for more than ``max_gap`` frames ends; its id is never reused.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Tuple

import cv2
import numpy as np

Box = Tuple[int, int, int, int]  # x, y, width, height in pixels


@dataclass(frozen=True)
class TrackerConfig:
    """How regions are found and matched.

    Attributes
    ----------
    min_area : int
        Regions of fewer foreground pixels are left out (default 50; at least 1).
    min_iou : float
        Least overlap (intersection over union, 0-1) of a region with a track's predicted box
        to take its id in the first pass (default 0.1).
    max_distance : float
        Largest distance in pixels between a region's centre and a track's predicted centre
        for the second pass (default 40).
    max_gap : int
        Frames a track may go unseen and still be matched (default 5; 0: only the previous
        frame's tracks).
    """

    min_area: int = 50
    min_iou: float = 0.1
    max_distance: float = 40.0
    max_gap: int = 5

    def __post_init__(self) -> None:
        if int(self.min_area) != self.min_area or self.min_area < 1:
            raise ValueError(f"min_area must be a whole number of at least 1, not "
                             f"{self.min_area!r}")
        if not 0.0 <= self.min_iou <= 1.0:
            raise ValueError(f"min_iou must be in [0, 1], not {self.min_iou!r}")
        if not self.max_distance >= 0.0:
            raise ValueError(f"max_distance must be >= 0, not {self.max_distance!r}")
        if int(self.max_gap) != self.max_gap or self.max_gap < 0:
            raise ValueError(f"max_gap must be a whole number >= 0, not {self.max_gap!r}")


@dataclass(frozen=True)
class TrackedObject:
    """One region of one frame: ``id`` (from 1, kept across frames), ``box`` ``(x, y, w, h)``
    in pixels, ``area`` (foreground pixels) and ``centroid`` ``(cx, cy)`` (float pixels)."""

    id: int
    box: Box
    area: int
    centroid: Tuple[float, float]


def find_regions(mask: np.ndarray, *, min_area: int = 1) -> List[Tuple[Box, int, Tuple[float,
                                                                                         float]]]:
    """The 8-connected foreground regions of ``mask`` ((H, W) uint8, > 127 foreground, or
    bool) of at least ``min_area`` pixels, as ``(box, area, centroid)``, top to bottom."""
    binary = (np.asarray(mask) > 127).astype(np.uint8) if mask.dtype != bool \
        else mask.astype(np.uint8)
    count, _, stats, centroids = cv2.connectedComponentsWithStats(binary, connectivity=8)
    regions = []
    for label in range(1, count):
        x, y, w, h, area = (int(v) for v in stats[label])
        if area >= min_area:
            cx, cy = centroids[label]
            regions.append(((x, y, w, h), area, (float(cx), float(cy))))
    return regions


def iou(a: Box, b: Box) -> float:
    """Intersection over union of two ``(x, y, w, h)`` boxes."""
    width = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    height = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    inter = max(width, 0) * max(height, 0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0.0


@dataclass
class _Track:
    id: int
    box: Box
    centroid: Tuple[float, float]
    velocity: Tuple[float, float] = (0.0, 0.0)
    unseen: int = 0  # frames since it was last matched

    def predicted(self) -> Tuple[Box, Tuple[float, float]]:
        steps = self.unseen + 1
        dx, dy = self.velocity[0] * steps, self.velocity[1] * steps
        x, y, w, h = self.box
        box = (int(round(x + dx)), int(round(y + dy)), w, h)
        return box, (self.centroid[0] + dx, self.centroid[1] + dy)


@dataclass
class ObjectTracker:
    """Ids for the regions of successive masks; :meth:`update` once per frame, in order."""

    config: TrackerConfig = field(default_factory=TrackerConfig)
    _tracks: Dict[int, _Track] = field(default_factory=dict, init=False, repr=False)
    _next_id: int = field(default=1, init=False, repr=False)

    def update(self, mask: np.ndarray) -> List[TrackedObject]:
        """The regions of ``mask`` ((H, W) uint8 0/255 or bool) with their ids, top to bottom."""
        regions = find_regions(mask, min_area=self.config.min_area)
        matches = self._match(regions)
        objects = []
        for index, (box, area, centroid) in enumerate(regions):
            track = self._tracks.get(matches.get(index, -1))
            if track is None:
                track = _Track(self._next_id, box, centroid, unseen=-1)  # 0 once aged
                self._tracks[track.id] = track
                self._next_id += 1
            else:
                steps = track.unseen + 1
                track.velocity = ((centroid[0] - track.centroid[0]) / steps,
                                  (centroid[1] - track.centroid[1]) / steps)
                track.box, track.centroid, track.unseen = box, centroid, -1
            objects.append(TrackedObject(track.id, box, area, centroid))
        self._age()
        return objects

    def _match(self, regions: list) -> Dict[int, int]:
        """Region index -> track id: greedy by overlap, then by distance."""
        predicted = {tid: t.predicted() for tid, t in self._tracks.items()}
        pairs = [(iou(region[0], box), i, tid) for i, region in enumerate(regions)
                 for tid, (box, _) in predicted.items()]
        chosen = _greedy(sorted((p for p in pairs if p[0] >= self.config.min_iou
                                 and p[0] > 0), reverse=True), {})
        pairs = [(float(np.hypot(region[2][0] - c[0], region[2][1] - c[1])), i, tid)
                 for i, region in enumerate(regions) for tid, (_, c) in predicted.items()]
        return _greedy(sorted(p for p in pairs if p[0] <= self.config.max_distance), chosen)

    def _age(self) -> None:
        for tid in list(self._tracks):
            track = self._tracks[tid]
            track.unseen += 1
            if track.unseen > self.config.max_gap:
                del self._tracks[tid]


def _greedy(pairs: list, chosen: Dict[int, int]) -> Dict[int, int]:
    """Take ``(score, region, track)`` pairs in order, each region and track at most once."""
    taken = set(chosen.values())
    for _, region, tid in pairs:
        if region not in chosen and tid not in taken:
            chosen[region] = tid
            taken.add(tid)
    return chosen
