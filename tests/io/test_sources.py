"""Frame sources: video files, image folders and glob patterns, frame ranges, resizing, errors."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import List

import cv2
import numpy as np
import pytest

from bgsub.errors import InputError
from bgsub.io.sources import MIN_FRAME_SIZE, natural_key, open_source

W, H = 40, 30


def _frames(n: int, *, w: int = W, h: int = H, seed: int = 0) -> List[np.ndarray]:
    """Distinct colour frames; frame k has value 8*k in its top-left pixel block."""
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(n):
        frame = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        frame[:4, :4] = 8 * k
        frames.append(frame)
    return frames


def _write_video(path: Path, frames: List[np.ndarray], *, fps: float = 30.0) -> Path:
    """Lossless FFV1 video, so frames read back exactly."""
    h, w = frames[0].shape[:2]
    is_color = frames[0].ndim == 3
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), fps,
                             (w, h), is_color)
    assert writer.isOpened()
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


def _write_folder(folder: Path, frames: List[np.ndarray], *, pattern: str = "in{:06d}.png",
                  first: int = 1) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for k, frame in enumerate(frames):
        assert cv2.imwrite(str(folder / pattern.format(k + first)), frame)
    return folder


def _read_all(path, **kwargs):
    with open_source(path, **kwargs) as source:
        return source.info, list(source)


# ------------------------------------------------------------------------------- videos


def test_colour_video_yields_every_frame_exactly(tmp_path):
    frames = _frames(6)
    info, items = _read_all(_write_video(tmp_path / "clip.mkv", frames))
    assert (info.width, info.height, info.kind, info.frame_count) == (W, H, "video", 6)
    assert info.fps == pytest.approx(30.0) and not info.fps_is_default
    assert [i for i, _ in items] == list(range(6))
    for (_, got), want in zip(items, frames):
        assert got.shape == (H, W, 3) and got.dtype == np.uint8
        np.testing.assert_array_equal(got, want)


def test_gray_video_is_expanded_to_three_channels(tmp_path):
    gray = [f[:, :, 0].copy() for f in _frames(3)]
    _, items = _read_all(_write_video(tmp_path / "gray.mkv", gray))
    for (_, got), want in zip(items, gray):
        assert got.shape == (H, W, 3)
        for c in range(3):
            np.testing.assert_array_equal(got[:, :, c], want)


def test_video_frame_range(tmp_path):
    frames = _frames(12)
    info, items = _read_all(_write_video(tmp_path / "clip.mkv", frames), start=2, stop=9, step=3)
    assert [i for i, _ in items] == [2, 5, 8]
    assert info.frame_count == 3
    assert info.fps == pytest.approx(10.0)  # 30 fps / step 3: plays at the input's speed
    for index, got in items:
        np.testing.assert_array_equal(got, frames[index])


def test_video_stop_past_end_reads_to_the_end(tmp_path):
    info, items = _read_all(_write_video(tmp_path / "clip.mkv", _frames(5)), start=3, stop=100)
    assert [i for i, _ in items] == [3, 4] and info.frame_count == 2


def test_source_can_be_iterated_twice(tmp_path):
    with open_source(_write_video(tmp_path / "clip.mkv", _frames(4))) as source:
        assert [i for i, _ in source] == [i for i, _ in source] == [0, 1, 2, 3]


# ------------------------------------------------------------------------------- folders, globs


def test_folder_natural_order_and_only_images(tmp_path):
    frames = _frames(12)
    folder = tmp_path / "seq"
    folder.mkdir()
    for k, frame in enumerate(frames):  # in1.png ... in12.png: "in10" sorts before "in2" as text
        cv2.imwrite(str(folder / f"in{k + 1}.png"), frame)
    (folder / "notes.txt").write_text("not a frame")
    (folder / "._in1.png").write_bytes(b"macOS resource fork")
    info, items = _read_all(folder)
    assert (info.kind, info.frame_count) == ("folder", 12)
    assert info.fps == 25.0 and info.fps_is_default
    assert [i for i, _ in items] == list(range(12))
    for (_, got), want in zip(items, frames):
        np.testing.assert_array_equal(got, want)


def test_natural_key_orders_numbers_as_numbers():
    names = ["in10.jpg", "in2.jpg", "in1.jpg", "in000003.jpg"]
    assert sorted(names, key=natural_key) == ["in1.jpg", "in2.jpg", "in000003.jpg", "in10.jpg"]


def test_cdnet_sequence_folder_reads_its_input_folder(tmp_path):
    frames = _frames(3)
    _write_folder(tmp_path / "traffic" / "input", frames)
    _write_folder(tmp_path / "traffic" / "groundtruth", [f[:, :, 0] for f in frames],
                  pattern="gt{:06d}.png")
    cv2.imwrite(str(tmp_path / "traffic" / "ROI.bmp"), frames[0])
    info, items = _read_all(tmp_path / "traffic")
    assert info.frame_count == 3 and len(items) == 3
    np.testing.assert_array_equal(items[1][1], frames[1])


def test_gray_images_are_expanded_to_three_channels(tmp_path):
    gray = [f[:, :, 1].copy() for f in _frames(2)]
    _, items = _read_all(_write_folder(tmp_path / "gray", gray))
    assert items[0][1].shape == (H, W, 3)
    np.testing.assert_array_equal(items[0][1][:, :, 2], gray[0])


def test_folder_frame_range(tmp_path):
    frames = _frames(10)
    info, items = _read_all(_write_folder(tmp_path / "seq", frames), start=1, stop=8, step=2)
    assert [i for i, _ in items] == [1, 3, 5, 7] and info.frame_count == 4
    np.testing.assert_array_equal(items[2][1], frames[5])


def test_glob_pattern_in_natural_order(tmp_path):
    frames = _frames(11)
    folder = _write_folder(tmp_path / "frames", frames, pattern="f{}.png")
    cv2.imwrite(str(folder / "other.jpg"), frames[0])
    info, items = _read_all(str(folder / "f*.png"))
    assert info.kind == "glob" and info.frame_count == 11
    for (_, got), want in zip(items, frames):
        np.testing.assert_array_equal(got, want)


# ------------------------------------------------------------------------------- resizing


def test_scale_halves_the_frames(tmp_path):
    info, items = _read_all(_write_video(tmp_path / "c.mkv", _frames(2, w=64, h=48)), scale=0.5)
    assert (info.width, info.height) == (32, 24)
    assert items[0][1].shape == (24, 32, 3)


def test_a_resize_beyond_the_largest_side_is_refused_before_reading(tmp_path):
    path = _write_video(tmp_path / "c.mkv", _frames(2, w=64, h=48))
    with pytest.raises(InputError, match="largest side"):
        _read_all(path, scale=1000)


def test_width_keeps_aspect_ratio(tmp_path):
    info, items = _read_all(_write_folder(tmp_path / "s", _frames(2, w=64, h=48)), width=100)
    assert (info.width, info.height) == (100, 75)
    assert items[1][1].shape == (75, 100, 3)


def test_shrinking_averages_pixels(tmp_path):
    frame = np.zeros((40, 40, 3), np.uint8)
    frame[::2, ::2] = 255  # a checkerboard-like grid: INTER_AREA averages it to ~64
    _, items = _read_all(_write_folder(tmp_path / "s", [frame]), scale=0.5)
    assert np.abs(items[0][1].astype(int) - 64).max() <= 1


# ------------------------------------------------------------------------------- errors


def _error(path, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        _read_all(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_missing_path(tmp_path):
    assert "no such file" in _error(tmp_path / "nope.mp4")


def test_text_file_is_not_a_video(tmp_path):
    path = tmp_path / "clip.mp4"
    path.write_text("this is not a video\n" * 20)
    assert str(path) in _error(path)


def test_empty_file_is_not_a_video(tmp_path):
    path = tmp_path / "empty.mkv"
    path.write_bytes(b"")
    assert str(path) in _error(path)


def test_video_without_decodable_frames(tmp_path):
    # FFmpeg opens an .mjpeg as a Motion JPEG video, but this one holds no JPEG data.
    path = tmp_path / "still.mjpeg"
    path.write_text("no jpeg here")
    assert "no frames" in _error(path)


def test_a_single_image_is_not_a_video(tmp_path):
    path = tmp_path / "still.jpg"
    cv2.imwrite(str(path), np.zeros((48, 64, 3), np.uint8))
    assert "is one image, not a video; give the folder of the frames" in _error(path)


def test_empty_folder(tmp_path):
    (tmp_path / "empty").mkdir()
    assert "no images" in _error(tmp_path / "empty")


def test_folder_without_images(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "readme.txt").write_text("hi")
    assert "no images" in _error(tmp_path / "docs")


def test_glob_matching_nothing(tmp_path):
    assert "matches" in _error(str(tmp_path / "*.png"))


def test_unreadable_image_is_reported_when_reached(tmp_path):
    folder = _write_folder(tmp_path / "seq", _frames(4))
    (folder / "in000003.png").write_text("not a png")
    with open_source(folder) as source:
        frames = iter(source)
        assert next(frames)[0] == 0 and next(frames)[0] == 1  # streamed: earlier frames come first
        with pytest.raises(InputError, match="in000003.png"):
            next(frames)


def test_mixed_image_sizes_name_the_file_and_both_sizes(tmp_path):
    folder = _write_folder(tmp_path / "seq", _frames(3))
    cv2.imwrite(str(folder / "in000004.png"), _frames(1, w=W + 2)[0])
    message = _error(folder)
    assert "in000004.png" in message and f"{W + 2}x{H}" in message and f"{W}x{H}" in message


def test_frames_smaller_than_a_patch(tmp_path):
    small = MIN_FRAME_SIZE - 1
    message = _error(_write_folder(tmp_path / "tiny", _frames(2, w=small, h=small)))
    assert f"{small}x{small}" in message and "13x13" in message
    # True for every engine, MOG2 included (it reads no patches).
    assert "the smallest frames bgsub processes" in message and "patches" not in message


def test_resizing_below_a_patch(tmp_path):
    assert "after resizing" in _error(_write_video(tmp_path / "c.mkv", _frames(2)), scale=0.3)


def test_exactly_patch_sized_frames_are_fine(tmp_path):
    info, _ = _read_all(_write_folder(tmp_path / "s", _frames(1, w=MIN_FRAME_SIZE,
                                                             h=MIN_FRAME_SIZE)))
    assert (info.width, info.height) == (MIN_FRAME_SIZE, MIN_FRAME_SIZE)


def test_start_past_the_end_of_a_video(tmp_path):
    assert "past the end" in _error(_write_video(tmp_path / "c.mkv", _frames(4)), start=4)


def test_start_past_the_end_of_a_folder(tmp_path):
    assert "past the end" in _error(_write_folder(tmp_path / "s", _frames(3)), start=7)


@pytest.mark.parametrize("kwargs", [
    dict(step=0), dict(step=-1), dict(start=-1), dict(start=3, stop=3), dict(start=3, stop=1),
    dict(scale=0.0), dict(scale=-2.0), dict(scale=float("nan")), dict(width=0),
    dict(scale=0.5, width=20),
])
def test_invalid_options(tmp_path, kwargs):
    _error(_write_folder(tmp_path / "s", _frames(3)), **kwargs)


def test_a_truncated_jpeg_is_reported_by_name(tmp_path, capfd):
    folder = _write_folder(tmp_path / "seq", _frames(3), pattern="in{:06d}.jpg")
    cut = folder / "in000002.jpg"
    data = cut.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    message = _error(folder)
    assert "in000002.jpg" in message and "truncated" in message
    assert "Premature end" not in capfd.readouterr().err  # no nameless decoder chatter


def test_whole_jpegs_read_as_before(tmp_path):
    frames = _frames(2)
    folder = _write_folder(tmp_path / "seq", frames, pattern="in{:06d}.jpg")
    _, got = _read_all(folder)
    for (_, image), path in zip(got, sorted(folder.iterdir())):
        np.testing.assert_array_equal(image, cv2.imread(str(path)))


@pytest.mark.parametrize("path", ["", "  "])
def test_an_empty_input_path_is_refused_not_read_as_the_current_folder(path):
    with pytest.raises(InputError, match="empty"):
        open_source(path)


# ------------------------------------------------------------------ truncation, folders


def _truncated(path: Path, n: int) -> Path:
    """A video of ``n`` frames cut to the first half of its bytes: its header still says ``n``."""
    video = _write_video(path.with_name("whole" + path.suffix), _frames(n))
    data = video.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def test_a_video_that_ends_before_its_declared_length_says_so(tmp_path):
    cut = _truncated(tmp_path / "cut.mkv", 30)
    with open_source(cut) as source:
        assert source.info.frame_count == 30
        assert source.truncation() is None  # nothing read yet
        decoded = len(list(source))
        assert 0 < decoded < 28
        assert source.truncation() == (f"{cut} ended after {decoded} of the 30 frames its "
                                       "header declares (truncated or damaged?)")


def test_a_start_at_the_decodable_end_of_a_cut_video_is_past_its_end(tmp_path):
    cut = _truncated(tmp_path / "cut.mkv", 30)
    with open_source(cut) as source:
        decoded = len(list(source))
    for start in (decoded, decoded + 3):  # both in the range the header declares
        with open_source(cut, start=start) as source:
            with pytest.raises(InputError, match=f"start frame {start} is past the end of the "
                                                 f"video .{decoded} frames decode; its header "
                                                 "declares 30"):
                list(source)


@pytest.mark.parametrize("kwargs", [dict(stop=5), dict(start=2, stop=8, step=3)])
def test_no_truncation_when_the_range_stops_before_the_damage(tmp_path, kwargs):
    with open_source(_truncated(tmp_path / "cut.mkv", 30), **kwargs) as source:
        list(source)
        assert source.truncation() is None


@pytest.mark.parametrize("step", [1, 4])
def test_a_whole_video_is_not_truncated(tmp_path, step):
    with open_source(_write_video(tmp_path / "c.mkv", _frames(10)), step=step) as source:
        assert len(list(source)) == len(range(0, 10, step))
        assert source.truncation() is None


def test_folders_the_frames_are_listed_from(tmp_path):
    seq = tmp_path / "seq"
    _write_folder(seq / "input", _frames(2))
    _write_folder(tmp_path / "other" / "input", _frames(1), first=3)
    with open_source(seq) as source:  # a CDnet sequence: its input/
        assert source.folders == ((seq / "input").resolve(),)
    with open_source(str(tmp_path / "*" / "input" / "in*.png")) as source:
        assert set(source.folders) == {(seq / "input").resolve(),
                                       (tmp_path / "other" / "input").resolve()}
    with open_source(_write_video(tmp_path / "c.mkv", _frames(2))) as source:
        assert source.folders == ()


@pytest.mark.parametrize("step, want", [(1, 30.0), (3, 10.0)])
def test_a_given_frame_rate_replaces_the_default_of_a_folder(tmp_path, step, want):
    folder = tmp_path / "seq"
    folder.mkdir()
    for k, frame in enumerate(_frames(6)):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), frame)
    with open_source(folder, fps=30, step=step) as source:
        assert source.info.fps == pytest.approx(want) and not source.info.fps_is_default


@pytest.mark.parametrize("fps", [np.float32(30), np.int64(30), Fraction(30)])
def test_a_frame_rate_of_any_real_number_type_is_accepted(tmp_path, fps):
    video = _write_video(tmp_path / "clip.mkv", _frames(3))
    with open_source(video, fps=fps) as source:
        assert source.info.fps == 30.0 and type(source.info.fps) is float


@pytest.mark.parametrize("fps", [0, 0.001, -5, float("nan"), float("inf"), 5000,
                                 np.float32("nan"), True, "30"])
def test_an_impossible_frame_rate_is_refused(tmp_path, fps):
    video = _write_video(tmp_path / "clip.mkv", _frames(3))
    with pytest.raises(InputError, match="frame rate must be a number of frames per second"):
        open_source(video, fps=fps)


def test_overlapping_quiet_blocks_restore_opencvs_log_level_once_all_end():
    # Blocks from two threads (sinks written in parallel) end in the other order than they
    # began: saved and restored per block, OpenCV stayed silent for good.
    import cv2

    from bgsub.io.sources import quiet_opencv

    logging = cv2.utils.logging
    before = logging.getLogLevel()
    first, second = quiet_opencv(), quiet_opencv()
    first.__enter__()
    second.__enter__()
    first.__exit__(None, None, None)
    assert logging.getLogLevel() == logging.LOG_LEVEL_SILENT  # the other block still runs
    second.__exit__(None, None, None)
    assert logging.getLogLevel() == before
