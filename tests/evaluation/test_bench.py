"""`bgsub bench` and bgsub.evaluation.bench: engine speed on a generated clip (no timing thresholds)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from bgsub.evaluation.bench import TIMING_NOTE, bench_methods, machine_info, make_clip
from bgsub.cli import main
from bgsub.errors import InputError


def test_bench_reports_positive_fps_per_method() -> None:
    report = bench_methods(methods=["framediff", "mog2"], width=64, height=48, frames=2,
                           repeats=2)
    assert [r.method for r in report.results] == ["framediff", "mog2"]
    for result in report.results:
        assert len(result.fps_runs) == 2
        assert all(f > 0 for f in result.fps_runs)
        assert result.fps == pytest.approx(float(np.median(result.fps_runs)))
        assert result.ms_per_frame == pytest.approx(1000.0 / result.fps)
        assert result.peak_rss_mib is None  # not asked for
    text = report.to_text()
    assert "decoding and writing are excluded" in text
    assert "framediff" in text and "mog2" in text


def test_machine_is_described() -> None:
    info = machine_info()
    assert info.cpu and info.logical_cores >= 1 and 1 <= info.usable_cores <= info.logical_cores
    assert info.numpy == np.__version__
    assert info.date.endswith("+00:00")
    text = info.to_text()
    assert info.cpu in text and "OpenCV" in text and "BLAS" in text


def test_cli_json(capsys) -> None:
    code = main(["bench", "--size", "64x48", "--max-frames", "2", "--repeats", "1", "--methods",
                 "framediff", "--json", "-q"])
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert (data["width"], data["height"], data["frames"]) == (64, 48, 2)
    assert data["note"] == TIMING_NOTE
    (result,) = data["results"]
    assert result["method"] == "framediff" and result["fps"] > 0
    assert data["machine"]["logical_cores"] >= 1


def test_memory_is_measured_per_method() -> None:
    report = bench_methods(methods=["framediff"], width=64, height=48, frames=2, repeats=1,
                           memory=True)
    (result,) = report.results
    assert result.peak_rss_mib is not None and result.peak_rss_mib > 0
    assert "peak RSS" in report.to_text()


def test_memory_of_a_thread_limited_engine_does_not_hang() -> None:
    # compensated limits OpenCV's threads every frame; a child forked from a parent whose
    # OpenCV pool had started waited forever in cv2.setNumThreads. The subprocess's timeout
    # turns such a hang into a failure; `python -m bgsub` also checks that the spawned
    # children do not re-run the command.
    done = subprocess.run(
        [sys.executable, "-m", "bgsub", "bench", "-m", "compensated", "--size", "64x48",
         "--max-frames", "2", "--repeats", "1", "--memory", "--json"],
        capture_output=True, text=True, timeout=90)
    assert done.returncode == 0, done.stderr
    (result,) = json.loads(done.stdout)["results"]
    assert result["method"] == "compensated" and result["peak_rss_mib"] > 0


def test_clip_shape_and_fallback_for_tiny_sizes() -> None:
    frames, description = make_clip(width=32, height=24, n_frames=3)
    assert frames.shape == (3, 24, 32, 3) and frames.dtype == np.uint8
    assert "panning random texture" in description  # below the scenes' minimum size
    assert not np.array_equal(frames[0], frames[1])  # the camera moves
    frames, _ = make_clip(width=64, height=48, n_frames=3)
    assert frames.shape == (3, 48, 64, 3)


@pytest.mark.parametrize("argv, message", [
    (["bench", "--size", "64by48"], "--size"),
    (["bench", "--methods", "nosuch"], "unknown method"),
    (["bench", "--methods", "framediff", "--max-frames", "0"], "at least 1"),
    (["bench", "--methods", "framediff", "--param", "framediff.nosuch=1"], "no parameter"),
])
def test_bad_options_exit_2(capsys, argv, message) -> None:
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_api_rejects_params_for_other_methods() -> None:
    with pytest.raises(InputError):
        bench_methods(methods=["framediff"], params={"mog2": {"history": 10}}, frames=1,
                      repeats=1, width=64, height=48)


@pytest.mark.parametrize("value", ["", " , "])
def test_cli_empty_methods_is_refused_not_all(bgsub_error, value) -> None:
    # As in `bgsub compare`: an empty list is a mistake, not "every engine".
    assert "--methods is empty" in bgsub_error(["bench", "--methods", value, "--max-frames", "1"])


def test_odd_sizes_are_benchmarked(capsys) -> None:
    # Nothing is written, so nothing needs even sizes: "even (video codecs need it)" was wrong.
    assert main(["bench", "--size", "161x121", "--max-frames", "1", "--repeats", "1", "--methods",
                 "framediff", "-q"]) == 0
    assert "bgsub bench: 1 frame of 161x121, 1 run per method" in capsys.readouterr().out
    frames, description = make_clip(width=65, height=49, n_frames=2)
    assert frames.shape == (2, 49, 65, 3) and "'pan' scene" in description


def test_too_small_size_says_what_bench_renders(bgsub_error) -> None:
    err = bgsub_error(["bench", "--size", "15x40", "--methods", "framediff"])
    assert "at least 16x16; below 64x48, the smallest sample scene, the clip is a panning" in err


@pytest.mark.parametrize("count, noun", [(1, "1 thread"), (2, "2 threads")])
def test_machine_description_counts_in_singular_and_plural(count, noun) -> None:
    from dataclasses import replace

    info = replace(machine_info(), logical_cores=count, usable_cores=count, blas_threads=count,
                   opencv_threads=count)
    text = info.to_text()
    core = "1 logical core (1 usable)" if count == 1 else "2 logical cores (2 usable)"
    assert core in text
    assert f"({noun})" in text and f", {noun})" in text  # OpenCV's and BLAS's
    assert "(1 threads)" not in text and ", 1 threads" not in text
