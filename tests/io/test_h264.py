"""Picture videos in H.264 (PyAV, the ``h264`` extra) or MPEG-4 part 2 (``--codec mp4v``)."""

from __future__ import annotations

import json
import re
import resource
import shutil
import signal
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.errors import OutputError, ProcessingError
from bgsub.io.h264 import h264_available, picture_codec
from bgsub.io.sinks import VideoSink
from helpers import read_frames, write_box_clip

needs_h264 = pytest.mark.skipif(not h264_available(),
                                reason="PyAV with libx264 not installed (the h264 extra)")
without_h264 = pytest.mark.skipif(h264_available(), reason="PyAV with libx264 is installed")


def fourcc(path: Path) -> str:
    """The codec OpenCV reads in the video at ``path`` (``"h264"``, ``"mp4v"``, ...)."""
    capture = cv2.VideoCapture(str(path))
    code = int(capture.get(cv2.CAP_PROP_FOURCC))
    capture.release()
    return code.to_bytes(4, "little").decode("ascii", "replace").lower()


def is_h264(path: Path) -> bool:
    """An H.264 MP4: its sample description names ``avc1`` and OpenCV reads it as h264."""
    return b"avc1" in path.read_bytes() and fourcc(path) in ("h264", "avc1")


def is_mp4v(path: Path) -> bool:
    """An MPEG-4 part 2 MP4: its sample description names ``mp4v`` (OpenCV's FFmpeg reads the
    codec as ``fmp4``)."""
    return b"mp4v" in path.read_bytes() and fourcc(path) in ("mp4v", "fmp4")


def _pictures(n: int = 10, w: int = 66, h: int = 50) -> list:
    out = []
    for k in range(n):
        picture = np.full((h, w, 3), 40, np.uint8)
        picture[10:30, 3 * k:3 * k + 20] = (0, 0, 230)
        out.append(picture)
    return out


@needs_h264
def test_mp4_is_h264_by_default_with_pyav_and_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "p.mp4"
    pictures = _pictures(w=65, h=49)  # odd sizes are padded, as for OpenCV's writer
    with VideoSink(path, fps=25) as sink:
        for picture in pictures:
            sink.write(picture)
    assert sink.codec == "h264" and is_h264(path)
    back = read_frames(path)
    assert len(back) == len(pictures)
    assert np.abs(back[5][:49, :65].astype(int) - pictures[5]).mean() < 6  # lossy, close


@needs_h264
def test_mp4_has_its_index_first_so_a_browser_starts_at_once(tmp_path: Path) -> None:
    path = tmp_path / "p.mp4"
    with VideoSink(path, fps=25) as sink:
        for picture in _pictures():
            sink.write(picture)
    data = path.read_bytes()
    assert 0 <= data.find(b"moov") < data.find(b"mdat")


def test_codec_mp4v_forces_mpeg4_part2(tmp_path: Path) -> None:
    path = tmp_path / "p.mp4"
    with VideoSink(path, fps=25, codec="mp4v") as sink:
        for picture in _pictures():
            sink.write(picture)
    assert sink.codec == "mp4v" and is_mp4v(path)
    assert len(read_frames(path)) == 10


@without_h264
def test_without_pyav_auto_falls_back_to_mp4v_and_h264_is_refused(tmp_path: Path) -> None:
    assert picture_codec(".mp4") == "mp4v"
    with pytest.raises(OutputError, match=r"pip install 'bgsub\[h264\]'"):
        VideoSink(tmp_path / "p.mp4", fps=25, codec="h264")
    assert not (tmp_path / "p.mp4").exists()


def test_other_suffixes_keep_their_codec_and_bad_choices_are_refused(tmp_path: Path) -> None:
    assert picture_codec(".mkv", "mp4v") is None and picture_codec(".avi") is None
    with VideoSink(tmp_path / "p.mkv", fps=25) as sink:
        sink.write(_pictures(1)[0])
    assert sink.codec == "FFV1"
    with pytest.raises(OutputError, match="must be one of auto, h264, mp4v"):
        VideoSink(tmp_path / "q.mp4", fps=25, codec="vp9")


@needs_h264
def test_a_failing_h264_write_stops_with_one_error(tmp_path: Path) -> None:
    # A file size limit makes the writes fail, as a full disk does.
    rng = np.random.default_rng(4)
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, limit[1]))
        with pytest.raises(ProcessingError) as caught:
            with VideoSink(tmp_path / "p.mp4", fps=10) as sink:
                for _ in range(80):  # noise: tens of kB a frame even in H.264
                    sink.write(rng.integers(0, 256, (96, 128, 3), dtype=np.uint8))
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, limit)
        signal.signal(signal.SIGXFSZ, handler)
    message = str(caught.value)
    assert "p.mp4" in message and ("removed" in message or "holds only" in message), message


# --------------------------------------------------------------------------------------------
# Through the commands
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("codec", ["auto", "mp4v"])
def test_run_json_says_which_codec_the_overlay_has(tmp_path: Path, capsys, codec: str) -> None:
    clip = write_box_clip(tmp_path / "clip.mkv")
    vis = tmp_path / "vis.mp4"
    assert main(["run", str(clip), "-m", "framediff", "-o", str(tmp_path / "m.mkv"),
                 "--vis", str(vis), "--codec", codec, "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    expected = "h264" if codec == "auto" and h264_available() else "mp4v"
    assert summary["video_codecs"] == {"vis": expected}
    assert is_h264(vis) if expected == "h264" else is_mp4v(vis)
    assert f"{vis}: " in captured.err  # the note naming the codec


def test_compare_side_by_side_codec_is_in_the_report(tmp_path: Path) -> None:
    clip = write_box_clip(tmp_path / "clip.mkv")
    out = tmp_path / "out"
    assert main(["compare", str(clip), "-m", "framediff", "-o", str(out), "-q",
                 "--mask-format", "none", "--codec", "mp4v"]) == 0
    assert json.loads((out / "report.json").read_text())["settings"]["video_codec"] == "mp4v"
    assert is_mp4v(out / "side_by_side.mp4")


@needs_h264
def test_compare_side_by_side_is_h264_with_pyav(tmp_path: Path) -> None:
    clip = write_box_clip(tmp_path / "clip.mkv")
    out = tmp_path / "out"
    assert main(["compare", str(clip), "-m", "framediff", "-o", str(out), "-q",
                 "--mask-format", "none", "--no-report"]) == 0
    assert is_h264(out / "side_by_side.mp4")


def test_flow_pair_refuses_a_codec_choice(tmp_path: Path, bgsub_error) -> None:
    for name in ("a.png", "b.png"):
        cv2.imwrite(str(tmp_path / name), np.zeros((48, 64), np.uint8))
    err = bgsub_error(["flow", tmp_path / "a.png", tmp_path / "b.png", "-o",
                       tmp_path / "f.flo", "--codec", "mp4v"])
    assert "--codec" in err and "video" in err


_PLAYER = """<html><body><div id="out">pending</div>
<video id="h264" src="h264.mp4" muted></video><video id="mp4v" src="mp4v.mp4" muted></video>
<script>
const seen = {};
for (const id of ["h264", "mp4v"]) {
  const v = document.getElementById(id);
  v.addEventListener("loadeddata", () => { seen[id] = "played " + v.videoWidth; show(); });
  v.addEventListener("error", () => { seen[id] = "refused"; show(); });
}
function show() { document.getElementById("out").textContent = JSON.stringify(seen); }
</script></body></html>"""


@needs_h264
@pytest.mark.skipif(shutil.which("chromium") is None, reason="no chromium on PATH")
def test_chromium_plays_the_h264_video_and_not_the_mp4v_one(tmp_path: Path) -> None:
    for codec in ("h264", "mp4v"):
        with VideoSink(tmp_path / f"{codec}.mp4", fps=25, codec=codec) as sink:
            for picture in _pictures(w=64, h=48):
                sink.write(picture)
    (tmp_path / "player.html").write_text(_PLAYER)
    done = subprocess.run(
        ["chromium", "--headless", "--no-sandbox", "--disable-gpu",
         "--allow-file-access-from-files", "--virtual-time-budget=5000", "--dump-dom",
         (tmp_path / "player.html").as_uri()],
        check=True, timeout=120, capture_output=True, text=True)
    shown = re.search(r'<div id="out">([^<]*)</div>', done.stdout)
    assert shown is not None, done.stdout
    assert json.loads(shown.group(1).replace("&quot;", '"')) == {"h264": "played 64",
                                                                  "mp4v": "refused"}
