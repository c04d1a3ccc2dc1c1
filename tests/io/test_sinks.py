"""Sinks: exact mask videos, PNG folders, temp-then-rename, partial outputs, refusals."""

from __future__ import annotations

import os
from typing import List

import cv2
import numpy as np
import pytest

from bgsub.io import outputs, sinks
from bgsub.errors import OutputError, ProcessingError
from bgsub.io.sinks import VideoSink, VisSink, open_mask_sink, process, render_overlay
from helpers import read_frames

W, H = 48, 32


def _masks(n: int, seed: int = 0) -> List[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [np.where(rng.random((H, W)) < 0.3, 255, 0).astype(np.uint8) for _ in range(n)]


# ------------------------------------------------------------------------------- mask videos


@pytest.mark.parametrize("ext", [".mkv", ".avi"])
def test_lossless_mask_video_round_trip_is_exact(tmp_path, ext):
    masks = _masks(5)
    path = tmp_path / f"masks{ext}"
    with open_mask_sink(path, width=W, height=H, fps=20) as sink:
        for k, mask in enumerate(masks):
            sink.write(mask, k)
    assert sink.frames_written == 5
    frames = read_frames(path)
    assert len(frames) == 5
    for got, want in zip(frames, masks):
        for c in range(3):
            np.testing.assert_array_equal(got[:, :, c], want)


def test_odd_sized_masks_are_refused_for_a_video_before_writing(tmp_path):
    with pytest.raises(OutputError, match="folder of PNGs"):
        open_mask_sink(tmp_path / "m.mkv", width=W + 1, height=H, fps=20)
    assert not list(tmp_path.iterdir())


def test_mp4_mask_video_warns_it_is_lossy(tmp_path, capsys):
    with open_mask_sink(tmp_path / "m.mp4", width=W, height=H, fps=20) as sink:
        sink.write(_masks(1)[0])
    err = capsys.readouterr().err
    assert "lossy" in err and len(err.strip().splitlines()) == 1
    assert len(read_frames(tmp_path / "m.mp4")) == 1


def test_video_is_written_under_a_temporary_name_then_renamed(tmp_path):
    path = tmp_path / "masks.mkv"
    with open_mask_sink(path, width=W, height=H, fps=20) as sink:
        sink.write(_masks(1)[0])
        assert not path.exists()
        assert (tmp_path / ".masks.partial.mkv").exists()
    assert path.exists() and not (tmp_path / ".masks.partial.mkv").exists()


def test_interrupt_leaves_a_readable_partial_video(tmp_path, capsys):
    path = tmp_path / "masks.mkv"
    masks = _masks(3)
    with pytest.raises(KeyboardInterrupt):
        with open_mask_sink(path, width=W, height=H, fps=20) as sink:
            for mask in masks:
                sink.write(mask)
            raise KeyboardInterrupt
    frames = read_frames(path)
    assert len(frames) == 3
    np.testing.assert_array_equal(frames[2][:, :, 0], masks[2])
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "partial" in err[0] and "3 frames" in err[0]
    assert "interrupted" in err[0]
    assert not (tmp_path / ".masks.partial.mkv").exists()


def test_error_inside_with_also_keeps_the_partial_video(tmp_path, capsys):
    path = tmp_path / "masks.avi"
    with pytest.raises(RuntimeError):
        with open_mask_sink(path, width=W, height=H, fps=20) as sink:
            sink.write(_masks(1)[0])
            raise RuntimeError("engine failed")
    assert len(read_frames(path)) == 1
    assert "1 frame" in capsys.readouterr().err


def test_interrupt_before_any_frame_leaves_nothing(tmp_path, capsys):
    with pytest.raises(KeyboardInterrupt):
        with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=20):
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == []
    assert "not written" in capsys.readouterr().err


# ------------------------------------------------------------------------------- PNG folders


def test_png_names_follow_the_input_index(tmp_path):
    masks = _masks(2)
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
        sink.write(masks[0], 122)
        sink.write(masks[1], 124)
    assert sorted(os.listdir(tmp_path / "out")) == ["bin000123.png", "bin000125.png"]
    got = cv2.imread(str(tmp_path / "out" / "bin000125.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(got, masks[1])


def test_png_without_index_are_numbered_from_one(tmp_path):
    with open_mask_sink(tmp_path / "a" / "b", width=W, height=H, fps=20) as sink:
        for mask in _masks(3):
            sink.write(mask)
    assert sorted(os.listdir(tmp_path / "a" / "b")) == [f"bin00000{k}.png" for k in (1, 2, 3)]


def test_existing_empty_folder_is_accepted(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("other results")
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
        sink.write(_masks(1)[0])
    assert sorted(os.listdir(tmp_path / "out")) == ["bin000001.png", "keep.txt"]


def test_folder_with_masks_is_refused_then_overwritten(tmp_path):
    folder = tmp_path / "out"
    with open_mask_sink(folder, width=W, height=H, fps=20) as sink:
        for mask in _masks(3):
            sink.write(mask)
    with pytest.raises(OutputError, match="already holds masks"):
        open_mask_sink(folder, width=W, height=H, fps=20)
    with open_mask_sink(folder, width=W, height=H, fps=20, overwrite=True) as sink:
        sink.write(_masks(1)[0])
    assert os.listdir(folder) == ["bin000001.png"]  # no stale masks from the first run


def test_interrupted_folder_holds_only_complete_masks(tmp_path, capsys):
    with pytest.raises(KeyboardInterrupt):
        with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
            for k, mask in enumerate(_masks(2)):
                sink.write(mask, k)
            raise KeyboardInterrupt
    assert sorted(os.listdir(tmp_path / "out")) == ["bin000001.png", "bin000002.png"]
    assert "2 masks" in capsys.readouterr().err


# ------------------------------------------------------------------------------- refusals


def test_existing_video_is_refused_and_overwrite_replaces_it(tmp_path):
    path = tmp_path / "m.mkv"
    path.write_bytes(b"old")
    with pytest.raises(OutputError, match="already exists"):
        open_mask_sink(path, width=W, height=H, fps=20)
    assert path.read_bytes() == b"old"
    with open_mask_sink(path, width=W, height=H, fps=20, overwrite=True) as sink:
        sink.write(_masks(1)[0])
    assert len(read_frames(path)) == 1


def test_missing_parent_folder_for_a_video(tmp_path):
    with pytest.raises(OutputError, match="does not exist"):
        open_mask_sink(tmp_path / "no" / "m.mkv", width=W, height=H, fps=20)


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root can write in read-only folders")
def test_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        with pytest.raises(OutputError, match="permission"):
            open_mask_sink(folder / "m.mkv", width=W, height=H, fps=20)
    finally:
        folder.chmod(0o700)


def test_unwritable_folder_is_refused_before_writing(tmp_path, monkeypatch):
    # The same check as test_read_only_folder, reachable when the tests run as root.
    monkeypatch.setattr(outputs.os, "access", lambda path, mode: False)
    with pytest.raises(OutputError, match="permission"):
        open_mask_sink(tmp_path / "out", width=W, height=H, fps=20)
    assert os.listdir(tmp_path) == []


def test_image_file_name_is_refused_as_mask_output(tmp_path):
    with pytest.raises(OutputError, match="folder"):
        open_mask_sink(tmp_path / "mask.png", width=W, height=H, fps=20)


@pytest.mark.parametrize("name", ["masks.txt", "masks.webm", "masks.PNG"])
def test_unknown_extension_is_refused_not_made_a_folder(tmp_path, name):
    with pytest.raises(OutputError) as refused:
        open_mask_sink(tmp_path / name, width=W, height=H, fps=20)
    message = str(refused.value)
    assert all(ext in message for ext in (".mkv", ".avi", ".mp4")) and "without an extension" in message
    assert f"ending in a slash ({name}/)" in message  # how to keep a dotted folder name
    assert os.listdir(tmp_path) == []


def test_dotted_folder_name_is_a_folder_when_it_exists_or_ends_in_a_slash(tmp_path):
    (tmp_path / "run.v1").mkdir()
    for output in (tmp_path / "run.v1", f"{tmp_path / 'run.v2'}{os.sep}"):
        with open_mask_sink(output, width=W, height=H, fps=20) as sink:
            sink.write(_masks(1)[0])
        assert os.listdir(output) == ["bin000001.png"]


class ClosedWriter:
    """A cv2.VideoWriter that did not open (what OpenCV gives when FFmpeg cannot write the
    container's header)."""

    def __init__(self, *args):
        pass

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return False

    def release(self):
        pass


def test_failing_video_writer_is_an_output_error(tmp_path, monkeypatch):
    monkeypatch.setattr(cv2, "VideoWriter", ClosedWriter)
    with pytest.raises(OutputError, match="video writer"):
        open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=20)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("bad", [np.zeros((H, W), np.float32), np.zeros((H, W, 3), np.uint8),
                                 np.zeros((H + 1, W), np.uint8)])
def test_mask_shape_and_dtype_are_checked(tmp_path, bad):
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
        with pytest.raises(ValueError):
            sink.write(bad)


@pytest.mark.parametrize("name", ["out/masks", "m.mkv"])
@pytest.mark.parametrize("width, height", [(-2, H), (W, 0)])
def test_a_mask_size_below_one_pixel_is_refused_before_writing(tmp_path, name, width, height):
    with pytest.raises(OutputError, match=f"masks of {width}x{height} pixels"):
        open_mask_sink(tmp_path / name, width=width, height=height, fps=20)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["out", "out.mkv"])
def test_a_whole_float_size_is_taken(tmp_path, name):
    # What cv2.VideoCapture.get(cv2.CAP_PROP_FRAME_WIDTH) gives: 320.0.
    with open_mask_sink(tmp_path / name, width=float(W), height=float(H), fps=20) as sink:
        sink.write(_masks(1)[0])
    assert sink.frames_written == 1


def test_a_bool_mask_is_written_as_0_and_255(tmp_path):
    mask = _masks(1)[0]
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
        sink.write(mask > 0)
    got = cv2.imread(str(tmp_path / "out" / "bin000001.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(got, mask)


@pytest.mark.parametrize("value", [1, 127])
def test_a_mask_with_values_other_than_0_and_255_is_refused(tmp_path, value):
    # A 0/1 mask would be scored as all background by `bgsub eval`.
    mask = np.where(_masks(1)[0] > 0, value, 0).astype(np.uint8)
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=20) as sink:
        with pytest.raises(ValueError, match=f"only 0 .* and 255 .*, not {value}"):
            sink.write(mask)
    assert sink.frames_written == 0


# ------------------------------------------------------------------------------- pictures


@pytest.mark.parametrize("make", [
    lambda path: VideoSink(path, fps=10, width=0, height=H),
    lambda path: VisSink(path, width=-4, height=H, fps=10),
])
def test_picture_sinks_refuse_a_size_below_one_pixel(tmp_path, make):
    with pytest.raises(OutputError, match="must be whole numbers of at least 1"):
        make(tmp_path / "p.mkv")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("ext", [".mp4", ".avi", ".mkv"])
def test_video_sink_writes_colour_pictures(tmp_path, ext):
    picture = np.zeros((H, W, 3), np.uint8)
    picture[:, :, 2] = 200  # red
    with VideoSink(tmp_path / f"p{ext}", fps=10) as sink:
        for _ in range(4):
            sink.write(picture)
    frames = read_frames(tmp_path / f"p{ext}")
    assert len(frames) == 4 and frames[0].shape == (H, W, 3)
    assert abs(int(frames[0][:, :, 2].mean()) - 200) < 10 and frames[0][:, :, 0].mean() < 10


def test_video_sink_keeps_the_last_column_and_row_of_an_odd_size(tmp_path):
    # OpenCV's writer drops them; the sink pads to even instead.
    picture = np.zeros((H + 1, W + 1, 3), np.uint8)
    picture[-1, :] = 255
    picture[:, -1] = 255
    with VideoSink(tmp_path / "p.mkv", fps=10) as sink:
        sink.write(picture)
    (frame,) = read_frames(tmp_path / "p.mkv")
    assert frame.shape == (H + 2, W + 2, 3)
    np.testing.assert_array_equal(frame[:H + 1, :W + 1], picture)  # FFV1: exact


def test_video_sink_blanks_keep_the_video_in_step(tmp_path):
    picture = np.full((H, W, 3), 180, np.uint8)
    with VideoSink(tmp_path / "p.mkv", fps=10) as sink:
        sink.write_blank()  # before the size is known
        sink.write(picture)
        sink.write_blank()
    frames = read_frames(tmp_path / "p.mkv")
    assert [int(f.mean()) < 20 for f in frames] == [True, False, True]


def test_video_sink_refuses_a_picture_of_another_size(tmp_path):
    with VideoSink(tmp_path / "p.mp4", fps=10) as sink:
        sink.write(np.zeros((H, W, 3), np.uint8))
        with pytest.raises(ValueError):
            sink.write(np.zeros((H, W + 2, 3), np.uint8))


def test_render_overlay_tints_the_mask_and_puts_it_beside(tmp_path):
    frame = np.full((H, W, 3), 100, np.uint8)
    mask = np.zeros((H, W), np.uint8)
    mask[10:20, 10:30] = 255
    out = render_overlay(frame, mask)
    assert out.shape == (H, 2 * W, 3)
    np.testing.assert_array_equal(out[:, W:, 0], mask)
    np.testing.assert_array_equal(out[0, 0], frame[0, 0])  # background untouched
    inside = out[15, 20]
    assert inside[2] > 150 and inside[0] < 100  # foreground tinted red


def test_vis_sink_writes_side_by_side_video(tmp_path):
    with VisSink(tmp_path / "vis.mp4", width=W, height=H, fps=10) as vis:
        for mask in _masks(3):
            vis.write(np.zeros((H, W, 3), np.uint8), mask)
    frames = read_frames(tmp_path / "vis.mp4")
    assert len(frames) == 3 and frames[0].shape == (H, 2 * W, 3)


def test_vis_sink_takes_a_bool_mask_as_0_and_255(tmp_path):
    mask = _masks(1)[0]
    frame = np.full((H, W, 3), 100, np.uint8)
    with VisSink(tmp_path / "vis.mkv", width=W, height=H, fps=10) as vis:
        vis.write(frame, mask > 0)
    got = read_frames(tmp_path / "vis.mkv")[0]
    np.testing.assert_array_equal(got, render_overlay(frame, mask))


@pytest.mark.parametrize("frame, mask, words", [
    (np.zeros((H, W, 3), np.uint8), np.zeros((H, W), np.float32), "a mask must be a uint8"),
    (np.zeros((H, W, 3), np.float32), np.zeros((H, W), np.uint8), "a frame must be a uint8"),
    (np.zeros((H, W, 3), np.uint8), np.zeros((H - 2, W), np.uint8), "must both be 48x32"),
])
def test_vis_sink_names_what_is_wrong_with_a_frame_or_mask(tmp_path, frame, mask, words):
    with VisSink(tmp_path / "vis.mkv", width=W, height=H, fps=10) as vis:
        with pytest.raises(ValueError, match=words):
            vis.write(frame, mask)


# ------------------------------------------------------------------------------- process()


class _Threshold:
    """Minimal engine: foreground where the gray value is above 128; reports a status."""

    def __init__(self):
        self.n = 0
        self.last_status = "ok"

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        self.n += 1
        self.last_status = "ok" if self.n % 2 else "fallback: test"
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return np.where(gray > 128, 255, 0).astype(np.uint8)


def test_process_writes_every_mask_and_counts_statuses(tmp_path):
    rng = np.random.default_rng(1)
    frames = [(k + 10, rng.integers(0, 256, (H, W, 3), dtype=np.uint8)) for k in range(5)]
    seen = []
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as sink:
        stats = process(frames, _Threshold(), sink, on_frame=lambda i, m: seen.append(i))
    assert stats.frames == 5 and seen == [10, 11, 12, 13, 14]
    assert stats.has_status and stats.not_ok == 2 and stats.statuses["fallback: test"] == 2
    got = cv2.imread(str(tmp_path / "out" / "bin000013.png"), cv2.IMREAD_UNCHANGED)
    gray = cv2.cvtColor(frames[2][1], cv2.COLOR_BGR2GRAY)
    np.testing.assert_array_equal(got, np.where(gray > 128, 255, 0))


class _ZeroOne(_Threshold):
    """A plugin engine that returns 0/1 masks."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        return super().apply(image) // 255


def test_process_refuses_an_engines_0_1_mask_as_a_processing_error(tmp_path):
    frames = [(0, np.full((H, W, 3), 200, np.uint8))]
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as sink:
        with pytest.raises(ProcessingError, match="_ZeroOne returned an unusable mask for "
                                                  "frame 1: .*only 0.*and 255"):
            process(frames, _ZeroOne(), sink)


class _Halved(_Threshold):
    """A plugin engine that returns masks of half the frame's size."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        return super().apply(image)[::2, ::2]


def test_process_refuses_an_engines_mask_of_another_size_as_a_processing_error(tmp_path):
    frames = [(0, np.full((H, W, 3), 200, np.uint8))]
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as sink:
        with pytest.raises(ProcessingError, match=f"_Halved returned an unusable mask for "
                                                  f"frame 1: a mask must be {W}x{H}"):
            process(frames, _Halved(), sink)
    assert sink.frames_written == 0


def test_process_refuses_flow_vis_without_debug_image(tmp_path):
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as sink, \
            VideoSink(tmp_path / "f.mp4", fps=10) as flow:
        with pytest.raises(TypeError):
            process([], _Threshold(), sink, flow_vis=flow)


@pytest.mark.parametrize("check", [sinks.check_file_output, sinks.check_video_output,
                                   sinks.check_mask_output])
def test_an_empty_output_path_is_refused_not_read_as_the_current_folder(check):
    with pytest.raises(OutputError, match="empty"):
        check("")


def test_an_output_under_a_file_names_the_file_as_not_a_folder(tmp_path):
    blocker = tmp_path / "plain.txt"
    blocker.write_text("not a folder")
    with pytest.raises(OutputError, match="plain.txt is not a folder"):
        sinks.check_video_output(blocker / "masks.mkv")
    with pytest.raises(OutputError, match="plain.txt is not a folder"):
        sinks.check_mask_output(blocker / "sub" / "masks")
    with pytest.raises(OutputError, match="plain.txt is not a folder"):
        sinks.check_video_output(blocker / "sub" / "masks.mkv")


def test_a_refused_file_is_explained_with_the_systems_reason(tmp_path):
    assert "No such file" in outputs.why_not_writable(tmp_path / "missing" / "x.mkv")
    assert outputs.why_not_writable(tmp_path / "x.mkv") == ""
    assert list(tmp_path.iterdir()) == []  # the probe leaves nothing behind


def test_motion_sink_keeps_the_rows_so_far_when_interrupted(tmp_path, capsys):
    from bgsub.io.sinks import MotionSink

    path = tmp_path / "cam.npy"
    shift = np.array([[1.0, 0, 2], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(KeyboardInterrupt):
        with MotionSink(path) as sink:
            sink.write(np.eye(3))
            sink.write(shift)
            sink.write(None)  # not measured
            raise KeyboardInterrupt
    rows = np.load(path, allow_pickle=False)
    assert rows.shape == (3, 3, 3)
    np.testing.assert_array_equal(rows[1], shift)
    assert np.isnan(rows[2]).all()
    assert "cam.npy is partial (interrupted) but valid: it holds 3 frames" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.npy"]  # no scratch file left
    with pytest.raises(OutputError, match="already exists"):
        MotionSink(path)
