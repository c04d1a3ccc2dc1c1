"""The benchmark commands that name the library's functions keep up with it: a renamed stage
would make ``benchmarks/profile_stages.py`` fail (or time nothing)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "profile_stages.py"


@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not part of an installed package")
def test_profile_stages_times_every_stage_it_names():
    done = subprocess.run([sys.executable, str(SCRIPT), "--frames", "3", "--size", "160x120"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    for stage in ("gRBM: projections onto the factors", "fusion: the frames' own evidence",
                  "fusion: flow-violation map", "front end: RANSAC fits"):
        row = next(line for line in done.stdout.splitlines() if line.startswith(f"| {stage} |"))
        assert float(row.split("|")[2]) > 0.0, row


@pytest.mark.skipif(not SCRIPT.exists(), reason="benchmarks/ is not part of an installed package")
def test_profile_stages_profiles_a_given_video(tmp_path):
    import cv2

    from bgsub.samples import SceneSpec, render_frames

    clip = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 25, (160, 120))
    for frame in render_frames(SceneSpec("pan", seed=1, width=160, height=120, n_frames=4)):
        writer.write(frame.image)
    writer.release()
    done = subprocess.run([sys.executable, str(SCRIPT), "--input", str(clip), "--frames", "3"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith(f"grbm, 160x120, overlap=0, 3 frames of {clip}")
