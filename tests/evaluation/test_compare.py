"""`bgsub compare` and bgsub.evaluation.compare: several engines on the same frames, timed and scored."""

from __future__ import annotations

import csv
import json
import math
import signal
from pathlib import Path
from typing import Dict, List, Tuple

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.engines import Engine, Param, register_engine
from bgsub.evaluation.compare import TileLayout, compare_methods
from bgsub.errors import InputError, OutputError
from bgsub.evaluation.cdnet import METRIC_NAMES, Metrics, evaluate_sequence
from helpers import SCENE_H, SCENE_W, read_frames, write_input_sequence

METHODS = ["framediff", "mog2"]


class _Bright(Engine):
    """Foreground where the gray level is above 200 (the test sequences' moving square)."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return np.where(gray > 200, 255, 0).astype(np.uint8)


#: Frame objects each ``_test_seen_*`` engine was given, in order (tests clear it).
SEEN: Dict[str, List[np.ndarray]] = {}


class _Seeing(_Bright):
    """Records the frames it is given in ``SEEN[tag]``."""

    def __init__(self, tag: str) -> None:
        self.tag = tag

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        SEEN.setdefault(self.tag, []).append(image)
        return super().apply(image)


#: ``_test_ctrl_c`` presses Ctrl-C when the frame number ``CTRL_C["at"]`` (counted over every
#: instance, from 1) comes in; 0 = never.
CTRL_C = {"at": 0, "frames": 0}


class _CtrlC(_Bright):
    def apply(self, image, fgmask=None, learning_rate=-1.0):
        CTRL_C["frames"] += 1
        if CTRL_C["frames"] == CTRL_C["at"]:
            signal.raise_signal(signal.SIGINT)
        return super().apply(image)


register_engine("_test_seen_a", "test: records its frames",
                params={"tag": Param("a", "SEEN key")})(_Seeing)
register_engine("_test_seen_b", "test: records its frames",
                params={"tag": Param("b", "SEEN key")})(_Seeing)
register_engine("_test_ctrl_c", "test: Ctrl-C as a given frame comes in")(_CtrlC)
#: Methods of the Ctrl-C tests: the second presses Ctrl-C, after the first made its mask.
CTRL_METHODS = ["framediff", "_test_ctrl_c"]
W, H = SCENE_W, SCENE_H


@pytest.fixture
def sequence(tmp_path: Path) -> Path:
    return write_input_sequence(tmp_path / "famA_one", temporal_roi="1 8")


def test_cli_writes_report_masks_and_video(sequence: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "report"
    code = main(["compare", str(sequence), "--methods", ",".join(METHODS), "-o", str(out),
                 "--skip-first", "--quiet"])
    assert code == 0
    for name in ("report.txt", "report.csv", "report.json", "side_by_side.mp4"):
        assert (out / name).is_file(), name
    for method in METHODS:
        assert sorted(p.name for p in (out / method).glob("bin*.png")) == \
            [f"bin{k:06d}.png" for k in range(1, 9)]
    printed = capsys.readouterr().out
    assert (out / "report.txt").read_text().strip() == printed.strip()
    for method in METHODS:
        assert method in printed


def test_rows_one_per_method_with_metrics_and_fps(sequence: Path) -> None:
    report = compare_methods(sequence, methods=METHODS, skip_first=True)
    assert [r.method for r in report.rows] == METHODS
    for row in report.rows:
        assert row.frames == 8 and row.eval_frames == 7
        assert row.fps > 0
        assert isinstance(row.metrics, Metrics)
    assert not report.families and not report.overall  # a single sequence has no means


def test_each_frame_is_decoded_once_for_all_methods(sequence: Path) -> None:
    # Every method is handed the very same array for a frame: it was decoded once.
    SEEN.clear()
    report = compare_methods(sequence, methods=["_test_seen_a", "_test_seen_b"])
    assert len(SEEN["a"]) == len(SEEN["b"]) == 8
    assert all(a is b for a, b in zip(SEEN["a"], SEEN["b"]))
    assert all(r.frames == 8 for r in report.rows)


def test_metrics_equal_bgsub_eval_on_written_masks(sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    report = compare_methods(sequence, methods=METHODS, report_dir=out, skip_first=True,
                             video=False)
    for row in report.rows:
        reference = evaluate_sequence(out / row.method, sequence, skip_first=True)
        assert row.counts == reference.counts
        assert row.counts.tp + row.counts.fn > 0  # the square is there to be found
        for name in METRIC_NAMES:
            ours, theirs = getattr(row.metrics, name), getattr(reference.metrics, name)
            assert (math.isnan(ours) and math.isnan(theirs)) or ours == pytest.approx(theirs)


def test_csv_and_json_hold_the_rows(sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    report = compare_methods(sequence, methods=METHODS, report_dir=out, video=False,
                             masks="none")
    with open(out / "report.csv", newline="") as fh:
        records = list(csv.DictReader(fh))
    assert [r["method"] for r in records] == METHODS
    data = json.loads((out / "report.json").read_text())
    assert [r["method"] for r in data["rows"]] == METHODS
    for record, entry, row in zip(records, data["rows"], report.rows):
        assert int(record["tp"]) == row.counts.tp == entry["counts"]["tp"]
        assert float(record["f_measure"]) == pytest.approx(row.metrics.f_measure)
        assert entry["fps"] == pytest.approx(row.fps)
    assert not list(out.glob("*/bin*.png"))  # masks="none"


def test_side_by_side_video_size_and_frame_count(sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    compare_methods(sequence, methods=METHODS, report_dir=out, masks="none")
    layout = TileLayout.for_frames(W, H, ["input", "ground truth", *METHODS])
    assert (layout.width, layout.height) == (4 * W, H)
    frames = read_frames(out / "side_by_side.mp4")
    assert len(frames) == 8
    assert frames[0].shape == (layout.height, layout.width, 3)


def test_tile_layout_stays_sensible_for_large_frames() -> None:
    layout = TileLayout.for_frames(854, 480, ["input", "a", "b", "c", "d"])
    assert layout.width <= 1600 and layout.height <= 180
    assert layout.tile_width % 2 == 0 and layout.tile_height % 2 == 0
    assert layout.tile_width / layout.tile_height == pytest.approx(854 / 480, rel=0.02)
    picture = layout.compose(np.zeros((480, 854, 3), np.uint8),
                             [np.full((480, 854), 255, np.uint8)] * 4)
    assert picture.shape == (layout.height, layout.width, 3)
    # A white mask tile stays white away from its label and border.
    assert picture[layout.tile_height // 2, layout.tile_width + layout.tile_width // 2].min() \
        == 255


def test_dataset_root_family_and_overall_means(tmp_path: Path) -> None:
    root = tmp_path / "data"
    write_input_sequence(root / "famA_one", seed=0, side=10, speed=4)
    write_input_sequence(root / "famA_two", seed=1, side=6, speed=2)
    write_input_sequence(root / "famB_one", seed=2, side=14, speed=5)
    report = compare_methods(root, methods=METHODS, report_dir=tmp_path / "out",
                             skip_first=True, video=False, masks="none")
    assert [(r.name, r.method) for r in report.rows] == [
        (s, m) for s in ("famA_one", "famA_two", "famB_one") for m in METHODS]
    assert {r.family for r in report.rows} == {"famA", "famB"}
    for method in METHODS:
        seq = {r.name: r.metrics for r in report.rows if r.method == method}
        fam = {r.name: r.metrics for r in report.families if r.method == method}
        assert set(fam) == {"famA", "famB"}
        (overall,) = [r.metrics for r in report.overall if r.method == method]
        for name in METRIC_NAMES:
            a = np.mean([getattr(seq["famA_one"], name), getattr(seq["famA_two"], name)])
            b = getattr(seq["famB_one"], name)
            assert getattr(fam["famA"], name) == pytest.approx(a)
            assert getattr(fam["famB"], name) == pytest.approx(b)
            assert getattr(overall, name) == pytest.approx((a + b) / 2)
    # The two sequences of famA really differ, so the mean is not trivially one of them.
    assert report.rows[0].metrics != report.rows[2].metrics


def test_dataset_category_layout_and_outputs_per_sequence(tmp_path: Path) -> None:
    root = tmp_path / "cdnet"
    write_input_sequence(root / "baseline" / "highway", seed=0)
    write_input_sequence(root / "cameraJitter" / "traffic", seed=1)
    out = tmp_path / "out"
    report = compare_methods(root, methods=["framediff"], report_dir=out, max_frames=3)
    assert [(r.name, r.family, r.frames) for r in report.rows] == [
        ("highway", "baseline", 3), ("traffic", "cameraJitter", 3)]
    assert (out / "baseline" / "highway" / "side_by_side.mp4").is_file()
    assert len(list((out / "cameraJitter" / "traffic" / "framediff").glob("bin*.png"))) == 3


@pytest.mark.parametrize("masks, video, wanted", [
    ("mkv", False, "framediff.mkv"), ("none", True, "side_by_side.mp4")])
def test_dataset_outputs_without_png_masks_get_their_folder(tmp_path: Path, masks, video,
                                                            wanted) -> None:
    # Video and mkv sinks need the sequence's folder made for them, as the PNG sink makes its own.
    root = tmp_path / "data"
    write_input_sequence(root / "famA_one", seed=0)
    out = tmp_path / "out"
    compare_methods(root, methods=["framediff"], report_dir=out, max_frames=3, masks=masks,
                    video=video)
    assert (out / "famA_one" / wanted).is_file()


def test_roi_bmp_used_for_a_sequence_ignored_for_a_dataset(tmp_path: Path) -> None:
    roi = np.zeros((H, W), np.uint8)
    roi[:, : W // 2] = 255
    seq = write_input_sequence(tmp_path / "root" / "famA_one", roi=roi)
    used = compare_methods(seq, methods=["framediff"])
    ignored = compare_methods(tmp_path / "root", methods=["framediff"])
    forced = compare_methods(tmp_path / "root", methods=["framediff"], ignore_roi_bmp=False)
    pixels = lambda row: row.counts.tp + row.counts.fp + row.counts.fn + row.counts.tn
    assert pixels(used.rows[0]) == 8 * H * W // 2
    assert pixels(ignored.rows[0]) == 8 * H * W
    assert pixels(forced.rows[0]) == 8 * H * W // 2


def test_temporal_roi_and_max_frames_limit_scoring(tmp_path: Path) -> None:
    seq = write_input_sequence(tmp_path / "famA_one", temporal_roi="4 8")
    report = compare_methods(seq, methods=["framediff"], max_frames=6)
    assert report.rows[0].frames == 6
    assert report.rows[0].eval_frames == 3  # frames 4, 5, 6
    with pytest.raises(InputError, match="no ground-truth frames"):
        compare_methods(seq, methods=["framediff"], max_frames=3)


def test_skip_first_drops_the_first_processed_frame_only(tmp_path: Path) -> None:
    seq = write_input_sequence(tmp_path / "famA_one", temporal_roi="4 8")
    # Frame 4 opens the temporal ROI but the engines have seen frames 1-3: it is scored.
    assert compare_methods(seq, methods=["framediff"], skip_first=True).rows[0].eval_frames == 5
    # Starting at frame 4 (index 3), frame 4 is the engines' first: it is not.
    late = compare_methods(seq, methods=["framediff"], skip_first=True, start=3)
    assert late.rows[0].eval_frames == 4
    assert late.rows[0].frames == 5


def test_video_input_with_separate_ground_truth(sequence: Path, tmp_path: Path) -> None:
    from bgsub.io.sinks import VideoSink

    video = tmp_path / "clip.mkv"  # lossless, so frames equal the sequence's
    with VideoSink(video, fps=25.0) as sink:
        for k in range(1, 9):
            sink.write(cv2.imread(str(sequence / "input" / f"in{k:06d}.png")))
    from_video = compare_methods(video, methods=["framediff"], gt=sequence)
    from_folder = compare_methods(sequence, methods=["framediff"])
    assert from_video.rows[0].counts == from_folder.rows[0].counts


def test_an_input_longer_than_its_ground_truth_is_warned_about(sequence: Path,
                                                               tmp_path: Path) -> None:
    from bgsub.io.sinks import VideoSink

    video = tmp_path / "clip.mkv"
    with VideoSink(video, fps=25.0) as sink:
        for k in [*range(1, 9), *range(1, 5)]:  # 12 frames against 8 of ground truth
            sink.write(cv2.imread(str(sequence / "input" / f"in{k:06d}.png")))
    report = compare_methods(video, methods=["framediff"], gt=sequence)
    assert report.warnings == [
        f"clip.mkv: {video} holds frames up to 12, past the ground truth's last (8 in {sequence}): "
        "check that the ground truth belongs to this input; only frames with ground truth are "
        "scored"]
    assert report.rows[0].eval_frames == 8
    assert compare_methods(video, methods=["framediff"], gt=sequence, stop=8).warnings == []


def test_no_ground_truth_gives_speed_only(sequence: Path, tmp_path: Path) -> None:
    report = compare_methods(sequence / "input", methods=METHODS, report_dir=tmp_path / "o",
                             video=False)
    assert all(r.metrics is None and r.fps > 0 for r in report.rows)
    assert "Recall" not in report.to_text()


@pytest.mark.parametrize("argv_tail, message", [
    (["--methods", "framediff,nosuch"], "unknown method 'nosuch'"),
    (["--methods", "framediff", "--param", "mog2.history=5"], "not among the methods"),
    (["--methods", "framediff,framediff"], "twice"),
])
def test_bad_methods_exit_2(sequence: Path, tmp_path: Path, capsys, argv_tail, message) -> None:
    out = tmp_path / "out"
    assert main(["compare", str(sequence), "-o", str(out), *argv_tail]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()  # nothing is created before the inputs are accepted


def test_missing_input_exits_2(tmp_path: Path, capsys) -> None:
    code = main(["compare", str(tmp_path / "absent"), "--methods", "framediff", "-o",
                 str(tmp_path / "out")])
    assert code == 2
    assert "does not exist" in capsys.readouterr().err


def test_existing_report_dir_needs_overwrite(sequence: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("keep me")
    argv = ["compare", str(sequence), "--methods", "framediff", "-o", str(out), "-q"]
    assert main(argv) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main(argv + ["--overwrite"]) == 0
    assert (out / "report.txt").is_file() and (out / "old.txt").read_text() == "keep me"


def test_api_refuses_existing_report_dir(sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    compare_methods(sequence, methods=["framediff"], report_dir=out, video=False)
    with pytest.raises(OutputError):
        compare_methods(sequence, methods=["framediff"], report_dir=out, video=False)


def test_report_dir_named_like_a_file_is_refused(sequence: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "cmp.txt"
    assert main(["compare", str(sequence), "--methods", "framediff", "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "folder" in err and "Traceback" not in err
    assert not out.exists()


def test_an_empty_report_dir_is_refused(sequence: Path, capsys) -> None:
    assert main(["compare", str(sequence), "--methods", "framediff", "-o", "", "-q"]) == 2
    assert "empty" in capsys.readouterr().err


def test_an_empty_methods_list_is_refused_not_read_as_all(sequence: Path, tmp_path: Path,
                                                           capsys) -> None:
    assert main(["compare", str(sequence), "-m", "", "-o", str(tmp_path / "o"), "-q"]) == 2
    assert "empty" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_dotted_report_dir_is_a_folder_when_it_says_so(sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "cmp.json"  # a folder name with a dot: accepted with a trailing slash
    compare_methods(sequence, methods=["framediff"], report_dir=f"{out}/", video=False)
    assert (out / "report.json").is_file()


def test_bad_roi_bmp_fails_before_any_output(tmp_path: Path, capsys) -> None:
    seq = write_input_sequence(tmp_path / "famA_one", roi=np.full((H, W + 8), 255, np.uint8))
    out = tmp_path / "out"
    assert main(["compare", str(seq), "--methods", "framediff", "-o", str(out)]) == 2
    assert "--no-roi-bmp" in capsys.readouterr().err
    assert not out.exists()
    assert main(["compare", str(seq), "--methods", "framediff", "-o", str(out), "-q",
                 "--no-roi-bmp"]) == 0


def test_gt_with_dataset_root_is_refused(tmp_path: Path) -> None:
    write_input_sequence(tmp_path / "root" / "famA_one")
    with pytest.raises(InputError, match="--gt"):
        compare_methods(tmp_path / "root", methods=["framediff"],
                        gt=tmp_path / "root" / "famA_one")


def ctrl_c_at(frame: int) -> None:
    """Ctrl-C as ``_test_ctrl_c`` gets frame number ``frame`` (counted over every input)."""
    CTRL_C.update(at=frame, frames=0)


@pytest.fixture
def no_ctrl_c():
    yield
    CTRL_C.update(at=0, frames=0)


def test_ctrl_c_during_a_frame_leaves_every_output_the_same_length(
        sequence: Path, tmp_path: Path, no_ctrl_c) -> None:
    # Ctrl-C while the second method works on frame 3, after the first made its mask: frame 3
    # goes to no output, so every method's masks and the side-by-side video hold frames 1-2.
    ctrl_c_at(3)
    out = tmp_path / "report"
    with pytest.raises(KeyboardInterrupt):
        compare_methods(sequence, methods=CTRL_METHODS, report_dir=out)
    for method in CTRL_METHODS:
        assert sorted(p.name for p in (out / method).glob("bin*.png")) == \
            ["bin000001.png", "bin000002.png"], method
    capture = cv2.VideoCapture(str(out / "side_by_side.mp4"))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 2
    capture.release()


def test_ctrl_c_writes_the_report_of_the_frames_processed(sequence: Path, tmp_path: Path,
                                                          no_ctrl_c) -> None:
    ctrl_c_at(4)
    out = tmp_path / "report"
    with pytest.raises(KeyboardInterrupt) as stop:
        compare_methods(sequence, methods=CTRL_METHODS, report_dir=out)
    report = stop.value.report
    assert [(r.method, r.frames, r.eval_frames) for r in report.rows] == [
        (m, 3, 3) for m in CTRL_METHODS]
    assert "famA_one: stopped by Ctrl-C after 3 frames: the figures cover those" in \
        report.warnings
    written = json.loads((out / "report.json").read_text())
    assert [row["eval_frames"] for row in written["rows"]] == [3, 3]
    masks = {m: evaluate_sequence(out / m, sequence, last_frame=3) for m in CTRL_METHODS}
    for row in report.rows:
        assert row.counts == masks[row.method].counts


def test_ctrl_c_in_the_cli_prints_the_partial_report_and_exits_130(
        sequence: Path, tmp_path: Path, capsys, no_ctrl_c) -> None:
    ctrl_c_at(4)
    out = tmp_path / "report"
    code = main(["compare", str(sequence), "--methods", ",".join(CTRL_METHODS), "-o", str(out)])
    captured = capsys.readouterr()
    assert code == 130
    assert "framediff" in captured.out and "_test_ctrl_c" in captured.out  # the table
    assert f"partial report written to {out / 'report.txt'}" in captured.err
    assert captured.err.rstrip().endswith("bgsub: interrupted")


def test_ctrl_c_in_the_second_sequence_keeps_the_first(tmp_path: Path, no_ctrl_c) -> None:
    root = tmp_path / "data"
    write_input_sequence(root / "famA_one", seed=0)
    write_input_sequence(root / "famA_two", seed=1)
    ctrl_c_at(8 + 3)  # frame 3 of the second sequence
    with pytest.raises(KeyboardInterrupt) as stop:
        compare_methods(root, methods=CTRL_METHODS, report_dir=tmp_path / "report")
    rows = {(r.name, r.method): r.frames for r in stop.value.report.rows}
    assert rows == {("famA_one", m): 8 for m in CTRL_METHODS} | \
        {("famA_two", m): 2 for m in CTRL_METHODS}


# --------------------------------------------------------------------------------------------
# --overwrite: this run's outputs only, and nothing compare did not write goes
# --------------------------------------------------------------------------------------------


#: The report files compare writes at the top of its folder.
REPORTS = {"report.txt", "report.csv", "report.json", "report.html"}


def listing(folder: Path) -> set:
    """Every file and folder below ``folder``, as relative posix paths (folders end in /)."""
    return {p.relative_to(folder).as_posix() + ("/" if p.is_dir() else "")
            for p in folder.rglob("*")}


def test_overwrite_leaves_only_this_runs_outputs_and_the_users_files(
        sequence: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    argv = ["compare", str(sequence), "-o", str(out), "-q"]
    assert main(argv + ["--methods", "framediff,mog2"]) == 0
    assert (out / "framediff").is_dir() and (out / "side_by_side.mp4").is_file()
    (out / "notes.txt").write_text("mine")
    (out / "mog2" / "keep.txt").write_text("mine too")
    # Named like an engine's output, but not in the previous report.json's list: not compare's.
    (out / "knn.mkv").write_bytes(b"mine as well")
    assert main(argv + ["--methods", "mog2", "--overwrite", "--no-video", "--mask-format", "mkv"]) == 0
    assert listing(out) == {*REPORTS, "mog2.mkv",
                            "notes.txt", "mog2/", "mog2/keep.txt", "knn.mkv"}
    (out / "knn.mkv").unlink()
    assert (out / "notes.txt").read_text() == "mine"
    data = json.loads((out / "report.json").read_text())
    assert data["outputs"] == ["report.txt", "report.csv", "report.json", "report.html",
                               "mog2.mkv"]
    # And back to PNG masks: the .mkv goes, the user's files stay.
    assert main(argv + ["--methods", "mog2", "--overwrite", "--no-video"]) == 0
    assert listing(out) == {*REPORTS, "notes.txt", "mog2/",
                            "mog2/keep.txt", *(f"mog2/bin{k:06d}.png" for k in range(1, 9))}


def test_overwrite_clears_a_dataset_roots_sequence_folders(tmp_path: Path) -> None:
    root = tmp_path / "data"
    write_input_sequence(root / "baseline" / "highway", seed=0)
    write_input_sequence(root / "cameraJitter" / "traffic", seed=1)
    out = tmp_path / "out"
    compare_methods(root, methods=["framediff", "mog2"], report_dir=out, max_frames=3)
    assert (out / "baseline" / "highway" / "side_by_side.mp4").is_file()
    (out / "cameraJitter" / "mine.txt").write_text("mine")
    compare_methods(root, methods=["mog2"], report_dir=out, max_frames=3, video=False,
                    masks="mkv", overwrite=True)
    assert listing(out) == {
        *REPORTS, "cameraJitter/", "cameraJitter/mine.txt",
        "cameraJitter/traffic/", "cameraJitter/traffic/mog2.mkv", "baseline/",
        "baseline/highway/", "baseline/highway/mog2.mkv"}
    compare_methods(root, methods=["knn"], report_dir=out, max_frames=3, video=False,
                    masks="none", overwrite=True)
    assert listing(out) == {*REPORTS, "cameraJitter/",
                            "cameraJitter/mine.txt"}


@pytest.mark.parametrize("dataset", [False, True])
def test_overwrite_without_a_report_json_goes_by_compares_names(tmp_path: Path,
                                                                 dataset: bool) -> None:
    # An interrupted run leaves outputs but no report.json listing them.
    root = tmp_path / "data"
    seq = write_input_sequence(root / "cat" / "famA_one")
    source = root if dataset else seq
    prefix = "cat/famA_one/" if dataset else ""
    out = tmp_path / "out"
    compare_methods(source, methods=["framediff", "mog2"], report_dir=out, max_frames=3,
                    masks="mkv")
    (out / "report.json").unlink()
    (out / f"{prefix}.side_by_side.partial.mp4").write_bytes(b"left by a killed run")
    (out / f"{prefix}framediff").mkdir()
    (out / f"{prefix}framediff" / "bin000001.png").write_bytes(b"")
    (out / "unrelated.mkv").write_bytes(b"not a method's name")
    (out / "holiday").mkdir()
    (out / "holiday" / "beach.mp4").write_bytes(b"not compare's")
    compare_methods(source, methods=["mog2"], report_dir=out, max_frames=3, video=False,
                    masks="none", overwrite=True)
    assert listing(out) == {*REPORTS, "unrelated.mkv",
                            "holiday/", "holiday/beach.mp4"}


@pytest.mark.parametrize("argv_tail, message", [
    (["--gt", "absent"], "not a CDnet sequence"),  # a typo
    (["--gt", "late"], "ends at frame 8, before the first ground-truth frame"),
])
def test_overwrite_keeps_old_results_when_the_input_is_refused(
        sequence: Path, tmp_path: Path, capsys, argv_tail, message) -> None:
    write_input_sequence(tmp_path / "late", n_frames=14, speed=2, temporal_roi="10 14")
    out = tmp_path / "out"
    assert main(["compare", str(sequence / "input"), "--gt", str(sequence), "-o", str(out),
                 "-m", "framediff", "-q"]) == 0
    before = listing(out)
    tail = [str(tmp_path / argv_tail[1]) if a in ("absent", "late") else a for a in argv_tail]
    assert main(["compare", str(sequence / "input"), "-o", str(out), "-m", "mog2", "-q",
                 "--overwrite", *tail]) == 2
    assert message in capsys.readouterr().err
    assert listing(out) == before


def test_overwrite_does_not_remove_this_runs_input(sequence: Path, tmp_path: Path,
                                                   capsys) -> None:
    out = tmp_path / "out"
    compare_methods(sequence, methods=["framediff"], report_dir=out, video=False)
    masks = out / "framediff"
    assert main(["compare", str(masks), "-o", str(out), "-m", "mog2", "-q", "--overwrite"]) == 2
    assert "part of this run's input" in capsys.readouterr().err
    assert len(list(masks.glob("bin*.png"))) == 8


# --------------------------------------------------------------------------------------------
# An input shorter than its ground truth
# --------------------------------------------------------------------------------------------


@pytest.fixture
def short_input(tmp_path: Path) -> Tuple[Path, Path]:
    """``(frames, gt)``: 6 frames of a 12-frame sequence whose temporal ROI is 3-12."""
    gt = write_input_sequence(tmp_path / "famA_long", n_frames=12, speed=3, temporal_roi="3 12")
    frames = tmp_path / "short"
    frames.mkdir()
    for k in range(1, 7):
        name = f"in{k:06d}.png"
        (frames / name).write_bytes((gt / "input" / name).read_bytes())
    return frames, gt


def test_input_shorter_than_its_ground_truth_warns_and_says_what_was_scored(
        short_input, tmp_path: Path, capsys) -> None:
    frames, gt = short_input
    out = tmp_path / "out"
    assert main(["compare", str(frames), "--gt", str(gt), "-o", str(out), "-m", "framediff",
                 "--no-video", "-q"]) == 0
    captured = capsys.readouterr()
    said = "short: scored 4 of 10 ground-truth frames (3-12): the input ends at frame 6"
    warnings = [line for line in captured.err.splitlines() if "warning" in line]
    assert warnings == [f"bgsub: warning: {said}"]  # one line, printed with -q too
    report = (out / "report.txt").read_text()
    assert "short: scored frames 3-6 (4 frames)" in report and said in report
    data = json.loads((out / "report.json").read_text())
    assert data["rows"][0]["eval_frames"] == 4 and data["warnings"] == [said]
    # The figures are bgsub eval's on the masks written, up to the input's last frame.
    reference = evaluate_sequence(out / "framediff", gt, last_frame=6)
    assert data["rows"][0]["counts"] == reference.counts.as_dict()
    assert reference.counts.tp > 0


@pytest.mark.parametrize("options", [{"max_frames": 5}, {"stop": 6}, {"stop": 4}])
def test_asking_for_fewer_frames_draws_no_warning(short_input, options) -> None:
    frames, gt = short_input
    report = compare_methods(frames, gt=gt, methods=["framediff"], **options)
    assert report.warnings == []
    assert not any("the input ends" in n for n in report.rows[0].notes)


def _mjpeg(frames: Path, path: Path) -> Path:
    """The PNG frames of the folder ``frames`` as an MJPEG video at ``path``: ``.avi`` states
    its length, a raw ``.mjpeg`` stream states none."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (W, H))
    for png in sorted(frames.glob("*.png")):
        writer.write(cv2.imread(str(png)))
    writer.release()
    return path


def test_input_ending_early_without_a_stated_length_is_scored_the_same(
        short_input, tmp_path: Path) -> None:
    # A video that does not say how long it is: the end is found by reading, and the frames
    # never read are not scored either.
    from bgsub.io.sources import open_source

    frames, gt = short_input
    stated = _mjpeg(frames, tmp_path / "short.avi")
    unstated = _mjpeg(frames, tmp_path / "short.mjpeg")
    with open_source(str(unstated)) as source:
        assert source.info.frame_count is None
    known = compare_methods(stated, gt=gt, methods=["framediff"])
    unknown = compare_methods(unstated, gt=gt, methods=["framediff"])
    assert unknown.rows[0].eval_frames == known.rows[0].eval_frames == 4
    assert unknown.rows[0].counts == known.rows[0].counts
    assert [w.replace(".mjpeg", ".avi") for w in unknown.warnings] == known.warnings
    assert len(known.warnings) == 1


def test_dataset_sequences_with_short_inputs_warn(tmp_path: Path) -> None:
    root = tmp_path / "data"
    for name, roi in (("famA_cut", "1 8"), ("famA_late", "5 8")):
        seq = write_input_sequence(root / name, temporal_roi=roi)
        for k in range(4, 9):  # input/ holds frames 1-3 of the 8 in groundtruth/
            (seq / "input" / f"in{k:06d}.png").unlink()
    write_input_sequence(root / "famB_whole", seed=1)
    report = compare_methods(root, methods=["framediff"])
    assert report.warnings == [
        "famA_cut: scored 3 of 8 ground-truth frames (1-8): the input ends at frame 3",
        f"famA_late: not scored: {root / 'famA_late'} ends at frame 3, before the first "
        f"ground-truth frame to score (5; 4 frames, 5-8, in {root / 'famA_late'})"]
    assert [(r.name, r.eval_frames) for r in report.rows] == [
        ("famA_cut", 3), ("famA_late", 0), ("famB_whole", 8)]


def test_a_truncated_video_is_reported(tmp_path: Path) -> None:
    """As `bgsub run` warns: decoding ends well before the frame count the header declares."""
    rng = np.random.default_rng(0)
    whole = tmp_path / "whole.avi"
    writer = cv2.VideoWriter(str(whole), cv2.VideoWriter_fourcc(*"FFV1"), 25, (32, 24))
    for _ in range(40):
        writer.write(rng.integers(0, 255, (24, 32, 3), dtype=np.uint8))
    writer.release()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    report = compare_methods(cut, methods=["framediff"])
    assert any("ended after" in w and "of the 40 frames its header declares" in w
               for w in report.warnings)
    assert not compare_methods(whole, methods=["framediff"]).warnings


def test_a_refused_input_leaves_no_report_folder(tmp_path: Path, capsys) -> None:
    (tmp_path / "empty.mp4").write_bytes(b"")
    out = tmp_path / "results" / "report"  # the parent it made goes too
    assert main(["compare", str(tmp_path / "empty.mp4"), "--methods", "mog2",
                 "-o", str(out)]) == 2
    assert "cannot read it as a video" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


def test_a_refused_input_leaves_an_existing_report_folder_alone(tmp_path: Path) -> None:
    (tmp_path / "empty.mp4").write_bytes(b"")
    out = tmp_path / "report"
    out.mkdir()
    with pytest.raises(InputError):
        compare_methods(tmp_path / "empty.mp4", methods=["mog2"], report_dir=out)
    assert out.is_dir()
