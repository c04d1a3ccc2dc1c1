"""The benchmark commands that name the library's functions keep up with it: a renamed stage
would make ``benchmarks/profile_stages.py`` fail (or time nothing)."""

from __future__ import annotations

import argparse
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


def _accuracy_module():
    spec = importlib.util.spec_from_file_location("accuracy_script", ACCURACY)
    accuracy = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(accuracy)
    return accuracy


@pytest.mark.skipif(not ACCURACY.exists(), reason="benchmarks/ is not part of an installed package")
def test_accuracy_renders_the_sample_seeds_it_is_given():
    accuracy = _accuracy_module()
    tuned = accuracy.sequences("samples", "all")
    fresh = accuracy.sequences("samples", "all", (3, 4, 5))
    assert {m.split(":")[1] for _, m in tuned} == {"0", "1", "2"}
    assert {m.split(":")[1] for _, m in fresh} == {"3", "4", "5"}
    assert {f for f, _ in fresh} == {f for f, _ in tuned}
    # Halves alternate within each category, as for the tuned seeds.
    assert {m.split(":")[1] for _, m in accuracy.sequences("samples", "B", (3, 4, 5))} == {"4"}


@pytest.mark.skipif(not ACCURACY.exists(), reason="benchmarks/ is not part of an installed package")
def test_accuracy_keeps_the_generated_scenes_of_a_number_range(tmp_path):
    accuracy = _accuracy_module()
    for category in ("follow", "overlay"):
        for number in (1, 12, 13, 24):
            (tmp_path / category / f"{category}_{number:02d}").mkdir(parents=True)
    kept = accuracy.sequences("generated", "all", root=tmp_path, numbers=(13, 24))
    assert sorted(Path(m).name for _, m in kept) == ["follow_13", "follow_24", "overlay_13",
                                                     "overlay_24"]
    assert len(accuracy.sequences("generated", "all", root=tmp_path)) == 8
    with pytest.raises(argparse.ArgumentTypeError, match="FIRST-LAST"):
        accuracy.parse_range("24-13")


CHART = SCRIPT.with_name("speed_chart.py")


def _chart_module():
    spec = importlib.util.spec_from_file_location("speed_chart_script", CHART)
    chart = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = chart  # its dataclass looks its module up
    spec.loader.exec_module(chart)
    return chart


def _chart_inputs(folder):
    """Made-up timing (in the library's own report formats) and accuracy files; returns the
    arguments of ``speed_chart.py`` and ``{point label: (x MOG2, F)}``."""
    import json

    from bgsub.evaluation.bench import BenchReport, BenchResult, machine_info
    from bgsub.evaluation.bench_presets import PresetReport, PresetResult

    def clip():
        return BenchReport(width=320, height=240, frames=5, repeats=1, clip="made up",
                           machine=machine_info())

    def presets(fast_fps):
        return PresetReport("grbm", clip(), [PresetResult("fast", {}, fast_fps, 450.0),
                                             PresetResult("balanced", {}, 90.0, 450.0),
                                             PresetResult("accurate", {}, 30.0, 450.0)])

    methods = clip()
    methods.results = [BenchResult(m, fps, [fps], 1000 / fps)
                       for m, fps in (("mog2", 460.0), ("knn", 300.0), ("compensated", 92.0))]
    timing = [folder / "presets.json", folder / "methods.json", folder / "presets2.json",
              folder / "presets3.json"]  # three runs of the presets: fast 0.4x, 0.6x, 0.5x
    for path, report in zip(timing, (presets(180.0), methods, presets(270.0), presets(225.0))):
        path.write_text(json.dumps(report.to_dict()))
    scores = {("grbm", "fast"): 0.62, ("grbm", None): 0.69, ("mog2", None): 0.21,
              ("knn", None): 0.18, ("compensated", None): 0.45}
    accuracy = []
    for (method, preset), mean in scores.items():
        path = folder / f"{method}_{preset}.json"
        path.write_text(json.dumps({"args": {"set": "real", "half": "all", "method": method,
                                             "preset": preset}, "mean": mean}))
        accuracy.append(str(path))
    made_with_p = folder / "accurate.json"  # -p values, no --preset: named by KEY=
    made_with_p.write_text(json.dumps({"args": {"set": "real", "half": "all", "method": "grbm",
                                                "param": ["work_width=480"]}, "mean": 0.70}))
    accuracy.append(f"grbm:accurate={made_with_p}")
    expected = {"grbm fast": (0.5, 0.62),  # the median of the three runs "grbm balanced": (0.2, 0.69),
                "grbm accurate": (30 / 450, 0.70), "mog2": (1.0, 0.21),
                "knn": (300 / 460, 0.18), "compensated": (92 / 460, 0.45)}
    return ["--timing", *map(str, timing), "--accuracy", *accuracy], expected


@pytest.mark.skipif(not CHART.exists(), reason="benchmarks/ is not part of an installed package")
def test_speed_chart_draws_every_point_where_its_figures_put_it(tmp_path, capsys):
    import cv2

    chart = _chart_module()
    argv, expected = _chart_inputs(tmp_path)
    out = tmp_path / "chart.png"
    assert chart.main([*argv, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    img = cv2.imread(str(out))
    assert img.shape == (chart.HEIGHT, chart.WIDTH, 3)
    assert (img < 250).any(axis=2).mean() > 0.02  # axes, grid, dots and labels, not a blank page
    xr = chart.x_range([ratio for ratio, _ in expected.values()])
    for label, (ratio, f) in expected.items():
        assert f"{label} " in printed and f"{ratio:.2f}x MOG2   F {f:.3f}" in printed, printed
        x, y = chart.to_pixel(ratio, f, xr)
        dot = img[y - 3:y + 4, x - 3:x + 4].reshape(-1, 3)
        # each dot is filled with one saturated colour, not white, not grey
        assert (dot == dot[0]).all() and int(dot[0].max()) - int(dot[0].min()) > 60, label


@pytest.mark.skipif(not CHART.exists(), reason="benchmarks/ is not part of an installed package")
def test_speed_chart_refuses_timing_without_mog2(tmp_path, capsys):
    import json

    chart = _chart_module()
    argv, _ = _chart_inputs(tmp_path)
    methods = json.loads((tmp_path / "methods.json").read_text())
    methods["results"] = [r for r in methods["results"] if r["method"] != "mog2"]
    (tmp_path / "methods.json").write_text(json.dumps(methods))
    out = tmp_path / "chart.png"
    assert chart.main([*argv, "-o", str(out)]) == 2
    assert "mog2 was not timed" in capsys.readouterr().err
    assert not out.exists()
