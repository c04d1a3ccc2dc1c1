"""The ``bgsub eval`` and ``bgsub methods`` commands."""

from __future__ import annotations

import csv
import io
import json
import re

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.engines import get_engine_spec
from bgsub.evaluation.cdnet import evaluate_sequence
from bgsub.samples import SceneSpec, generate_scene
from bgsub.io.sinks import open_mask_sink
from helpers import write_bins, write_gt_sequence

GT = np.array([[255, 255, 0, 0, 170]] * 4, np.uint8)  # 8 positives, 8 negatives, 4 ignored
PRED = np.array([[255, 0, 0, 0, 255]] * 4, np.uint8)  # TP 4, FN 4, TN 8


@pytest.fixture
def case(tmp_path):
    seq = write_gt_sequence(tmp_path / "seq", {1: GT, 2: GT})
    return write_bins(tmp_path / "pred", {1: PRED, 2: PRED}), seq


def test_eval_text_table(case, capsys):
    pred, seq = case
    assert main(["eval", str(pred), str(seq)]) == 0
    out = capsys.readouterr().out
    assert "F-measure" in out and "Recall" in out
    # Recall 0.5, precision 1, F = 2/3; TP 8 FN 8 TN 16 over both frames.
    assert "0.5000" in out and "0.6667" in out and "TP 8 FP 0 FN 8 TN 16" in out


def test_eval_json(case, capsys):
    pred, seq = case
    assert main(["eval", str(pred), str(seq), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    (only,) = report["sequences"]
    assert only["counts"] == {"tp": 8, "fp": 0, "fn": 8, "tn": 16}
    assert only["metrics"]["f_measure"] == pytest.approx(2 / 3)
    assert report["overall"]["recall"] == pytest.approx(0.5)


def test_eval_json_undefined_metric_is_null(case, capsys):
    pred, seq = case
    for png in pred.iterdir():
        cv2.imwrite(str(png), np.zeros_like(PRED))
    assert main(["eval", str(pred), str(seq), "--json"]) == 0
    metrics = json.loads(capsys.readouterr().out)["sequences"][0]["metrics"]
    assert metrics["precision"] is None and metrics["f_measure"] == 0.0


def test_eval_csv_file_and_stdout(case, tmp_path, capsys):
    pred, seq = case
    target = tmp_path / "scores.csv"
    assert main(["eval", str(pred), str(seq), "--csv", str(target), "--skip-first"]) == 0
    rows = list(csv.DictReader(io.StringIO(target.read_text())))
    assert [r["level"] for r in rows] == ["sequence", "category", "overall"]
    assert rows[0]["frames"] == "1" and rows[0]["tp"] == "4"
    assert float(rows[0]["recall"]) == pytest.approx(0.5)
    capsys.readouterr()
    assert main(["eval", str(pred), str(seq), "--csv", "-"]) == 0
    printed = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert printed[0]["tp"] == "8"


def test_eval_csv_not_overwritten(case, tmp_path, capsys):
    pred, seq = case
    target = tmp_path / "scores.csv"
    target.write_text("keep me")
    assert main(["eval", str(pred), str(seq), "--csv", str(target)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert target.read_text() == "keep me"


def test_eval_csv_given_a_folder_says_so(case, tmp_path, capsys):
    pred, seq = case
    assert main(["eval", str(pred), str(seq), "--csv", str(tmp_path), "--overwrite"]) == 2
    assert "is a folder; give a file name" in capsys.readouterr().err


def test_eval_missing_frame_exit_code(case, capsys):
    pred, seq = case
    (pred / "bin000002.png").unlink()
    assert main(["eval", str(pred), str(seq)]) == 2
    err = capsys.readouterr().err
    assert "bin000002.png" in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert main(["eval", str(pred), str(seq), "--allow-missing", "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["sequences"][0]["missing"] == 1
    assert "counted as background" in captured.err


def test_eval_bad_paths_exit_2(case, tmp_path, capsys):
    pred, seq = case
    assert main(["eval", str(tmp_path / "nope"), str(seq)]) == 2
    assert main(["eval", str(pred), str(tmp_path / "nope")]) == 2
    assert main(["eval", str(pred), str(seq), "--first-frame", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("bgsub: error:") == 3


@pytest.fixture
def scene(tmp_path):
    """A 16-frame 64x48 moving-camera scene with two objects, every frame in the temporal ROI."""
    spec = SceneSpec("pan", seed=1, width=64, height=48, n_frames=16, warmup=0, n_objects=2)
    return generate_scene(spec, tmp_path / "scenes")


def _gt_masks(seq, numbers):
    """The ground truth's own objects as 0/255 masks: a perfect prediction of those frames."""
    return {n: np.where(cv2.imread(str(seq / "groundtruth" / f"gt{n:06d}.png"),
                                   cv2.IMREAD_GRAYSCALE) == 255, 255, 0).astype(np.uint8)
            for n in numbers}


def test_eval_start_step_stop_read_a_mask_video_like_bgsub_run(scene, tmp_path, capsys):
    # The perfect masks of input frames 3, 5, 7, 9 (0-based), as `bgsub run --start 3 --step 2
    # --stop 11` would write them.
    masks = _gt_masks(scene, [4, 6, 8, 10])
    with open_mask_sink(tmp_path / "m.mkv", width=64, height=48, fps=25.0) as sink:
        for number, mask in masks.items():
            sink.write(mask, number - 1)
    assert main(["eval", str(tmp_path / "m.mkv"), str(scene), "--json", "--start", "3",
                 "--step", "2", "--stop", "11"]) == 0
    (only,) = json.loads(capsys.readouterr().out)["sequences"]
    assert (only["frames"], only["first_frame"], only["last_frame"]) == (4, 4, 10)
    assert only["metrics"]["f_measure"] == 1.0 and only["counts"]["tp"] > 0


def test_eval_repeats_the_flags_bgsub_run_notes(scene, tmp_path, capsys):
    video = tmp_path / "m.mkv"
    assert main(["run", str(scene), "-o", str(video), "-m", "framediff", "--start", "5",
                 "--step", "3"]) == 0
    flags = re.search(r"GROUNDTRUTH (.*)`", capsys.readouterr().err).group(1).split()
    assert main(["eval", str(video), str(scene), "--json", *flags]) == 0
    (only,) = json.loads(capsys.readouterr().out)["sequences"]
    # The same run written as bin pngs keeps the frame numbers: the reference.
    assert main(["run", str(scene), "-o", str(tmp_path / "bins"), "-m", "framediff", "--start",
                 "5", "--step", "3", "-q"]) == 0
    expected = evaluate_sequence(tmp_path / "bins", scene, frames=[6, 9, 12, 15]).counts
    assert only["frames"] == 4 and only["counts"] == expected.as_dict()


def test_eval_short_mask_video_error_names_the_run_flags(scene, tmp_path, bgsub_error):
    with open_mask_sink(tmp_path / "m.mkv", width=64, height=48, fps=25.0) as sink:
        for number, mask in _gt_masks(scene, range(9, 17)).items():
            sink.write(mask, number - 1)
    err = bgsub_error(["eval", tmp_path / "m.mkv", scene])
    assert "ends after frame 8" in err and "give eval the same flags" in err
    assert "--start/--step/--stop" in err


def test_eval_step_selects_the_frames_of_a_png_folder_like_those_of_a_video(scene, tmp_path,
                                                                            capsys):
    # The README's `bgsub run ... -o stepd --step 2`: bin000001.png, bin000003.png, ...
    for out in ("stepd", "stepd.mkv"):
        assert main(["run", str(scene), "-o", str(tmp_path / out), "-m", "framediff",
                     "--step", "2", "-q"]) == 0
    scores = []
    for out in ("stepd", "stepd.mkv"):
        assert main(["eval", str(tmp_path / out), str(scene), "--step", "2", "--json"]) == 0
        (only,) = json.loads(capsys.readouterr().out)["sequences"]
        scores.append((only["frames"], only["missing"], only["counts"]))
    assert scores[0] == scores[1] and scores[0][:2] == (8, 0)


def test_eval_missing_frames_of_a_part_of_the_sequence_name_the_options(scene, tmp_path,
                                                                       capsys, bgsub_error):
    masks = tmp_path / "part"
    assert main(["run", str(scene), "-o", str(masks), "-m", "framediff", "--start", "5",
                 "--stop", "11", "-q"]) == 0
    err = bgsub_error(["eval", masks, scene])
    assert "10 of 16 frames to evaluate have no prediction" in err
    assert ("to score just the frames with a mask (6, bin000006.png-bin000011.png), use "
            "--first-frame 6 --last-frame 11; or use --allow-missing to count the 10 frames "
            "without one as background") in err
    assert main(["eval", str(masks), str(scene), "--first-frame", "6", "--last-frame",
                 "11"]) == 0
    captured = capsys.readouterr()
    assert "frames 6-11" in captured.out and captured.err == ""
    assert main(["eval", str(masks), str(scene), "--allow-missing", "-q"]) == 0
    assert "use --first-frame 6 --last-frame 11" in capsys.readouterr().err


def test_eval_warns_of_a_mask_video_longer_than_the_ground_truth(scene, tmp_path, capsys):
    video = tmp_path / "other.mkv"
    with open_mask_sink(video, width=64, height=48, fps=25.0) as sink:
        for k in range(24):
            sink.write(np.zeros((48, 64), np.uint8), k)
    assert main(["eval", str(video), str(scene), "-q"]) == 0  # scored, not refused
    captured = capsys.readouterr()
    assert "pan_s1" in captured.out
    (line,) = captured.err.splitlines()
    assert line.startswith("bgsub: warning: pan_s1: mask video ") and (
        "holds 24 frames, past the end of the ground truth" in line
        and "has 16 ground-truth frames" in line)


def test_eval_scales_masks_run_wrote_at_another_width(scene, tmp_path, capsys):
    assert main(["run", str(scene), "-o", str(tmp_path / "small"), "-m", "framediff",
                 "--width", "40", "-q"]) == 0
    assert cv2.imread(str(tmp_path / "small" / "bin000001.png")).shape[:2] == (30, 40)
    assert main(["eval", str(tmp_path / "small"), str(scene)]) == 0
    captured = capsys.readouterr()
    assert "40x30 predictions scaled to 64x48 (nearest neighbour)" in captured.out
    assert captured.out.count("scaled") == 1 and captured.err == ""


def test_eval_help_teaches():
    with pytest.raises(SystemExit) as exit_info:
        main(["eval", "--help"])
    assert exit_info.value.code == 0


def test_methods_lists_engines_and_defaults(capsys):
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    for name in ("mog2", "knn", "framediff"):
        assert f"\n{name}" in "\n" + out
    assert "(default)" in out
    assert "history=500" in out and "var_threshold=16.0" in out and "detect_shadows=false" in out


def test_methods_json_matches_registry(capsys):
    assert main(["methods", "--json"]) == 0
    entries = {e["name"]: e for e in json.loads(capsys.readouterr().out)}
    assert sum(e["default"] for e in entries.values()) == 1
    spec = get_engine_spec("knn")
    assert entries["knn"]["description"] == spec.description
    assert {k: v["default"] for k, v in entries["knn"]["params"].items()} == {
        k: p.default for k, p in spec.params.items()}


def test_methods_shows_each_parameters_range(capsys):
    assert main(["methods", "grbm"]) == 0
    out = capsys.readouterr().out
    assert "patch grid step in working-size pixels (>=1)" in out
    assert main(["methods", "grbm", "--json"]) == 0
    alpha = json.loads(capsys.readouterr().out)[0]["params"]["alpha"]
    assert (alpha["low"], alpha["high"]) == (0, 1)


def test_methods_unknown_name(capsys):
    assert main(["methods", "nope"]) == 2
    assert "unknown method" in capsys.readouterr().err


def test_methods_empty_name_is_unknown_not_all(bgsub_error):
    err = bgsub_error(["methods", ""])
    assert "unknown method ''" in err and "available:" in err


def test_eval_first_frame_after_last_frame(case, bgsub_error):
    pred, seq = case
    err = bgsub_error(["eval", pred, seq, "--first-frame", "30", "--last-frame", "20"])
    assert "--first-frame 30) is after last_frame (--last-frame 20)" in err


def test_eval_method_scores_one_method_of_a_compare_report(tmp_path, case, capsys, bgsub_error):
    pred, seq = case
    report = tmp_path / "cmp"
    report.mkdir()
    (report / "report.txt").write_text("")
    pred.rename(report / "mine")  # the layout of `bgsub compare --mask-format png`
    (report / "other.mkv").write_bytes(b"")  # listed by its name only
    err = bgsub_error(["eval", report, seq])
    assert "it holds the mask sets mine/, other.mkv" in err and "--method mine" in err
    assert main(["eval", str(report), str(seq), "--method", "mine", "--json"]) == 0
    only = json.loads(capsys.readouterr().out)["sequences"][0]
    assert only["counts"] == {"tp": 8, "fp": 0, "fn": 8, "tn": 16}
    assert "method (--method) is empty" in bgsub_error(["eval", report, seq, "--method", ""])
