"""The benchmark commands that name the library's functions keep up with it: a renamed stage
would make ``benchmarks/profile_stages.py`` fail (or time nothing)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import write_pan_clip

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
    clip = write_pan_clip(tmp_path / "clip.avi", seed=1, n=4, width=160, height=120)
    done = subprocess.run([sys.executable, str(SCRIPT), "--input", str(clip), "--frames", "3"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith(f"grbm, 160x120, overlap=0, 3 frames of {clip}")
