"""``--preset NAME`` on the command line: each preset runs end to end, a batch records it, the
refusal of an unknown one is one line, and ``bgsub methods`` and ``bgsub bench --presets`` show
the presets."""

from __future__ import annotations

import json

import pytest
from helpers import batch_results, read_frames, write_box_clip, write_pan_clip

from bgsub.cli import main
from bgsub.evaluation.metrics import Counts, count_frame
from bgsub.samples import SceneSpec, render_frames

PAN = SceneSpec("pan", seed=0, width=320, height=240, n_frames=30)


@pytest.fixture(scope="module")
def pan_clip(tmp_path_factory):
    return write_pan_clip(tmp_path_factory.mktemp("pan") / "pan.avi", seed=PAN.seed,
                          n=PAN.n_frames, width=PAN.width, height=PAN.height)


@pytest.fixture
def made_engines(monkeypatch):
    """The engines ``bgsub run`` makes, in order."""
    from bgsub import engines

    made = []

    def create_engine(*args, **params):
        made.append(engines.base.create_engine(*args, **params))
        return made[-1]

    monkeypatch.setattr(engines, "create_engine", create_engine)
    return made


def _f_measure(masks, scene: SceneSpec) -> float:
    """F of ``masks`` (BGR frames of a mask video) against the scene's ground truth, over the
    frames the scene's temporal ROI scores."""
    truth = [frame.groundtruth for frame in render_frames(scene)]
    counts = Counts()
    for mask, labels in list(zip(masks, truth))[scene.roi_start - 1:]:
        counts += count_frame(mask[:, :, 0], labels)
    return counts.metrics().f_measure


@pytest.mark.parametrize("preset", ["fast", "balanced", "accurate"])
def test_each_preset_runs_end_to_end_and_finds_the_objects(preset, pan_clip, tmp_path):
    out = tmp_path / "masks.mkv"
    assert main(["run", str(pan_clip), "-o", str(out), "--preset", preset, "-q"]) == 0
    masks = read_frames(out)
    assert len(masks) == PAN.n_frames
    assert _f_measure(masks, PAN) > 0.5


def test_param_and_config_override_the_preset(pan_clip, tmp_path, made_engines):
    config = tmp_path / "settings.toml"
    config.write_text("work_width = 200\nedge_radius = 4\n")
    assert main(["run", str(pan_clip), "-o", str(tmp_path / "m.mkv"), "--preset", "fast",
                 "--config", str(config), "-p", "edge_radius=6", "--max-frames", "2", "-q"]) == 0
    assert (made_engines[-1].config.work_width, made_engines[-1].config.edge_radius) == (200, 6)


@pytest.mark.parametrize("given, width", [([], 160), (["--preset", "balanced"], 320)])
def test_a_config_file_names_the_preset_and_preset_overrides_it(given, width, pan_clip,
                                                                 tmp_path, made_engines):
    config = tmp_path / "settings.toml"
    config.write_text('preset = "fast"\nedge_radius = 6\n')
    assert main(["run", str(pan_clip), "-o", str(tmp_path / "m.mkv"), "--config", str(config),
                 "--max-frames", "2", "-q"] + given) == 0
    assert (made_engines[-1].config.work_width, made_engines[-1].config.edge_radius) == (width, 6)


@pytest.mark.parametrize("text, method, message", [
    ('preset = "fsat"', "grbm", "key 'preset': unknown preset 'fsat' for grbm; did you mean"),
    ("preset = 3", "grbm", "key 'preset': takes a preset name in quotes"),
    ('preset = "fast"', "mog2", "key 'preset': method 'mog2' has no presets"),
])
def test_a_bad_preset_in_a_config_file_is_one_error_line(text, method, message, tmp_path,
                                                         bgsub_error):
    config = tmp_path / "settings.toml"
    config.write_text(text + "\n")
    err = bgsub_error(["run", "missing.avi", "-o", "masks.mkv", "-m", method,
                       "--config", config])
    assert f"{config}: {message}" in err


@pytest.mark.parametrize("command", [
    ["run", "missing.avi", "-o", "masks.mkv"],
    ["compare", "missing.avi", "-o", "report", "-m", "grbm,mog2"],
    ["bench", "-m", "grbm"],
])
def test_an_unknown_preset_is_one_error_line(command, bgsub_error):
    err = bgsub_error(command + ["--preset", "fsat"])
    assert "unknown preset 'fsat' for grbm; did you mean 'fast'?" in err


def test_a_preset_for_a_method_without_presets_is_one_error_line(bgsub_error):
    err = bgsub_error(["run", "missing.avi", "-o", "masks.mkv", "-m", "mog2", "--preset", "fast"])
    assert "method 'mog2' has no presets" in err


def test_a_batch_rerun_with_another_preset_is_made_with_other_settings(tmp_path, capsys):
    clips = tmp_path / "clips"
    clips.mkdir()
    for k in range(2):
        write_box_clip(clips / f"v{k}.mkv", seed=k, n=3)
    argv = ["run", str(clips), "-o", str(tmp_path / "out"), "--jobs", "1"]
    assert batch_results(capsys, argv + ["--preset", "fast"]) == [("done", "")] * 2
    assert batch_results(capsys, argv + ["--preset", "fast"]) == [("skipped", "")] * 2
    reason = "made with other settings (preset fast -> accurate): --overwrite redoes it"
    assert batch_results(capsys, argv + ["--preset", "accurate"]) == [("skipped", reason)] * 2


def test_methods_lists_each_preset_with_its_values(capsys):
    assert main(["methods", "grbm"]) == 0
    lines = capsys.readouterr().out.splitlines()
    start = lines.index("  presets (--preset NAME; -p overrides their values):")
    assert [line.split() for line in lines[start + 1:start + 4]] == [
        ["fast", "work_width=160,", "stride=16,", "overlay=0,", "edge_radius=4,",
         "ransac_threshold=0.5,", "violation_threshold=0.375,", "overlap=0,",
         "still_pause=1,", "flow_boost=1.0,", "grow_above=0.8,",
         "lookback=45"],
        ["balanced", "the", "defaults"],
        ["accurate", "edge_step=1,", "colour_cut=9"]]


def test_methods_json_holds_the_presets(capsys):
    assert main(["methods", "grbm", "--json"]) == 0
    entry = json.loads(capsys.readouterr().out)[0]
    assert entry["presets"] == {"fast": {"work_width": 160, "stride": 16, "overlay": 0,
                                         "edge_radius": 4, "ransac_threshold": 0.5,
                                         "violation_threshold": 0.375, "overlap": 0,
                                         "still_pause": 1, "flow_boost": 1.0,
                                         "grow_above": 0.8, "lookback": 45},
                                "balanced": {}, "accurate": {"edge_step": 1,
                                                                "colour_cut": 9}}


def test_methods_shows_no_presets_for_an_engine_without_them(capsys):
    assert main(["methods", "mog2"]) == 0
    assert "presets" not in capsys.readouterr().out


def _row(out: str, preset: str) -> list:
    return next(line.split() for line in out.splitlines() if line.startswith(f"{preset} "))


def test_bench_presets_prints_one_row_per_preset(capsys):
    assert main(["bench", "--presets", "--max-frames", "5", "--repeats", "1", "-q"]) == 0
    out = capsys.readouterr().out
    for preset in ("fast", "balanced", "accurate"):
        fps, ratio, real, generated = _row(out, preset)[1:5]
        assert float(fps) > 0 and float(ratio) > 0
        assert (real, generated) == ("-", "-")  # no --accuracy file


def test_bench_presets_reads_the_f_of_each_preset_from_accuracy_files(tmp_path, capsys):
    files = []
    for preset, which, mean in (("fast", "real", 0.5), (None, "generated", 0.75)):
        path = tmp_path / f"{preset}_{which}.json"
        path.write_text(json.dumps({"args": {"set": which, "preset": preset}, "mean": mean}))
        files += ["--accuracy", str(path)]
    assert main(["bench", "--presets", "--max-frames", "2", "--repeats", "1", "-q"] + files) == 0
    out = capsys.readouterr().out
    assert _row(out, "fast")[3:5] == ["0.500", "-"]
    assert _row(out, "balanced")[3:5] == ["-", "0.750"]


def test_bench_presets_refuses_a_file_that_is_no_accuracy_record(tmp_path, bgsub_error):
    path = tmp_path / "other.json"
    path.write_text("{}")
    err = bgsub_error(["bench", "--presets", "--accuracy", str(path)])
    assert "not a benchmarks/accuracy.py --json file" in err
