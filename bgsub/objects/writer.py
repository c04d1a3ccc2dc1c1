"""The tracked objects of a run as a file, and drawn into the overlay video.

Two layouts, chosen by the file's extension:

* ``.jsonl``: one JSON object per frame, ``{"frame": N, "objects": [{"id": K, "box": [x, y, w,
  h], "area": A, "centroid": [cx, cy]}, ...]}``, every frame (also those without objects);
* ``.csv``: the MOTChallenge layout, one line per object, no header: ``frame, id, bb_left,
  bb_top, bb_width, bb_height, conf, -1, -1, -1`` (``conf`` is 1: these are not scored
  detections).

``frame`` is the 1-based position in the input, the number of the frame's mask
(``binNNNNNN.png``). Lines go to a hidden partial file as they come and it takes the final name
when the run ends, also after Ctrl-C: each line is whole, so the file stays valid.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, List, Mapping, Optional

import cv2
import numpy as np

from bgsub.errors import OutputError
from bgsub.io.loop import Consumer, FrameResult
from bgsub.io.line_sink import LineSink
from bgsub.io.outputs import check_file_output
from bgsub.io.writers import VisWriter
from bgsub.objects.tracker import ObjectTracker, TrackedObject, TrackerConfig

_LAYOUTS = (".jsonl", ".csv")


def check_objects_output(path: Any, *, overwrite: bool = False) -> Path:
    """Check that an objects file (``.jsonl`` or ``.csv``) can be written at ``path``;
    nothing is written. :class:`OutputError` otherwise."""
    output = check_file_output(path, overwrite=overwrite)
    if output.suffix.lower() not in _LAYOUTS:
        raise OutputError(f"{output}: an objects file is .jsonl (JSON lines) or .csv "
                          "(MOTChallenge); give a name ending in one of them")
    return output


def json_line(frame: int, objects: List[TrackedObject]) -> str:
    """The ``.jsonl`` line of frame number ``frame`` (1-based)."""
    items = [{"id": o.id, "box": list(o.box), "area": o.area,
              "centroid": [round(o.centroid[0], 2), round(o.centroid[1], 2)]} for o in objects]
    return json.dumps({"frame": frame, "objects": items}, separators=(", ", ": ")) + "\n"


def mot_lines(frame: int, objects: List[TrackedObject]) -> str:
    """The MOTChallenge ``.csv`` lines of frame number ``frame`` (1-based)."""
    return "".join(f"{frame},{o.id},{o.box[0]},{o.box[1]},{o.box[2]},{o.box[3]},1,-1,-1,-1\n"
                   for o in objects)


class ObjectSink(LineSink):
    """A ``.jsonl`` or MOTChallenge ``.csv`` file of each frame's objects (see the module)."""

    def __init__(self, path: Any, *, overwrite: bool = False) -> None:
        checked = check_objects_output(path, overwrite=overwrite)
        self._format = json_line if checked.suffix.lower() == ".jsonl" else mot_lines
        super().__init__(checked, what="the objects", overwrite=overwrite)

    def write(self, frame: int, objects: List[TrackedObject]) -> None:
        """Add frame number ``frame`` (1-based) and its objects."""
        self.write_record(self._format(frame, objects))


class ObjectWriter(Consumer):
    """Tracks the objects of one engine's masks and writes them to an :class:`ObjectSink`
    (``sink=None``: tracks only, e.g. for :class:`ObjectVisWriter`). :attr:`objects` holds the
    current frame's objects once :meth:`prepare` has run."""

    def __init__(self, sink: Optional[ObjectSink], *, engine: Optional[str] = None,
                 config: TrackerConfig = TrackerConfig()) -> None:
        self.sink = sink
        self.engine = engine
        self.tracker = ObjectTracker(config)
        self.objects: List[TrackedObject] = []

    def start(self, engines: Mapping[str, Any]) -> None:
        if self.engine is None:
            if len(engines) != 1:
                raise ValueError(f"ObjectWriter: name the engine of the {len(engines)} engines")
            self.engine = next(iter(engines))
        elif self.engine not in engines:
            raise ValueError(f"ObjectWriter: no engine named {self.engine!r}")

    def prepare(self, result: FrameResult) -> None:
        self.objects = self.tracker.update(result.masks[self.engine])

    def add(self, result: FrameResult) -> None:
        if self.sink is not None:
            self.sink.write(result.index + 1, self.objects)

    def close(self, *, complete: bool, error: Optional[BaseException]) -> None:
        if self.sink is not None:
            self.sink.finish(complete=complete, error=error)


def draw_objects(frame: np.ndarray, objects: List[TrackedObject]) -> np.ndarray:
    """A copy of ``frame`` ((H, W, 3) uint8 BGR, or (H, W) gray) with each object's box and id."""
    picture = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()
    for obj in objects:
        hue = (obj.id * 47) % 180  # a steady colour per id
        colour = cv2.cvtColor(np.uint8([[[hue, 255, 255]]]), cv2.COLOR_HSV2BGR)[0, 0].tolist()
        x, y, w, h = obj.box
        cv2.rectangle(picture, (x, y), (x + w - 1, y + h - 1), colour, 1)
        cv2.putText(picture, str(obj.id), (x, max(y - 2, 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.35,
                    colour, 1, cv2.LINE_AA)
    return picture


class ObjectVisWriter(VisWriter):
    """A :class:`VisWriter` whose frames show the boxes and ids of ``objects``' current
    objects; ``objects`` must come before it in the loop's consumers (it tracks in prepare)."""

    def __init__(self, sink: Any, *, objects: ObjectWriter, engine: Optional[str] = None) -> None:
        super().__init__(sink, engine=engine)
        self._objects = objects
        self._picture: Optional[np.ndarray] = None

    def prepare(self, result: FrameResult) -> None:
        self._picture = draw_objects(result.frame, self._objects.objects)

    def add(self, result: FrameResult) -> None:
        self.sink.write(self._picture, result.masks[self.engine])
