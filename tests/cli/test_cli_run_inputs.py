"""`bgsub run --roi / --motion-in / --model / --methods` end to end on a small generated panning
clip (lossless, so a camera motion written by one run is exact for the next)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.io.sources import open_source

H, W, PAN, N = 96, 128, 4, 8


def _world(seed, h, w):
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 4, w // 4, 3)).astype(np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


@pytest.fixture
def clip(tmp_path):
    """A lossless clip: the world pans PAN px a frame to the right; a bright block moves down
    the bottom-left corner (outside the region of interest ``roi``), a red one against the pan
    across the top."""
    world = _world(0, H, W + PAN * N + 8)
    path = tmp_path / "pan.mkv"
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 25.0,
                             (W, H), True)
    for k in range(N):
        frame = world[:, PAN * (N - k):PAN * (N - k) + W].copy()
        frame[60 + 3 * k:72 + 3 * k, 4:16] = 250
        frame[10:26, 80 - 3 * k:96 - 3 * k] = (30, 30, 220)
        writer.write(frame)
    writer.release()
    return path


@pytest.fixture
def roi(tmp_path):
    """The top half of the frame, drawn at half size (scaled to the frames)."""
    path = tmp_path / "roi.png"
    mask = np.zeros((H // 2, W // 2), np.uint8)
    mask[:H // 4] = 255
    cv2.imwrite(str(path), mask)
    return path


def _masks(path):
    with open_source(str(path)) as source:
        return [frame[:, :, 0] for _, frame in source]


def _run(*argv):
    return main([str(a) for a in argv] + ["-q"])


@pytest.mark.parametrize("method", ["mog2", "compensated"])
def test_roi_leaves_no_foreground_outside(clip, roi, tmp_path, method):
    out = tmp_path / "m.mkv"
    assert _run("run", clip, "-o", out, "-m", method, "--roi", roi) == 0
    masks = _masks(out)
    assert len(masks) == N
    assert not any(m[H // 2:].any() for m in masks) and any(m[:H // 2].any() for m in masks)


def test_roi_is_the_roi_parameter(clip, roi, tmp_path):
    assert _run("run", clip, "-o", tmp_path / "a.mkv", "-m", "mog2", "--roi", roi) == 0
    assert _run("run", clip, "-o", tmp_path / "b.mkv", "-m", "mog2", "-p", f"roi={roi}") == 0
    assert all(np.array_equal(a, b) for a, b in zip(_masks(tmp_path / "a.mkv"),
                                                    _masks(tmp_path / "b.mkv")))


@pytest.mark.parametrize("make, words", [
    (lambda p: None, "no such file"),
    (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\nnot really"), "cannot read the region"),
    (lambda p: cv2.imwrite(str(p), np.zeros((H, W), np.uint8)), "all black"),
    (lambda p: cv2.imwrite(str(p), np.full((H, H), 255, np.uint8)), "aspect ratio"),
])
def test_bad_roi_is_one_line(clip, tmp_path, bgsub_error, make, words):
    path = tmp_path / "bad.png"
    make(path)
    out = tmp_path / "m.mkv"
    line = bgsub_error(["run", clip, "-o", out, "-m", "mog2", "--roi", path])
    assert words in line and str(path) in line
    assert not out.exists()


def test_motion_in_reads_back_what_motion_wrote(clip, tmp_path):
    first, second = tmp_path / "a.npy", tmp_path / "b.npy"
    assert _run("run", clip, "-o", tmp_path / "a.mkv", "-m", "compensated",
                "--motion", first) == 0
    assert _run("run", clip, "-o", tmp_path / "b.mkv", "-m", "compensated", "--motion-in",
                first, "--motion", second) == 0
    np.testing.assert_allclose(np.load(second), np.load(first), atol=1e-9)


def test_motion_in_is_used(clip, tmp_path):
    given = np.repeat(np.eye(3)[None], N, axis=0)
    given[1:, 0, 2] = -PAN  # the wrong way
    np.save(tmp_path / "wrong.npy", given)
    assert _run("run", clip, "-o", tmp_path / "a.mkv", "-m", "compensated") == 0
    assert _run("run", clip, "-o", tmp_path / "b.mkv", "-m", "compensated",
                "--motion-in", tmp_path / "wrong.npy") == 0
    assert any(not np.array_equal(a, b) for a, b in zip(_masks(tmp_path / "a.mkv"),
                                                        _masks(tmp_path / "b.mkv")))


def test_motion_in_shorter_than_the_input_says_the_rest_was_estimated(clip, tmp_path, capsys):
    np.save(tmp_path / "short.npy", np.repeat(np.eye(3)[None], 3, axis=0))
    assert main(["run", str(clip), "-o", str(tmp_path / "m.mkv"), "-m", "compensated",
                 "--motion-in", str(tmp_path / "short.npy")]) == 0
    assert "holds the camera motion of 3 frames; the 5 after them were estimated" in \
        capsys.readouterr().err


@pytest.mark.parametrize("content, words", [
    (np.zeros((N, 2, 3)), "(N, 3, 3) array"),
    (np.full((N, 3, 3), np.inf), "entry 0 is partly not finite"),
    (b"garbage", "not an .npy file; the known camera motion is an (N, 3, 3) float array"),
])
def test_bad_motion_in_is_one_line(clip, tmp_path, bgsub_error, content, words):
    path = tmp_path / "cam.npy"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        np.save(path, content)
    line = bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "-m", "compensated",
                        "--motion-in", path])
    assert words in line


def test_motion_in_needs_a_moving_camera_method(clip, tmp_path, bgsub_error):
    np.save(tmp_path / "cam.npy", np.repeat(np.eye(3)[None], N, axis=0))
    line = bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "-m", "mog2",
                        "--motion-in", tmp_path / "cam.npy"])
    assert "--motion-in" in line and "mog2" in line


def test_motion_in_is_for_one_input(clip, tmp_path, bgsub_error):
    np.save(tmp_path / "cam.npy", np.repeat(np.eye(3)[None], N, axis=0))
    line = bgsub_error(["run", clip, clip.with_name("other.mkv"), "-o", tmp_path / "out",
                        "-m", "compensated", "--motion-in", tmp_path / "cam.npy"])
    assert "single input" in line


def test_model_is_the_model_parameter(clip, tmp_path):
    from helpers import model_path

    model = model_path()
    assert _run("run", clip, "-o", tmp_path / "a.mkv", "--model", model, "--max-frames",
                "3") == 0
    assert _run("run", clip, "-o", tmp_path / "b.mkv", "-p", f"model={model}",
                "--max-frames", "3") == 0
    assert all(np.array_equal(a, b) for a, b in zip(_masks(tmp_path / "a.mkv"),
                                                    _masks(tmp_path / "b.mkv")))


def test_model_errors_are_one_line(clip, tmp_path, bgsub_error):
    assert "takes no model" in bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "-m",
                                            "mog2", "--model", "natural"])
    assert "both set it" in bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "--model",
                                         "natural", "-p", "model=natural"])
    assert "nope" in bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "--model", "nope"])


@pytest.mark.parametrize("flag", ["-m", "--method", "--methods"])
def test_run_takes_every_spelling_of_the_method(clip, tmp_path, flag):
    assert _run("run", clip, "-o", tmp_path / "m.mkv", flag, "mog2", "--json") == 0


def test_run_refuses_several_methods(clip, tmp_path, bgsub_error):
    line = bgsub_error(["run", clip, "-o", tmp_path / "m.mkv", "--methods", "mog2,knn"])
    assert "run takes one method" in line and "compare" in line


@pytest.mark.parametrize("flag", ["-m", "--methods", "--method"])
def test_compare_and_bench_take_every_spelling_of_the_methods(clip, tmp_path, flag, capsys):
    assert main(["compare", str(clip), "-o", str(tmp_path / "cmp"), flag, "mog2,framediff",
                 "--mask-format", "none", "--no-video", "-q"]) == 0
    assert main(["bench", flag, "mog2,framediff", "--size", "32x24", "--max-frames", "2",
                 "--repeats", "1", "--json", "-q"]) == 0
    out = capsys.readouterr().out
    assert out.count("framediff") >= 2 and out.count("mog2") >= 2
