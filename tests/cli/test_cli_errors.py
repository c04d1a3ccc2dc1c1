"""A corpus of truncated, corrupt and odd inputs, models, parameters and output paths: every
command refuses each one with its exit status and exactly one ``bgsub: error:`` line on stderr
(native libraries' lines included: captured at the file descriptor), never a traceback."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.io.flowio import read_flo
from bgsub.model.rbm import FORMAT_VERSION, load_model
from helpers import one_error_line, write_bins, write_input_sequence

W, H, FRAMES = 64, 48, 5
LONG_NAME = "x" * 300  # longer than any file system's 255-byte names


def _texture(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    smooth = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 1.5)
    return (255 * (smooth - smooth.min()) / np.ptp(smooth)).astype(np.uint8)


def _model_file(path: Path, *, patch: int = 13, factors: int = 8, hidden: int = 4,
                meta: dict = None, **arrays) -> Path:
    """A hand-written model archive (consistent shapes unless ``arrays`` replace some)."""
    rng = np.random.default_rng(0)
    n = patch * patch
    entries = {"wxf": rng.normal(0, 0.1, (n, factors)), "wyf": rng.normal(0, 0.1, (n, factors)),
               "whf": rng.normal(0, 0.1, (hidden, factors)), "bh": np.zeros(hidden),
               "by": np.zeros(n)}
    entries = {k: v.astype(np.float32) for k, v in entries.items()}
    entries.update(arrays)
    header = {"patch_size": patch, "output_units": "gaussian", "normalization": "contrast",
              "meta": meta or {}}
    np.savez(path, format_version=np.array(FORMAT_VERSION), header=np.array(json.dumps(header)),
             **entries)
    return path


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    """Generated once: good frames, and bad files beside them."""
    root = tmp_path_factory.mktemp("corpus")
    big = _texture(H + 10, W + 20, seed=1)
    frames = root / "frames"
    frames.mkdir()
    for k in range(FRAMES):
        cv2.imwrite(str(frames / f"in{k + 1:06d}.png"),
                    cv2.cvtColor(big[5:5 + H, 2 * k:2 * k + W], cv2.COLOR_GRAY2BGR))
    good_png = (frames / "in000001.png").read_bytes()
    (root / "a.png").write_bytes(good_png)
    (root / "b.png").write_bytes((frames / "in000002.png").read_bytes())
    # A PNG whose compressed data is damaged: libpng prints "libpng error: ..." itself.
    (root / "corrupt.png").write_bytes(good_png[:60] + b"\0" * 50 + good_png[110:])
    (root / "truncated.png").write_bytes(good_png[: len(good_png) // 2])
    # Cut in its last chunk ("libpng error: Read Error"), or in its header (OpenCV's log line).
    (root / "truncated_end.png").write_bytes(good_png[:-20])
    (root / "truncated_header.png").write_bytes(good_png[:16])
    (root / "empty.png").write_bytes(b"")
    (root / "text.png").write_text("not an image\n")
    ok, jpeg = cv2.imencode(".jpg", big)
    (root / "truncated.jpg").write_bytes(jpeg.tobytes()[: len(jpeg) // 2])
    cv2.imwrite(str(root / "bright.tiff"), np.full((H, W), 3.0, np.float32))
    cv2.imwrite(str(root / "int32.tiff"), np.full((H, W), 7, np.int32))
    for name, data in (("empty.mkv", b""), ("noise.mp4", os.urandom(4096)),
                       ("text.avi", b"not a video\n" * 20)):
        (root / name).write_bytes(data)
    (root / "no_images").mkdir()
    (root / "no_images" / "notes.txt").write_text("no frames here\n")
    _models(root)
    _sequences(root)
    return root


def _sequences(root: Path) -> None:
    """CDnet sequences with a damaged ground-truth PNG (libpng prints its own error line) or a
    damaged ROI.bmp (OpenCV logs one), and masks to score against them."""
    damaged = write_input_sequence(root / "gt_corrupt", n_frames=3)
    gt = damaged / "groundtruth" / "gt000002.png"
    data = gt.read_bytes()
    gt.write_bytes(data[:60] + b"\0" * 50 + data[110:])
    roi = write_input_sequence(root / "roi_corrupt", n_frames=3,
                               roi=np.full((48, 64), 255, np.uint8))
    (roi / "ROI.bmp").write_bytes((roi / "ROI.bmp").read_bytes()[:40])
    write_bins(root / "preds", {k: np.zeros((48, 64), np.uint8) for k in (1, 2, 3)})


def _models(root: Path) -> None:
    _model_file(root / "patch2.npz", patch=2)
    _model_file(root / "patch1.npz", patch=1)
    _model_file(root / "no_factors.npz", factors=0)
    _model_file(root / "no_hidden.npz", hidden=0)
    _model_file(root / "huge_range.npz", meta={"max_shift": 1e9})
    _model_file(root / "negative_range.npz", meta={"max_shift": -3})
    _model_file(root / "text_range.npz", meta={"max_disp": "four"})
    _model_file(root / "nan_weights.npz", wxf=np.full((169, 8), np.nan, np.float32))
    good = (root / "patch2.npz").read_bytes()
    (root / "truncated.npz").write_bytes(good[: len(good) // 2])
    (root / "text.npz").write_text("not a model\n")
    np.save(root / "array.npy", np.zeros(3))
    np.savez(root / "objects.npz", wxf=np.array([{"a": 1}], dtype=object))


# (argv with {c} for the corpus folder and {t} for this test's own folder, words the line
# must hold). Outputs go to {t} so that no case sees another's.
CASES = [
    # images
    (["flow", "{c}/corrupt.png", "{c}/b.png", "-o", "{t}/f.flo"], "corrupt.png"),
    (["flow", "{c}/truncated.png", "{c}/b.png", "-o", "{t}/f.flo"], "truncated.png"),
    (["flow", "{c}/empty.png", "{c}/b.png", "-o", "{t}/f.flo"], "empty.png"),
    (["flow", "{c}/text.png", "{c}/b.png", "-o", "{t}/f.flo"], "text.png"),
    (["flow", "{c}/truncated.jpg", "{c}/b.png", "-o", "{t}/f.flo"], "truncated.jpg"),
    (["flow", "{c}/bright.tiff", "{c}/bright.tiff", "-o", "{t}/f.flo"], "from 3 to 3"),
    (["flow", "{c}/int32.tiff", "{c}/int32.tiff", "-o", "{t}/f.flo"], "int32"),
    (["flow", "/dev/null", "{c}/b.png", "-o", "{t}/f.flo"], "not an image file"),
    (["flow", "{c}/a.png", "{c}/no_images", "-o", "{t}/f.flo"], "folder"),
    (["analogy", "{c}/truncated.png", "{c}/a.png", "{c}/b.png", "-o", "{t}/an.png"],
     "truncated.png"),
    (["analogy", "{c}/truncated_end.png", "{c}/a.png", "{c}/b.png", "-o", "{t}/an.png"],
     "truncated_end.png"),
    (["analogy", "{c}/a.png", "{c}/truncated_header.png", "{c}/b.png", "-o", "{t}/an.png"],
     "truncated_header.png"),
    # ground truth
    (["eval", "{c}/preds", "{c}/gt_corrupt"], "gt000002.png"),
    (["eval", "{c}/preds", "{c}/roi_corrupt"], "ROI.bmp"),
    (["compare", "{c}/roi_corrupt", "-o", "{t}/cmp", "-m", "mog2", "--no-video"], "ROI.bmp"),
    # videos and frame sources
    (["run", "{c}/empty.mkv", "-o", "{t}/m.mkv", "-m", "mog2"], "empty.mkv"),
    (["run", "{c}/noise.mp4", "-o", "{t}/m.mkv", "-m", "mog2"], "noise.mp4"),
    (["run", "{c}/text.avi", "-o", "{t}/m.mkv", "-m", "mog2"], "text.avi"),
    (["run", "/dev/null", "-o", "{t}/m.mkv", "-m", "mog2"], "not a video device"),
    (["run", "/dev/zero", "-o", "{t}/m.mkv", "-m", "mog2"], "not a video device"),
    (["run", "{c}/no_images", "-o", "{t}/m.mkv", "-m", "mog2"], "holds no images"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "--step", "0"], "step"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "--start", "99"], "past the end"),
    (["compare", "{c}/frames", "-o", "{t}/cmp", "--max-frames", "12", "--step", "0",
      "-m", "framediff"], "step must be at least 1"),
    # models
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/patch2.npz"],
     "at least 3"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/patch1.npz"],
     "at least 3"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-p", "model={c}/patch2.npz"], "at least 3"),
    (["analogy", "{c}/a.png", "{c}/b.png", "{c}/a.png", "-o", "{t}/an.png", "--model",
      "{c}/patch2.npz"], "at least 3"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/no_factors.npz"],
     "factor"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/no_hidden.npz"],
     "mapping unit"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/huge_range.npz"],
     "max_shift"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-p", "model={c}/negative_range.npz"],
     "max_shift"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/text_range.npz"],
     "max_disp"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/nan_weights.npz"],
     "non-finite"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/truncated.npz"],
     "truncated.npz"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/text.npz"],
     "text.npz"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/array.npy"],
     "array.npy"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "{c}/objects.npz"],
     "pickle"),
    # parameters
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "-p", "n_mixtures=256"],
     "n_mixtures"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "knn", "-p", "n_samples=0"], "n_samples"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "-p", "history=-1"], "history"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "-p", "var_threshold=nan"],
     "var_threshold"),
    (["run", "{c}/frames", "-o", "{t}/m.mkv", "-m", "mog2", "-p", "colour=1"], "colour"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--stride", "0"], "--stride"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--max-motion", "nan"],
     "--max-motion"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--model", "dots-translation",
      "--levels", "2"], "--levels"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.flo", "--readout", "max-flow",
      "--stride", "14"], "--stride 14"),
    (["train", "--data", "dots-translation", "--patch-size", "1000", "-o", "{t}/m.npz"], "GiB"),
    (["train", "--data", "dots-translation", "--patch-size", "2", "-o", "{t}/m.npz"],
     "--patch-size"),
    # output paths
    (["run", "{c}/frames", "-o", "{t}/" + LONG_NAME + ".mkv", "-m", "mog2"], "too long"),
    (["run", "{c}/frames", "-o", "{t}/" + LONG_NAME, "-m", "mog2"], "too long"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/" + LONG_NAME + ".flo"], "too long"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{t}/f.txt"], ".flo"),
    (["flow", "{c}/a.png", "{c}/b.png", "-o", "{c}/a.png"], "a.png"),
    (["run", "{c}/frames", "-o", "-", "-m", "mog2"], "stdout"),
    (["run", "{c}/frames", "-o", "{t}/m.xyz", "-m", "mog2"], "m.xyz"),
    (["run", "{c}/frames", "-o", "{c}/a.png/m.mkv", "-m", "mog2"], "a.png"),
]


@pytest.mark.parametrize("argv, words", CASES, ids=[" ".join(c[0])[:60] for c in CASES])
def test_refused_in_one_line(corpus, tmp_path, capfd, argv, words):
    argv = [a.format(c=corpus, t=tmp_path) for a in argv]
    assert words in one_error_line(argv, capfd)
    assert not [p for p in tmp_path.iterdir() if p.name != "cmp"]  # nothing half-written


def test_damaged_ground_truth_in_compare_gives_no_native_log_line(corpus, tmp_path, capfd):
    # The outputs written before the damaged frame are reported too, each in a bgsub line.
    assert main(["compare", str(corpus / "gt_corrupt"), "-o", str(tmp_path / "cmp"), "-m",
                 "mog2"]) == 2
    lines = capfd.readouterr().err.splitlines()
    assert all(line.startswith("bgsub: ") for line in lines), lines
    assert [line for line in lines if line.startswith("bgsub: error:")] == [
        f"bgsub: error: cannot read ground-truth image {corpus}/gt_corrupt/groundtruth/"
        "gt000002.png"]


def _bgsub(*argv) -> subprocess.CompletedProcess:
    """``bgsub`` in a process of its own: OpenCV crashes there would end this one."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    return subprocess.run([sys.executable, "-m", "bgsub", *map(str, argv)], env=env,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("n_samples", [100_000, 60_000])
def test_a_knn_model_beyond_what_opencv_can_size_is_refused(corpus, tmp_path, n_samples):
    # 64x48 colour frames: OpenCV's C int holds at most 58254 samples per pixel; 100000 wraps
    # round (OpenCV then crashes: SIGSEGV), 60000 asks for exabytes.
    out = tmp_path / "k.mkv"
    done = _bgsub("run", corpus / "frames", "-o", out, "-m", "knn", "-p", f"n_samples={n_samples}",
                  "-q")
    assert done.returncode == 2, done.stderr
    assert done.stderr == (f"bgsub: error: knn: n_samples={n_samples} needs a "
                           f"{W * H * n_samples * 12 / 2**30:.1f} GiB model for {W}x{H} colour "
                           "frames, above the 2 GiB a background model may take: give n_samples "
                           "at most 58254 for frames of this size, or smaller frames\n")
    assert list(tmp_path.iterdir()) == []


def test_a_float_tiff_is_read_as_gray_levels(corpus, tmp_path, capfd):
    # A valid 32-bit float image in [0, 1] gives the flow of its 8-bit version.
    gray = [cv2.imread(str(corpus / n), cv2.IMREAD_GRAYSCALE) for n in ("a.png", "b.png")]
    for k, image in enumerate(gray):
        cv2.imwrite(str(tmp_path / f"{k}.tiff"), image.astype(np.float32) / 255)
        cv2.imwrite(str(tmp_path / f"{k}.png"), image)
    for ext in ("tiff", "png"):
        assert main(["flow", str(tmp_path / f"0.{ext}"), str(tmp_path / f"1.{ext}"), "-o",
                     str(tmp_path / f"{ext}.flo"), "-q", "--max-motion", "3"]) == 0
    assert capfd.readouterr().err == ""
    np.testing.assert_array_equal(read_flo(tmp_path / "tiff.flo"), read_flo(tmp_path / "png.flo"))


def test_shipped_models_pass_the_loader_checks():
    for name in ("natural", "dots-translation", "dots-translation-3px", "dots-rotation"):
        assert load_model(name).patch_size == 13
