"""The error corpus of ``bgsub run``'s options: live inputs (URL, camera, device),
``--stall-timeout``, ``--roi``, ``--motion-in``, ``--objects``, ``--stats``, ``--config``,
``--json``, batches, reruns and ``--scheduler``. Each case is refused with exit status 2 and exactly one
``bgsub: error:`` line, before anything is written: no file of the corpus changes (an input
named as an output is refused, ``--overwrite`` or not) and nothing is created."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from helpers import one_error_line, write_box_clip

W, H, N = 64, 48, 12


def _motions(root: Path) -> None:
    still = np.repeat(np.eye(3)[None], N, axis=0)
    np.save(root / "m.npy", still)
    absurd = still.copy()
    absurd[3, 0, 2] = 1e12  # 1e12 px to the right between frames 2 and 3
    np.save(root / "absurd.npy", absurd)
    np.save(root / "flat.npy", np.zeros((N, 2, 3)))
    np.savez(root / "archive.npz", motion=still)
    (root / "text.npy").write_text("0 0 0\n")
    (root / "pickled.npy").write_bytes(b"\x93NUMPY\x01\x00v\x00{'descr': '|O', 'fortran_order': "
                                       b"False, 'shape': (1,), }" + b" " * 57 + b"\n"
                                       + pickle.dumps([{"a": 1}]))


def _regions_and_configs(root: Path) -> None:
    cv2.imwrite(str(root / "roi.png"), np.full((H, W), 255, np.uint8))
    cv2.imwrite(str(root / "wide.png"), np.full((10, 100), 255, np.uint8))
    (root / "notimage.png").write_text("not an image\n")
    (root / "good.toml").write_text("history = 100\n")
    (root / "badvalue.toml").write_text("history = 'abc'\n")
    (root / "broken.toml").write_text("history = = 3\n")
    (root / "unknown.toml").write_text("histry = 100\n")
    (root / "summary.json").write_text("{}\n")
    (root / "configs").mkdir()
    (root / "configs" / "v0.csv").write_text("history = 100\n")  # where --stats puts v0's


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    """A clip, a folder of two videos, an input named like a batch's record folder, motion
    files, regions of interest and configuration files, good and bad."""
    root = tmp_path_factory.mktemp("options")
    write_box_clip(root / "clip.mkv", n=N, width=W, height=H)
    (root / "vids").mkdir()
    for k in range(2):
        write_box_clip(root / "vids" / f"v{k}.mkv", seed=k, n=N, width=W, height=H)
    (root / "odd").mkdir()
    write_box_clip(root / "odd" / ".bgsub-batch.mkv", n=N, width=W, height=H)
    _motions(root)
    _regions_and_configs(root)
    return root


RUN = ["run", "{c}/clip.mkv", "-o", "{t}/m.mkv"]
BATCH = ["run", "{c}/vids", "-o", "{t}/b", "-m", "mog2"]

# (argv with {c} for the corpus folder and {t} for this test's own folder, words the line
# must hold).
CASES = [
    # live inputs (those FFmpeg opens are in LIVE_CASES)
    (["run", "7", "-o", "{t}/m.mkv", "-m", "mog2"], "camera 7"),
    (["run", "/dev/video9", "-o", "{t}/m.mkv", "-m", "mog2"], "/dev/video9"),
    (["run", "7", "-o", "{t}/m.mkv", "-m", "mog2", "--objects", "{t}/o.csv", "--json"],
     "camera 7"),
    # --stall-timeout
    (RUN + ["-m", "mog2", "--stall-timeout", "0"], "stall timeout"),
    (RUN + ["-m", "mog2", "--stall-timeout", "nan"], "stall timeout"),
    (RUN + ["-m", "mog2", "--stall-timeout", "-1"], "stall timeout"),
    # --roi
    (RUN + ["--roi", "{c}/wide.png"], "aspect ratio"),
    (RUN + ["--roi", "{c}/notimage.png"], "not an image"),
    (RUN + ["--roi", "{c}/missing.png"], "no such file"),
    (RUN + ["-m", "mog2", "--roi", "{c}/roi.png", "-p", "roi={c}/roi.png"], "both set it"),
    (RUN + ["--roi", "{c}/roi.png", "--vis", "{c}/roi.png", "--overwrite"],
     "--vis would overwrite an input"),
    (["run", "{c}/clip.mkv", "-o", "{c}/roi.png", "-p", "roi={c}/roi.png", "--overwrite"],
     "-o would overwrite an input"),
    # --motion-in
    (RUN + ["--motion-in", "{c}/text.npy"], "not an .npy file; the known camera motion is an "
                                            "(N, 3, 3) float array"),
    (RUN + ["--motion-in", "{c}/archive.npz"], "an .npz archive; the known camera motion"),
    (RUN + ["--motion-in", "{c}/pickled.npy"], "without pickled objects"),
    (RUN + ["--motion-in", "{c}/flat.npy"], "(N, 3, 3) array"),
    (RUN + ["--motion-in", "{c}/absurd.npy"], "entry 3 moves a corner of the 64x48 frame by "
                                              "1e+12 px, more than the frame's size"),
    (RUN + ["--motion-in", "{c}/missing.npy"], "no such file"),
    (RUN + ["--motion-in", "{c}/vids"], "is a folder"),
    (RUN + ["-m", "mog2", "--motion-in", "{c}/m.npy"], "has no known_motion"),
    (RUN + ["--motion-in", "{c}/m.npy", "--motion", "{c}/m.npy", "--overwrite"],
     "--motion would overwrite an input"),
    # --objects
    (RUN + ["-m", "mog2", "--objects", "{t}/o.txt"], ".jsonl"),
    (RUN + ["-m", "mog2", "--objects", "{t}/o.jsonl", "--min-object-area", "-1"],
     "--min-object-area"),
    (RUN + ["-m", "mog2", "--min-object-area", "5"], "--min-object-area needs --objects"),
    (RUN + ["-m", "mog2", "--objects", "{c}/good.toml", "--config", "{c}/good.toml",
            "--overwrite"], "--objects would overwrite an input"),
    # --stats
    (RUN + ["-m", "mog2", "--stats", "{c}/good.toml", "--config", "{c}/good.toml",
            "--overwrite"], "--stats would overwrite an input"),
    (RUN + ["-m", "mog2", "--stats", "{c}/clip.mkv", "--overwrite"],
     "--stats would overwrite an input"),
    # --config
    (RUN + ["-m", "mog2", "--config", "{c}/badvalue.toml"], "takes an integer"),
    (RUN + ["--config", "{c}/broken.toml"], "not valid TOML"),
    (RUN + ["-m", "mog2", "--config", "{c}/unknown.toml"], "histry"),
    (RUN + ["--config", "{c}/missing.toml"], "no such file"),
    (RUN + ["-m", "mog2", "--config", "{c}/good.toml", "--vis", "{c}/good.toml",
            "--overwrite"], "--vis would overwrite an input"),
    # --json
    (["run", "{c}/clip.mkv", "-o", "-", "-m", "mog2", "--json"], "stdout"),
    # batch options on a single input: refused, not ignored
    (RUN + ["-m", "mog2", "-j", "0"], "--jobs is for several inputs"),
    (RUN + ["-m", "mog2", "-j", "2"], "--jobs is for several inputs"),
    (RUN + ["-m", "mog2", "-j", "-1"], "--jobs takes a number of inputs at once, or 0"),
    (RUN + ["-m", "mog2", "--mask-format", "png"], "--mask-format is for several inputs"),
    (RUN + ["-m", "mog2", "--summary", "{t}/s.json"], "--summary is for several inputs"),
    (RUN + ["-m", "mog2", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler is for several"),
    # batches
    (["run", "{c}/vids", "-o", "{c}/vids/", "-m", "mog2"], "is the folder of input videos"),
    (["run", "{c}/vids", "-o", "{c}/vids/", "-m", "mog2", "--overwrite"],
     "is the folder of input videos"),
    (BATCH + ["--vis", "{c}/vids"], "--vis is the folder of input videos"),
    (BATCH + ["--mask-format", "mp4", "--vis", "{t}/b"], "given to both -o and --vis"),
    (["run", "{c}/vids/v0.mkv", "{c}/odd/.bgsub-batch.mkv", "-o", "{t}/b", "-m", "mog2",
      "--mask-format", "png"], "the batch's own record folder"),
    (BATCH + ["--min-object-area", "5"], "--min-object-area needs --objects"),
    (BATCH + ["-j", "-1"], "--jobs takes a number of inputs at once, or 0"),
    (BATCH + ["--objects", "{t}/o.jsonl"], "--objects of several inputs is a folder"),
    (BATCH + ["--stats", "{t}/s.csv"], "--stats of several inputs is a folder"),
    (BATCH + ["--stats", "{c}/vids"], "--stats is the folder of input videos"),
    (BATCH + ["--objects", "{c}/vids"], "--objects is the folder of input videos"),
    (BATCH + ["--config", "{c}/configs/v0.csv", "--stats", "{c}/configs", "--overwrite"],
     "--stats would overwrite an input"),
    (["run", "{c}/vids", "-o", "{t}/b.mkv", "-m", "mog2"], "is a folder"),
    (["run", "{c}/vids", "-o", "{c}/summary.json", "-m", "mog2"], "must be a folder"),
    (["run", "{c}/vids", "-o", "{t}/b", "--motion-in", "{c}/m.npy"], "for a single input"),
    (BATCH + ["--summary", "{t}/nowhere/s.json"], "does not exist"),
    (BATCH + ["--summary", "{c}/vids/v0.mkv", "--overwrite"],
     "--summary would overwrite an input"),
    (BATCH + ["--config", "{c}/good.toml", "--summary", "{c}/good.toml", "--overwrite"],
     "--summary would overwrite an input"),
    # reruns: an existing summary is not replaced without --overwrite
    (BATCH + ["--summary", "{c}/summary.json"], "already exists"),
    # --scheduler (a Dask address that cannot be one; without Dask: the extra to install)
    (BATCH + ["--scheduler", "notanaddress"], "--scheduler"),
]


def _snapshot(*folders: Path) -> dict:
    return {path: (path.stat().st_size, path.stat().st_mtime_ns)
            for folder in folders for path in folder.rglob("*")}


@pytest.mark.parametrize("argv, words", CASES, ids=[" ".join(c[0])[:70] for c in CASES])
def test_refused_in_one_line_writing_nothing(corpus, tmp_path, capfd, argv, words):
    argv = [a.format(c=corpus, t=tmp_path) for a in argv]
    before = _snapshot(corpus)
    assert words in one_error_line(argv, capfd)
    assert _snapshot(corpus) == before  # no input replaced, nothing added
    assert list(tmp_path.iterdir()) == []  # nothing created


# Cases run as the console script in a process of their own: FFmpeg's own log level is set when
# bgsub first imports OpenCV's video reading, which this test process did before (its clips),
# and argparse ends the process itself.
LIVE_CASES = [
    (["run", "http://127.0.0.1:9/clip.mp4", "-o", "{t}/m.mkv", "-m", "mog2"], "cannot open it"),
    (["run", "rtsp://127.0.0.1:9/live", "-o", "{t}/m.mkv", "-m", "mog2", "--stall-timeout",
      "1"], "cannot open it"),
    (["run", "http://", "-o", "{t}/m.mkv", "-m", "mog2"], "http://"),
    (RUN + ["-m", "mog2", "--stall-timeout", "abc"], "--stall-timeout"),
]


@pytest.mark.parametrize("argv, words", LIVE_CASES, ids=[" ".join(c[0])[:70] for c in LIVE_CASES])
def test_refused_in_one_line_by_the_console_script(corpus, tmp_path, argv, words):
    argv = [a.format(c=corpus, t=tmp_path) for a in argv]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    done = subprocess.run([sys.executable, "-m", "bgsub", *argv], env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("bgsub: error:") and done.stderr.count("\n") == 1, done.stderr
    assert words in done.stderr
    assert list(tmp_path.iterdir()) == []
