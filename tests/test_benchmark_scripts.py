"""The benchmark commands that name the library's functions keep up with it: a renamed stage
would make ``benchmarks/profile_stages.py`` fail (or time nothing)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import write_pan_clip

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


ACCURACY = SCRIPT.with_name("accuracy.py")


@pytest.mark.skipif(not ACCURACY.exists(), reason="benchmarks/ is not part of an installed package")
def test_accuracy_renders_the_sample_seeds_it_is_given():
    spec = importlib.util.spec_from_file_location("accuracy_script", ACCURACY)
    accuracy = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(accuracy)
    tuned = accuracy.sequences("samples", "all")
    fresh = accuracy.sequences("samples", "all", (3, 4, 5))
    assert {m.split(":")[1] for _, m in tuned} == {"0", "1", "2"}
    assert {m.split(":")[1] for _, m in fresh} == {"3", "4", "5"}
    assert {f for f, _ in fresh} == {f for f, _ in tuned}
    # Halves alternate within each category, as for the tuned seeds.
    assert {m.split(":")[1] for _, m in accuracy.sequences("samples", "B", (3, 4, 5))} == {"4"}
