"""Live and network sources: a URL served from 127.0.0.1 in the test, a camera index with no
camera, a character device that is no camera, and what a stall or a drop reports."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from helpers import serve_folder, write_box_clip, write_mp4_clip

from bgsub.cli import main
from bgsub.errors import InputError
from bgsub.io.sources import open_source
from bgsub.io.streams import is_live, stream_kind, stream_name


@pytest.fixture
def clip_url(tmp_path):
    write_mp4_clip(tmp_path / "clip.mp4", n=20)
    with serve_folder(tmp_path) as base:
        url = base + "clip.mp4"
        probe = cv2.VideoCapture(url, cv2.CAP_FFMPEG)
        readable = probe.isOpened() and probe.read()[0]
        probe.release()
        if not readable:
            pytest.skip("OpenCV's FFmpeg cannot read http:// here")
        yield url


def _frames_of(path):
    with open_source(str(path)) as source:
        return [frame for _, frame in source]


def test_stream_kind_names_cameras_urls_and_devices(tmp_path):
    assert stream_kind("0") == "camera"
    assert stream_kind("rtsp://cam.local/live") == "url"
    assert stream_kind("http://host/a/clip.mp4?key=[1]") == "url"
    assert stream_kind("/dev/null") == "device"
    assert stream_kind(str(tmp_path)) is None
    assert stream_name("http://host/a/clip.mp4?key=1") == "clip"
    assert stream_name("1") == "camera1"


def test_live_sources_are_cameras_devices_and_streaming_urls():
    assert is_live("0") and is_live("/dev/null") and is_live("rtsp://cam.local/live")
    assert not is_live("http://host/clip.mp4") and not is_live("https://host/clip.mp4")


def test_url_is_read_once_as_a_stream_of_unknown_length(clip_url, tmp_path):
    expected = _frames_of(tmp_path / "clip.mp4")
    with open_source(clip_url) as source:
        assert source.info.kind == "stream" and source.info.frame_count is None
        frames = [frame for _, frame in source]
        assert source.truncation() is None  # it ended where it said it would
        with pytest.raises(InputError, match="read once"):
            list(source)
    assert len(frames) == len(expected) == 20
    assert all(np.array_equal(a, b) for a, b in zip(frames, expected))


def test_url_frame_range_keeps_input_indices(clip_url):
    with open_source(clip_url, start=3, stop=11, step=2) as source:
        assert [index for index, _ in source] == [3, 5, 7, 9]


def test_run_reads_a_url_to_its_end(clip_url, tmp_path, capsys):
    out = tmp_path / "masks"
    assert main(["run", clip_url, "-o", str(out), "-m", "mog2", "--json"]) == 0
    assert len(list(out.glob("bin*.png"))) == 20
    assert '"frames": 20' in capsys.readouterr().out


def test_run_max_frames_stops_a_url(clip_url, tmp_path):
    out = tmp_path / "masks"
    assert main(["run", clip_url, "-o", str(out), "-m", "mog2", "--max-frames", "6", "-q"]) == 0
    assert sorted(p.name for p in out.glob("bin*.png"))[-1] == "bin000006.png"
    assert len(list(out.glob("bin*.png"))) == 6


def test_run_max_frames_with_start_and_step(tmp_path):
    clip = write_box_clip(tmp_path / "box.mkv", n=12)
    out = tmp_path / "masks"
    assert main(["run", str(clip), "-o", str(out), "-m", "mog2", "--start", "2", "--step", "3",
                 "--max-frames", "2", "-q"]) == 0
    assert sorted(p.name for p in out.glob("bin*.png")) == ["bin000003.png", "bin000006.png"]


def test_max_frames_below_one_is_refused(tmp_path, bgsub_error):
    clip = write_box_clip(tmp_path / "box.mkv")
    line = bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "--max-frames", "0"])
    assert "--max-frames" in line


def test_stalled_url_is_reported_in_one_line_and_outputs_stay_valid(tmp_path, capsys):
    write_box_clip(tmp_path / "box.mkv", n=40)
    out = tmp_path / "masks.mkv"
    with serve_folder(tmp_path, cut_at=0.5, hold=4.0) as base:
        code = main(["run", base + "box.mkv", "-o", str(out), "-m", "mog2",
                     "--stall-timeout", "1", "-q"])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("\n") == 1 and "stalled (no frame for 1 s)" in err
    masks = _frames_of(out)
    assert 5 <= len(masks) < 40


def test_dropped_url_is_reported_in_one_line(tmp_path, capsys):
    write_box_clip(tmp_path / "box.mkv", n=40)
    with serve_folder(tmp_path, cut_at=0.5) as base:
        code = main(["run", base + "box.mkv", "-o", str(tmp_path / "m.mkv"), "-m", "mog2",
                     "-q"])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("\n") == 1 and "box.mkv" in err and "after" in err
    assert "stalled" not in err


def test_missing_url_is_one_line(tmp_path, bgsub_error):
    with serve_folder(tmp_path) as base:
        line = bgsub_error(["run", base + "nothing.mp4", "-o", tmp_path / "m.mkv"])
    assert "cannot open it" in line and "nothing.mp4" in line


def test_camera_index_without_camera_is_one_line(tmp_path, bgsub_error):
    line = bgsub_error(["run", "7", "-o", tmp_path / "m.mkv"])
    assert "camera 7: cannot open it" in line


def test_character_device_that_is_no_camera_is_one_line(tmp_path, bgsub_error):
    line = bgsub_error(["run", "/dev/null", "-o", tmp_path / "m.mkv"])
    assert "/dev/null: cannot open it" in line


def test_stall_timeout_must_be_positive(clip_url):
    with pytest.raises(InputError, match="stall timeout"):
        open_source(clip_url, stall_seconds=0)


def test_batch_takes_each_url_as_one_input(tmp_path):
    from bgsub.batch.inputs import expand

    items = expand(["http://host/v/clip.mp4?take=[1]", "rtsp://cam.local/live", "0"])
    assert [(i.path, i.name) for i in items] == [
        ("http://host/v/clip.mp4?take=[1]", "clip"), ("rtsp://cam.local/live", "live"),
        ("0", "camera0")]


def test_batch_of_urls_writes_one_output_each(tmp_path):
    for name in ("a", "b"):
        write_mp4_clip(tmp_path / f"{name}.mp4", n=8)
    out = tmp_path / "out"
    with serve_folder(tmp_path) as base:
        code = main(["run", base + "a.mp4", base + "b.mp4?x=1", "-o", str(out), "-m", "mog2",
                     "--jobs", "1", "-q"])
    assert code == 0
    assert len(_frames_of(out / "a.mkv")) == len(_frames_of(out / "b.mkv")) == 8


def test_batch_passes_the_stall_timeout_to_each_url(tmp_path, capsys):
    good, bad = tmp_path / "good", tmp_path / "bad"
    good.mkdir()
    bad.mkdir()
    write_mp4_clip(good / "a.mp4", n=8)
    write_box_clip(bad / "b.mkv", n=40)
    with serve_folder(good) as one, serve_folder(bad, cut_at=0.5, hold=4.0) as two:
        code = main(["run", one + "a.mp4", two + "b.mkv", "-o", str(tmp_path / "out"), "-m",
                     "mog2", "--jobs", "1", "--stall-timeout", "1", "-q"])
    assert code == 0
    assert "stalled (no frame for 1 s)" in capsys.readouterr().err
    assert (tmp_path / "out" / "a.mkv").is_file() and (tmp_path / "out" / "b.mkv").is_file()


def test_ctrl_c_during_a_stall_leaves_valid_partial_outputs(tmp_path, capsys):
    import os
    import signal
    import threading

    write_box_clip(tmp_path / "long.mkv", n=300)  # (past FFmpeg's probe before the cut)
    out = tmp_path / "masks.mkv"
    with serve_folder(tmp_path, cut_at=0.6, hold=10.0) as base:
        timer = threading.Timer(3.0, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        try:
            code = main(["run", base + "long.mkv", "-o", str(out), "-m", "mog2",
                         "--stall-timeout", "5", "-q"])
        finally:
            timer.cancel()
    assert code == 130
    assert "partial (interrupted) but valid" in capsys.readouterr().err
    assert 100 < len(_frames_of(out)) < 300
