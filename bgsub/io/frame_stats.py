"""Per-frame statistics of a run as a CSV file (``bgsub run --stats``), for tuning.

One header line, then one row per frame:

=============== ===============================================================================
column          meaning
=============== ===============================================================================
``frame``       1-based position in the input: the number of the frame's mask
``status``      the engine's ``last_status`` (``ok``, ``fallback: ...``, ``scene cut``)
``dx``, ``dy``  where the camera motion moved the frame's centre, input pixels
``rotation``    the camera motion's rotation, degrees
``scale``       the camera motion's scale (1 = no zoom)
``inliers``     motion vectors that agree with the camera fit
``vectors``     motion vectors measured
``inlier_share`` ``inliers / vectors``
``foreground``  share of the mask's pixels that are foreground, 0 to 1
``gain``        what the frame was divided by to match the model's exposure
``model``       the background model that decided: ``still`` or ``compensated``
``parallax``    the share of the motion vectors' weight a parallax field explained (a camera
                translating through a 3-D scene; 0: the homography alone)
``ms``          the engine's time on the frame (``apply``), milliseconds
=============== ===============================================================================

A cell is empty where the engine has no such quantity (an engine without camera motion, or a
frame where none was measured: the first, a blank frame, a scene cut). The moving-camera
engines report theirs through ``frame_stats()``; any other engine gives ``status`` when it has a
``last_status``, and every engine ``foreground`` and ``ms``.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any, Dict, Optional

import numpy as np

from bgsub.errors import OutputError
from bgsub.io.line_sink import LineSink
from bgsub.io.loop import FrameResult
from bgsub.io.outputs import PathLike, check_file_output
from bgsub.io.writers import SinkWriter

#: The columns of a statistics file, in order.
COLUMNS = ("frame", "status", "dx", "dy", "rotation", "scale", "inliers", "vectors",
           "inlier_share", "foreground", "gain", "model", "parallax", "ms")


def check_stats_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that a statistics file (``.csv``) can be written at ``path``; nothing is
    written. :class:`OutputError` otherwise."""
    output = check_file_output(path, overwrite=overwrite)
    if output.suffix.lower() != ".csv":
        raise OutputError(f"{output}: a statistics file is a .csv table; give a name ending "
                          "in .csv")
    return output


def _cell(value: Any) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return f"{value:.4f}" if isinstance(value, float) else str(value)


def stats_row(frame: int, engine: Any, mask: np.ndarray, seconds: Optional[float]) -> str:
    """The CSV line of frame number ``frame`` (1-based): what ``engine`` reports of it (see
    the module), its ``(H, W)`` ``mask`` and the ``seconds`` its ``apply`` took."""
    report = getattr(engine, "frame_stats", None)
    values: Dict[str, Any] = dict(report()) if callable(report) else {
        "status": getattr(engine, "last_status", None)}
    if values.get("inliers") is not None and values.get("vectors"):
        values["inlier_share"] = values["inliers"] / values["vectors"]
    values["frame"] = frame
    values["foreground"] = float(np.count_nonzero(mask)) / mask.size
    values["ms"] = None if seconds is None else seconds * 1000.0
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerow([_cell(values.get(c)) for c in COLUMNS])
    return out.getvalue()


class StatsSink(LineSink):
    """A ``.csv`` file of per-frame statistics (see the module): the header, then one row per
    :meth:`write`."""

    def __init__(self, path: PathLike, *, overwrite: bool = False) -> None:
        super().__init__(check_stats_output(path, overwrite=overwrite),
                         what="the statistics", header=",".join(COLUMNS) + "\n",
                         overwrite=overwrite)

    def write(self, row: str) -> None:
        """Add one frame's row (a line from :func:`stats_row`)."""
        self.write_record(row)


class StatsWriter(SinkWriter):
    """Writes one engine's per-frame statistics to a :class:`StatsSink` (``engine=None``: the
    loop's only engine)."""

    def add(self, result: FrameResult) -> None:
        self.sink.write(stats_row(result.index + 1, result.engines[self.engine],
                                  result.masks[self.engine], result.seconds.get(self.engine)))
