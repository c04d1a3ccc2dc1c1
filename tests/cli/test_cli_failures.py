"""Failures that say their likely cause and the fix: an .mp4 over HTTP from a server without
byte ranges, and a single image given as the input."""

from __future__ import annotations

import contextlib
import functools
import http.server

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from helpers import http_server, serve_folder, write_gt_sequence


def _index_at_end_mp4(path):
    """An .mp4 as OpenCV writes it (the index after the frames, no faststart), large enough
    that a reader must seek to the index rather than find it in its first read."""
    rng = np.random.default_rng(0)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (320, 240))
    for _ in range(40):
        writer.write(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    writer.release()
    data = path.read_bytes()
    assert data.find(b"moov") > len(data) // 2
    return path


@contextlib.contextmanager
def _plain_http_server(folder):
    """``python3 -m http.server``'s handler (no byte ranges) on 127.0.0.1, in a thread."""
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    with http_server(functools.partial(Quiet, directory=str(folder))) as url:
        yield url


def test_an_mp4_over_http_without_byte_ranges_names_cause_and_fix(tmp_path, bgsub_error):
    _index_at_end_mp4(tmp_path / "clip.mp4")
    with _plain_http_server(tmp_path) as url:
        err = bgsub_error(["run", url + "clip.mp4", "-o", str(tmp_path / "m.mkv"), "-m",
                           "mog2", "--stall-timeout", "3"])
    assert "gave no frame" in err and "ignores byte ranges" in err
    assert "-movflags +faststart" in err
    assert not (tmp_path / "m.mkv").exists()


def test_the_same_mp4_from_a_server_with_byte_ranges_is_read(tmp_path, capsys):
    _index_at_end_mp4(tmp_path / "clip.mp4")
    with serve_folder(tmp_path) as url:
        code = main(["run", url + "clip.mp4", "-o", str(tmp_path / "m.mkv"), "-m", "mog2",
                     "--stall-timeout", "3", "-q"])
    assert code == 0, capsys.readouterr().err


@pytest.fixture
def image(tmp_path):
    path = tmp_path / "frames" / "in000001.png"
    path.parent.mkdir()
    cv2.imwrite(str(path), np.zeros((48, 64, 3), np.uint8))
    return path


@pytest.mark.parametrize("command", [
    ["run", "IMAGE", "-o", "OUT/m.mkv"],
    ["compare", "IMAGE", "-o", "OUT/report", "-m", "mog2"],
    ["eval", "IMAGE", "GT"],
])
def test_a_single_image_input_is_refused_with_a_folder_or_glob(tmp_path, image, bgsub_error,
                                                               command):
    write_gt_sequence(tmp_path / "gt", {1: np.zeros((48, 64), np.uint8)})
    argv = [a.replace("IMAGE", str(image)).replace("OUT", str(tmp_path))
            .replace("GT", str(tmp_path / "gt")) for a in command]
    err = bgsub_error(argv)
    assert "is one image, not a video" in err
    assert f"({image.parent}/)" in err and f"'{image.parent}/*.png'" in err
