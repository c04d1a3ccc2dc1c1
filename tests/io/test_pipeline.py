"""The output pipeline (`bgsub.io.pipeline`) and the per-frame statistics file."""

from __future__ import annotations

import contextlib
import csv
import json

import numpy as np
import pytest

from bgsub import create_engine
from bgsub.errors import OutputError
from bgsub.io.frame_stats import COLUMNS, StatsSink
from bgsub.io.pipeline import OutputRequest, open_outputs, process
from bgsub.io.sinks import open_mask_sink
from bgsub.objects import ObjectSink
from bgsub.samples import SceneSpec, render_frames


def _frames(n=8, h=48, w=64, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        frame = rng.integers(0, 40, (h, w, 3), dtype=np.uint8)
        frame[15:30, 3 * k:3 * k + 12] = 230
        yield k, frame


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_process_writes_objects_and_a_stats_row_per_frame(tmp_path):
    engine = create_engine("mog2")
    with open_mask_sink(tmp_path / "m", width=64, height=48, fps=25) as masks, \
            ObjectSink(tmp_path / "o.jsonl") as objects, StatsSink(tmp_path / "s.csv") as stats:
        process(_frames(), engine, masks, objects=objects, stats=stats)
    rows = _rows(tmp_path / "s.csv")
    assert list(rows[0]) == list(COLUMNS)
    assert [row["frame"] for row in rows] == [str(k) for k in range(1, 9)]
    assert all(row["dx"] == "" and row["model"] == "" for row in rows)  # mog2: no camera
    assert float(rows[-1]["foreground"]) > 0 and all(float(r["ms"]) >= 0 for r in rows)
    lines = (tmp_path / "o.jsonl").read_text().splitlines()
    assert [json.loads(line)["frame"] for line in lines] == list(range(1, 9))


def test_the_foreground_column_is_the_masks_share(tmp_path):
    engine = create_engine("framediff")
    seen = []
    with open_mask_sink(tmp_path / "m", width=64, height=48, fps=25) as masks, \
            StatsSink(tmp_path / "s.csv") as stats:
        process(_frames(), engine, masks, stats=stats,
                on_frame=lambda index, mask: seen.append(np.count_nonzero(mask) / mask.size))
    assert [float(row["foreground"]) for row in _rows(tmp_path / "s.csv")] == \
        pytest.approx(seen, abs=1e-4)
    assert any(seen)


def test_a_moving_camera_engine_reports_the_pan_it_saw():
    spec = SceneSpec("pan", seed=0, width=160, height=120, n_frames=8)
    engine = create_engine("compensated")
    found, truth = [], []
    for frame in render_frames(spec):
        engine.apply(frame.image)
        stats = engine.frame_stats()
        centre = np.array([79.5, 59.5, 1.0])
        moved = frame.motion @ centre
        truth.append(moved[0] / moved[2] - centre[0])
        found.append(stats["dx"])
        assert stats["status"] == "ok"
    assert truth[1] > 1.0  # the scene pans to the right by px per frame
    assert found[1:] == pytest.approx(truth[1:], abs=0.25)
    assert stats["model"] == "compensated" and 0 < stats["inliers"] <= stats["vectors"]
    assert stats["scale"] == pytest.approx(1.0, abs=0.01)


def test_a_stats_file_must_be_csv(tmp_path):
    with pytest.raises(OutputError, match=r"a statistics file is a \.csv table"):
        OutputRequest(masks=str(tmp_path / "m"), stats=str(tmp_path / "s.txt")).check()


def test_open_outputs_gives_the_writers_in_the_order_outputs_need(tmp_path):
    request = OutputRequest(masks=str(tmp_path / "m"), vis=str(tmp_path / "v.avi"),
                            objects=str(tmp_path / "o.csv"), stats=str(tmp_path / "s.csv"))
    with contextlib.ExitStack() as stack:
        writers, codecs = open_outputs(stack, request, width=64, height=48, fps=25)
        names = [type(writer).__name__ for writer in writers]
        assert names == ["MaskWriter", "ObjectWriter", "ObjectVisWriter", "StatsWriter"]
        assert codecs == {"vis": "MJPG"}
