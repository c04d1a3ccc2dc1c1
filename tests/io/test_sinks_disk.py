"""Sinks on a disk that fills up: one clear error, no empty or unplayable output under its final
name, the frames so far kept valid, and no OpenCV warning per frame.

A full disk is simulated (writes that fail with ENOSPC, a video file that loses its end, a file
size limit), so these run anywhere without a small file system to fill.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import signal

import cv2
import numpy as np
import pytest

from bgsub.io import mask_sinks, motion_sink, videofile
from bgsub.errors import OutputError, ProcessingError
from bgsub.io.sinks import MotionSink, VideoSink, VisSink, open_mask_sink, process

from helpers import read_frames
from test_sinks import ClosedWriter, H, W, _masks

_REAL_WRITER = cv2.VideoWriter


class _Disk:
    """The files the mask and motion sinks open get ``free`` bytes in all, then ENOSPC, as on a full disk
    (writing over bytes already in a file takes no more space)."""

    def __init__(self, monkeypatch, free: int) -> None:
        self.free = free
        real_open = open

        def small_open(file, mode="r", *args, **kwargs):
            fh = real_open(file, mode, *args, **kwargs)
            return _Metered(fh, self) if "w" in mode else fh

        for module in (mask_sinks, motion_sink):
            monkeypatch.setattr(module, "open", small_open, raising=False)


class _Metered:
    def __init__(self, fh, disk: _Disk) -> None:
        self._fh, self._disk, self._end = fh, disk, 0

    def write(self, data) -> int:
        data = memoryview(data).cast("B")
        start = self._fh.tell()
        grows = max(0, start + len(data) - self._end)
        if grows > self._disk.free:  # what fits gets in, then the disk is full
            fits = len(data) - (grows - self._disk.free)
            self._fh.write(data[:fits])
            self._end = max(self._end, start + fits)
            self._disk.free = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._disk.free -= grows
        self._end = max(self._end, start + len(data))
        return self._fh.write(data)

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._fh.close()


class _CutShort:
    """A cv2.VideoWriter whose file keeps only ``keep`` of its bytes once released, as when the
    disk filled up; only for files whose name contains ``which``. (OpenCV writes the videos of
    these tests: their .mp4 picture videos ask for mp4v, not the H.264 PyAV would write.)"""

    keep = 0.5
    which = ""
    fail_at = 0  # from this frame on (1-based) write nothing and return False, as OpenCV 5 does

    def __init__(self, path, *args) -> None:
        self._path = path
        self._writer = _REAL_WRITER(path, *args)
        self._frames = 0

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return self._writer.isOpened()

    def write(self, image):
        self._frames += 1
        if self.fail_at and self._frames >= self.fail_at and self.which in self._path:
            return False
        return self._writer.write(image)

    def release(self) -> None:
        self._writer.release()
        if self.which in os.path.basename(self._path):
            os.truncate(self._path, int(os.path.getsize(self._path) * self.keep))


@pytest.fixture
def cut_short(monkeypatch):
    monkeypatch.setattr(cv2, "VideoWriter", _CutShort)
    monkeypatch.setattr(_CutShort, "which", "")
    monkeypatch.setattr(_CutShort, "keep", 0.5)
    monkeypatch.setattr(_CutShort, "fail_at", 0)
    return _CutShort


class _Moving:
    """Minimal engine with a camera motion: foreground where the gray value is above 128."""

    last_motion = None

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        self.last_motion = np.eye(3)
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return np.where(gray > 128, 255, 0).astype(np.uint8)


def _frames(n: int):
    rng = np.random.default_rng(3)
    return [(k, rng.integers(0, 256, (H, W, 3), dtype=np.uint8)) for k in range(n)]


# ----------------------------------------------------------------------------- mask folders


def test_a_full_disk_stops_a_mask_folder_with_only_complete_masks_counted(tmp_path, monkeypatch,
                                                                         capsys):
    masks = _masks(10)
    sizes = [len(cv2.imencode(".png", m)[1]) for m in masks]
    _Disk(monkeypatch, free=sum(sizes[:3]) + sizes[3] // 2)  # the 4th mask does not fit
    out = tmp_path / "masks"
    with pytest.raises(ProcessingError, match=r"bin000004\.png: the disk is full"):
        with open_mask_sink(out, width=W, height=H, fps=10) as sink:
            for k, mask in enumerate(masks):
                sink.write(mask, k)
    assert sorted(p.name for p in out.iterdir()) == [f"bin00000{k}.png" for k in (1, 2, 3)]
    for k in range(3):  # (imwrite said True and left 0-byte files)
        got = cv2.imread(str(out / f"bin00000{k + 1}.png"), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(got, masks[k])
    err = capsys.readouterr().err
    assert "holds 3 masks, the last bin000003.png" in err and err.count("\n") == 1


# ------------------------------------------------------------------------------ motion file


def test_a_full_disk_keeps_the_motion_rows_so_far_without_a_memory_map(tmp_path, monkeypatch,
                                                                       capsys):
    def no_memory_map(*args, **kwargs):
        raise AssertionError("writing to a memory map on a full disk is a SIGBUS")

    monkeypatch.setattr(np, "memmap", no_memory_map)
    monkeypatch.setattr(np.lib.format, "open_memmap", no_memory_map)
    _Disk(monkeypatch, free=128 + 5 * 72 + 30)  # the header, 5 rows and part of the 6th
    path = tmp_path / "cam.npy"
    with pytest.raises(ProcessingError, match="cam.npy: the disk is full"):
        with MotionSink(path) as sink:
            for k in range(10):
                sink.write(np.diag([1.0, 1.0 + k, 1.0]) if k % 3 else None)
    rows = np.load(path, allow_pickle=False)
    assert rows.shape == (5, 3, 3) and rows.dtype == np.float64
    assert np.isnan(rows[3]).all() and rows[4, 1, 1] == 5.0
    assert "cam.npy is partial (stopped by an error) but valid: it holds 5 frames" in \
        capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.npy"]


def test_a_motion_file_without_room_for_its_header_is_refused(tmp_path, monkeypatch):
    _Disk(monkeypatch, free=0)
    with pytest.raises(ProcessingError, match="the disk is full"):
        MotionSink(tmp_path / "cam.npy")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------------- videos


def test_a_video_the_full_disk_left_unplayable_is_removed_not_given_its_name(
        tmp_path, monkeypatch, cut_short):
    monkeypatch.setattr(videofile, "free_bytes", lambda folder: 0)
    with pytest.raises(ProcessingError, match=r"v.mp4: the disk is full; the unfinished video "
                                              r"would not play, so it was removed \(it was to "
                                              r"hold 4 frames\)"):
        with VisSink(tmp_path / "v.mp4", width=W, height=H, fps=10, codec="mp4v") as vis:
            for k, mask in enumerate(_masks(4)):
                vis.write(np.full((H, W, 3), 40 * k, np.uint8), mask)
    assert list(tmp_path.iterdir()) == []  # no v.mp4 without its index, no hidden leftover


def test_a_mask_video_the_full_disk_cut_short_is_kept_and_says_what_it_holds(
        tmp_path, monkeypatch, cut_short):
    monkeypatch.setattr(videofile, "free_bytes", lambda folder: 0)
    path = tmp_path / "m.mkv"
    with pytest.raises(ProcessingError) as caught:
        with open_mask_sink(path, width=W, height=H, fps=10) as sink:
            for mask in _masks(10):
                sink.write(mask)
    held = re.fullmatch(r".*m.mkv: the disk is full; the video is valid but holds only (\d+) of "
                        r"the 10 frames written to it", str(caught.value))
    assert held, str(caught.value)
    assert len(read_frames(path)) == int(held.group(1)) > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.mkv"]


def test_a_video_writer_that_cannot_open_on_a_full_disk_says_the_disk_is_full(tmp_path,
                                                                           monkeypatch):
    monkeypatch.setattr(cv2, "VideoWriter", ClosedWriter)
    monkeypatch.setattr(videofile, "free_bytes", lambda folder: 0)
    with pytest.raises(OutputError, match=r"v.mp4: the disk is full; OpenCV cannot open"):
        VideoSink(tmp_path / "v.mp4", fps=10, width=W, height=H, codec="mp4v")
    assert list(tmp_path.iterdir()) == []


def test_a_nearly_full_disk_is_no_error_when_the_video_reads_back_whole(tmp_path, monkeypatch):
    monkeypatch.setattr(videofile, "free_bytes", lambda folder: 0)
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=20) as sink:
        for mask in _masks(3):
            sink.write(mask)
    assert len(read_frames(tmp_path / "m.mkv")) == 3


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs POSIX file size limits")
def test_a_failing_video_writer_says_it_once_without_opencv_warnings(tmp_path, capfd):
    # A real failing write: a file size limit makes FFmpeg's writes fail, as a full disk does.
    import resource

    rng = np.random.default_rng(4)
    path = tmp_path / "p.mkv"
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, limit[1]))
        with pytest.raises(ProcessingError) as caught:
            with VideoSink(path, fps=10) as sink:
                for _ in range(60):  # ~20 kB each (FFV1 of noise)
                    sink.write(rng.integers(0, 256, (64, 96, 3), dtype=np.uint8))
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, limit)
        signal.signal(signal.SIGXFSZ, handler)
    # OpenCV 5 says which write failed (the run stops there), OpenCV 4 nothing (found at close).
    message = str(caught.value)
    assert "removed" in message or "holds only" in message, message
    if path.exists():  # kept: it plays, and holds what the message says
        assert f"holds only {len(read_frames(path))} of the " in message
    assert not [p for p in tmp_path.iterdir() if ".partial" in p.name]
    err = capfd.readouterr().err
    assert err == "", err[:300]  # no OpenCV warning per frame, no "partial" beside the error


@pytest.mark.parametrize("fail_at, words", [
    (4, "the video writer failed at frame 4; the video was finished with the 3 frames before it"),
    (1, "the video writer failed at frame 1; nothing was written"),
])
def test_a_write_opencv_reports_failed_stops_the_run_there(tmp_path, capsys, cut_short, fail_at,
                                                           words):
    cut_short.which, cut_short.keep, cut_short.fail_at = "v.partial", 1.0, fail_at
    with pytest.raises(ProcessingError) as caught:
        with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks, \
                VisSink(tmp_path / "v.mkv", width=W, height=H, fps=10) as vis:
            process(_frames(10), _Moving(), masks, vis=vis)
    assert str(caught.value) == f"{tmp_path / 'v.mkv'}: {words}"
    assert len(read_frames(tmp_path / "m.mkv")) == fail_at  # the run stopped at that frame
    assert len(read_frames(tmp_path / "v.mkv")) == fail_at - 1 or fail_at == 1
    assert (tmp_path / "v.mkv").exists() == (fail_at > 1)
    # One line for the masks; the error itself says what became of v.mkv.
    n = "1 frame" if fail_at == 1 else f"{fail_at} frames"
    assert capsys.readouterr().err == (f"bgsub: {tmp_path / 'm.mkv'} is partial (stopped by an "
                                       f"error) but valid: it holds {n}\n")


# ------------------------------------------------------------------------- several outputs


def test_an_output_failing_as_it_is_finished_leaves_the_others_finished(tmp_path, capsys,
                                                                        cut_short):
    # As `bgsub run` opens them: the masks first, the motion last (so closed first).
    cut_short.which, cut_short.keep = "v.partial", 0.3
    with pytest.raises(ProcessingError, match="v.mp4: .*removed"):
        with contextlib.ExitStack() as stack:
            masks = stack.enter_context(open_mask_sink(tmp_path / "m.mkv", width=W, height=H,
                                                       fps=10))
            vis = stack.enter_context(VisSink(tmp_path / "v.mp4", width=W, height=H, fps=10,
                                                codec="mp4v"))
            motion = stack.enter_context(MotionSink(tmp_path / "cam.npy"))
            process(_frames(6), _Moving(), masks, vis=vis, motion=motion)
    assert len(read_frames(tmp_path / "m.mkv")) == 6
    assert np.load(tmp_path / "cam.npy").shape == (6, 3, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.npy", "m.mkv"]
    # It holds every frame: not "partial ... holds 6 frames".
    assert capsys.readouterr().err == (f"bgsub: {tmp_path / 'm.mkv'} is complete: the run "
                                       "stopped by an error after writing all 6 frames\n")


def test_an_outputs_own_failure_is_said_when_another_error_stopped_the_run(tmp_path, capsys,
                                                                           cut_short):
    cut_short.keep = 0.0
    with pytest.raises(OutputError, match="the run's own error"):
        with VideoSink(tmp_path / "p.mp4", fps=10, codec="mp4v") as sink:
            sink.write(np.zeros((H, W, 3), np.uint8))
            raise OutputError("the run's own error")
    err = capsys.readouterr().err
    assert re.fullmatch(r"bgsub: error: .*p.mp4: the video writer could not finish the file; "
                        r"the unfinished video would not play, so it was removed \(it was to "
                        r"hold 1 frame\)\n", err), err
    assert list(tmp_path.iterdir()) == []
