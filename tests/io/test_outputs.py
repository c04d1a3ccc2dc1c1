"""Two writers of one output: the second is refused before it writes, the first finishes."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.errors import OutputError
from bgsub.io.mask_sinks import MaskVideoSink
from bgsub.io.sinks import MotionSink, VideoSink, open_mask_sink

from helpers import read_frames
from test_sinks import H, W, _masks

_BUSY = "another run is writing it now; wait for it to end or choose another name"


@pytest.mark.parametrize("name", ["m.mkv", "masks"])
def test_a_second_writer_of_the_same_masks_is_refused_and_the_first_finishes(tmp_path, name):
    path = tmp_path / name
    with open_mask_sink(path, width=W, height=H, fps=10) as first:
        first.write(_masks(1)[0], 0)
        with pytest.raises(OutputError, match=f"^{path}: {_BUSY}$"):
            open_mask_sink(path, width=W, height=H, fps=10, overwrite=True)
        first.write(_masks(1)[0], 1)
    held = len(read_frames(path)) if name.endswith(".mkv") else len(list(path.iterdir()))
    assert held == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


@pytest.mark.parametrize("make", [
    lambda path: VideoSink(path.with_suffix(".mp4"), fps=10, overwrite=True),
    lambda path: MotionSink(path.with_suffix(".npy"), overwrite=True),
])
def test_a_second_writer_of_a_picture_or_motion_file_is_refused(tmp_path, make):
    with make(tmp_path / "out"):
        with pytest.raises(OutputError, match=_BUSY):
            make(tmp_path / "out")


def test_the_output_is_free_again_once_the_first_writer_is_closed(tmp_path):
    path = tmp_path / "m.mkv"
    with open_mask_sink(path, width=W, height=H, fps=10) as first:
        first.write(_masks(1)[0])
    with open_mask_sink(path, width=W, height=H, fps=10, overwrite=True) as second:
        second.write(_masks(1)[0])
        second.write(_masks(1)[0])
    assert len(read_frames(path)) == 2


def test_an_output_another_run_finished_meanwhile_is_not_replaced(tmp_path):
    # The output did not exist when it was checked, and exists once its name is claimed.
    path = tmp_path / "m.mkv"
    with open_mask_sink(path, width=W, height=H, fps=10) as first:
        first.write(_masks(1)[0])
    with pytest.raises(OutputError, match="another run finished it meanwhile"):
        MaskVideoSink(path, width=W, height=H, fps=10)
    assert len(read_frames(path)) == 1


def test_a_temporary_file_a_killed_run_left_is_taken_over(tmp_path):
    stale = tmp_path / ".m.partial.mkv"
    stale.write_bytes(b"left by a run killed with SIGKILL")
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as sink:
        sink.write(_masks(1)[0])
    assert len(read_frames(tmp_path / "m.mkv")) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.mkv"]


def test_a_video_that_got_no_picture_leaves_no_file(tmp_path):
    with VideoSink(tmp_path / "f.mp4", fps=10):
        pass
    assert list(tmp_path.iterdir()) == []


def test_a_motion_file_refused_by_a_second_writer_keeps_the_firsts_rows(tmp_path):
    path = tmp_path / "cam.npy"
    with MotionSink(path) as first:
        first.write(np.eye(3))
        with pytest.raises(OutputError, match=_BUSY):
            MotionSink(path, overwrite=True)
        first.write(np.eye(3))
    assert np.load(path, allow_pickle=False).shape == (2, 3, 3)
