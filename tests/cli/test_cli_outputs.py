"""Every output a single run writes, written the same by a batch and by the Python API."""

from __future__ import annotations

import contextlib
import csv
import json

import cv2
import numpy as np
import pytest

from bgsub import create_engine
from bgsub.cli import main
from bgsub.io.pipeline import OutputRequest, process
from bgsub.io.sources import open_source
from helpers import batch_results, write_box_clip, write_pan_clip

W, H, N = 64, 48, 10
_KINDS = ("--objects", "--motion", "--stats")


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _masks(path):
    with open_source(path) as source:
        return [frame[:, :, 0].copy() for _, frame in source]


def _same_files(a: dict, b: dict) -> None:
    """The outputs of two runs hold the same frames, objects, motion and statistics (all but
    the time each frame took)."""
    assert all(np.array_equal(x, y) for x, y in zip(_masks(a["masks"]), _masks(b["masks"])))
    assert len(_masks(a["masks"])) == N
    assert open(a["objects"]).read() == open(b["objects"]).read()
    np.testing.assert_array_equal(np.load(a["motion"]), np.load(b["motion"]))
    rows_a, rows_b = _rows(a["stats"]), _rows(b["stats"])
    assert len(rows_a) == N
    assert [{**r, "ms": ""} for r in rows_a] == [{**r, "ms": ""} for r in rows_b]


def test_single_run_batch_and_api_write_the_same_files(tmp_path, capsys):
    clips = tmp_path / "clips"
    clips.mkdir()
    clip = write_box_clip(clips / "v0.mkv", n=N, width=W, height=H)
    write_box_clip(clips / "v1.mkv", seed=1, n=N, width=W, height=H)
    common = ["--method", "compensated", "-p", "overlap=0"]
    single = {"masks": tmp_path / "one.mkv", "objects": tmp_path / "one.jsonl",
              "motion": tmp_path / "one.npy", "stats": tmp_path / "one.csv"}
    assert main(["run", str(clip), "-o", str(single["masks"]), *common,
                 *[f"{flag}={single[flag[2:]]}" for flag in _KINDS]]) == 0
    out = tmp_path / "batch"
    assert main(["run", str(clips), "-o", str(out / "masks"), *common, "--jobs", "1",
                 *[f"{flag}={out / flag[2:]}" for flag in _KINDS]]) == 0
    batch = {"masks": out / "masks" / "v0.mkv", "objects": out / "objects" / "v0.jsonl",
             "motion": out / "motion" / "v0.npy", "stats": out / "stats" / "v0.csv"}
    api = {kind: str(tmp_path / f"api{path.suffix}") for kind, path in single.items()}
    with contextlib.ExitStack() as stack:
        source = stack.enter_context(open_source(clip))
        sinks = OutputRequest(**api).open(stack, width=W, height=H, fps=source.info.fps)
        engine = create_engine("compensated", overlap=0)
        process(source, engine, **sinks)
    _same_files(single, batch)
    _same_files(single, api)


def test_a_batch_takes_objects_stats_codec_and_json(tmp_path, capsys):
    clips = tmp_path / "clips"
    clips.mkdir()
    for k in range(2):
        write_box_clip(clips / f"v{k}.mkv", seed=k, n=N, width=W, height=H)
    out = tmp_path / "out"
    code = main(["run", str(clips), "-o", str(out), "--method", "mog2", "--jobs", "1",
                 "--objects", str(tmp_path / "objects"), "--stats", str(tmp_path / "stats"),
                 "--vis", str(tmp_path / "vis"), "--codec", "mp4v", "--json",
                 "--min-object-area", "5"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads(captured.out)
    assert [(r["name"], r["status"], r["frames"]) for r in summary["results"]] == \
        [("v0", "done", N), ("v1", "done", N)]
    assert summary["results"][1]["outputs"]["objects"] == str(tmp_path / "objects" / "v1.jsonl")
    for k in range(2):
        assert len((tmp_path / "objects" / f"v{k}.jsonl").read_text().splitlines()) == N
        assert len(_rows(tmp_path / "stats" / f"v{k}.csv")) == N
        video = cv2.VideoCapture(str(tmp_path / "vis" / f"v{k}.mp4"))
        fourcc = int(video.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode()
        video.release()
        assert fourcc in ("mp4v", "FMP4")  # (FFmpeg's name of MPEG-4 part 2)


def test_a_batch_passes_codec_to_every_input(tmp_path, capsys, monkeypatch):
    import bgsub.io.h264

    monkeypatch.setattr(bgsub.io.h264, "h264_available", lambda: False)
    clips = tmp_path / "clips"
    clips.mkdir()
    for k in range(2):
        write_box_clip(clips / f"v{k}.mkv", seed=k, n=3, width=W, height=H)
    code = main(["run", str(clips), "-o", str(tmp_path / "out"), "--method", "mog2",
                 "--jobs", "1", "--vis", str(tmp_path / "vis"), "--codec", "h264"])
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("H.264 videos need PyAV") == 2


def test_run_stats_gives_a_row_per_mask_with_the_cameras_motion(tmp_path, capsys):
    clip = write_pan_clip(tmp_path / "pan.avi", n=8, width=160, height=120)
    code = main(["run", str(clip), "-o", str(tmp_path / "m"), "--start", "2",
                 "--stats", str(tmp_path / "s.csv"), "--method", "compensated"])
    assert code == 0, capsys.readouterr().err
    rows = _rows(tmp_path / "s.csv")
    assert [row["frame"] for row in rows] == ["3", "4", "5", "6", "7", "8"]  # bin000003.png...
    assert rows[0]["model"] == rows[0]["dx"] == ""  # the first frame: nothing to compare with
    assert all(row["status"] == "ok" and row["model"] == "compensated" for row in rows[1:])
    assert all(1.5 < float(row["dx"]) < 6 for row in rows[1:])  # 2-5 px a frame, rightwards
    assert all(0 < float(row["inlier_share"]) <= 1 for row in rows[1:])


def test_a_stats_file_that_exists_is_refused_before_any_frame(tmp_path, bgsub_error):
    clip = write_box_clip(tmp_path / "c.mkv", n=3, width=W, height=H)
    (tmp_path / "s.csv").write_text("mine\n")
    err = bgsub_error(["run", str(clip), "-o", str(tmp_path / "m"), "--stats",
                       str(tmp_path / "s.csv")])
    assert "s.csv: already exists" in err
    assert not (tmp_path / "m").exists() and (tmp_path / "s.csv").read_text() == "mine\n"


def test_a_batch_rerun_with_another_object_size_is_a_skip_naming_it(tmp_path, capsys):
    clips = tmp_path / "clips"
    clips.mkdir()
    for k in range(2):
        write_box_clip(clips / f"v{k}.mkv", seed=k, n=3, width=W, height=H)
    argv = ["run", str(clips), "-o", str(tmp_path / "out"), "--method", "mog2", "--jobs", "1",
            "--objects", str(tmp_path / "objects")]
    assert batch_results(capsys, argv + ["--min-object-area", "5"]) == [("done", "")] * 2
    assert batch_results(capsys, argv + ["--min-object-area", "5"]) == [("skipped", "")] * 2
    reason = ("made with other settings (min_object_area 5 -> 9): --overwrite redoes it")
    assert batch_results(capsys, argv + ["--min-object-area", "9"]) == [("skipped", reason)] * 2
    assert (batch_results(capsys, argv + ["--min-object-area", "9", "--overwrite"])
            == [("done", "")] * 2)


@pytest.mark.parametrize("extra, message", [
    (["--min-object-area", "0"], "--min-object-area"),
    (["--min-object-area", "5"], "--min-object-area needs --objects"),
    (["--stats", "STATS/s.csv"], "--stats of several inputs is a folder"),
])
def test_batch_output_options_are_checked_before_any_input(tmp_path, bgsub_error, extra,
                                                           message):
    clips = tmp_path / "clips"
    clips.mkdir()
    for k in range(2):
        write_box_clip(clips / f"v{k}.mkv", seed=k, n=3, width=W, height=H)
    objects = [] if "needs" in message else ["--objects", str(tmp_path / "objects")]
    extra = [a.replace("STATS", str(tmp_path / "stats")) for a in extra]
    err = bgsub_error(["run", str(clips), "-o", str(tmp_path / "out"), "-m", "mog2", *objects,
                       *extra])
    assert message in err
    assert not (tmp_path / "out").exists()
