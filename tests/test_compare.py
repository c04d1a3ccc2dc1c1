"""`bgsub compare` and bgsub.compare: several engines on the same frames, timed and scored."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Optional

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.compare import TileLayout, compare_methods
from bgsub.errors import InputError, OutputError
from bgsub.evaluation import METRIC_NAMES, Metrics, evaluate_sequence

METHODS = ["framediff", "mog2"]
W, H = 64, 48


def write_sequence(folder: Path, *, n_frames: int = 8, side: int = 10, speed: int = 4,
                   seed: int = 0, temporal_roi: Optional[str] = None,
                   roi: Optional[np.ndarray] = None) -> Path:
    """A tiny CDnet sequence: static textured background, a bright square moving right.

    ``input/in%06d.png`` (lossless, so the test does not depend on JPEG), ``groundtruth/
    gt%06d.png`` (0/255), optional ``temporalROI.txt`` and ``ROI.bmp``.
    """
    rng = np.random.default_rng(seed)
    background = rng.integers(40, 120, size=(H, W), dtype=np.uint8)
    (folder / "input").mkdir(parents=True)
    (folder / "groundtruth").mkdir()
    for k in range(n_frames):
        frame = background.copy()
        gt = np.zeros((H, W), np.uint8)
        x, y = 2 + speed * k, 12 + seed
        frame[y:y + side, x:x + side] = 230
        gt[y:y + side, x:x + side] = 255
        cv2.imwrite(str(folder / "input" / f"in{k + 1:06d}.png"),
                    cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
        cv2.imwrite(str(folder / "groundtruth" / f"gt{k + 1:06d}.png"), gt)
    if temporal_roi is not None:
        (folder / "temporalROI.txt").write_text(temporal_roi + "\n")
    if roi is not None:
        cv2.imwrite(str(folder / "ROI.bmp"), roi)
    return folder


@pytest.fixture
def sequence(tmp_path: Path) -> Path:
    return write_sequence(tmp_path / "famA_one", temporal_roi="1 8")


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


def test_each_frame_is_decoded_once_for_all_methods(sequence: Path, monkeypatch) -> None:
    import bgsub.compare as compare_module

    opened = []
    real_open = compare_module.open_source

    def counting_open(*args, **kwargs):
        source = real_open(*args, **kwargs)
        opened.append(source)
        return source

    monkeypatch.setattr(compare_module, "open_source", counting_open)
    from bgsub.sources import _ImageListBackend

    decoded = []
    real_read = _ImageListBackend.read
    monkeypatch.setattr(_ImageListBackend, "read",
                        lambda self, index: decoded.append(self.files[index])
                        or real_read(self, index))
    report = compare_methods(sequence, methods=["framediff", "mog2", "knn"])
    assert len(opened) == 1
    # The source may probe the first image once for its size, but no frame is decoded once per
    # method (3 x 8).
    assert len(set(decoded)) == 8 and len(decoded) <= 9
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
    layout = TileLayout.for_frames(W, H, ["input", *METHODS])
    assert (layout.width, layout.height) == (3 * W, H)
    capture = cv2.VideoCapture(str(out / "side_by_side.mp4"))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
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
    write_sequence(root / "famA_one", seed=0, side=10, speed=4)
    write_sequence(root / "famA_two", seed=1, side=6, speed=2)
    write_sequence(root / "famB_one", seed=2, side=14, speed=5)
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
    write_sequence(root / "baseline" / "highway", seed=0)
    write_sequence(root / "cameraJitter" / "traffic", seed=1)
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
    # Only the PNG mask sink used to create a sequence's folder.
    root = tmp_path / "data"
    write_sequence(root / "famA_one", seed=0)
    out = tmp_path / "out"
    compare_methods(root, methods=["framediff"], report_dir=out, max_frames=3, masks=masks,
                    video=video)
    assert (out / "famA_one" / wanted).is_file()


def test_roi_bmp_used_for_a_sequence_ignored_for_a_dataset(tmp_path: Path) -> None:
    roi = np.zeros((H, W), np.uint8)
    roi[:, : W // 2] = 255
    seq = write_sequence(tmp_path / "root" / "famA_one", roi=roi)
    used = compare_methods(seq, methods=["framediff"])
    ignored = compare_methods(tmp_path / "root", methods=["framediff"])
    forced = compare_methods(tmp_path / "root", methods=["framediff"], ignore_roi_bmp=False)
    pixels = lambda row: row.counts.tp + row.counts.fp + row.counts.fn + row.counts.tn
    assert pixels(used.rows[0]) == 8 * H * W // 2
    assert pixels(ignored.rows[0]) == 8 * H * W
    assert pixels(forced.rows[0]) == 8 * H * W // 2


def test_temporal_roi_and_max_frames_limit_scoring(tmp_path: Path) -> None:
    seq = write_sequence(tmp_path / "famA_one", temporal_roi="4 8")
    report = compare_methods(seq, methods=["framediff"], max_frames=6)
    assert report.rows[0].frames == 6
    assert report.rows[0].eval_frames == 3  # frames 4, 5, 6
    with pytest.raises(InputError, match="no ground-truth frames"):
        compare_methods(seq, methods=["framediff"], max_frames=3)


def test_skip_first_drops_the_first_processed_frame_only(tmp_path: Path) -> None:
    seq = write_sequence(tmp_path / "famA_one", temporal_roi="4 8")
    # Frame 4 opens the temporal ROI but the engines have seen frames 1-3: it is scored.
    assert compare_methods(seq, methods=["framediff"], skip_first=True).rows[0].eval_frames == 5
    # Starting at frame 4 (index 3), frame 4 is the engines' first: it is not.
    late = compare_methods(seq, methods=["framediff"], skip_first=True, start=3)
    assert late.rows[0].eval_frames == 4
    assert late.rows[0].frames == 5


def test_video_input_with_separate_ground_truth(sequence: Path, tmp_path: Path) -> None:
    from bgsub.sinks import VideoSink

    video = tmp_path / "clip.mkv"  # lossless, so frames equal the sequence's
    with VideoSink(video, fps=25.0) as sink:
        for k in range(1, 9):
            sink.write(cv2.imread(str(sequence / "input" / f"in{k:06d}.png")))
    from_video = compare_methods(video, methods=["framediff"], gt=sequence)
    from_folder = compare_methods(sequence, methods=["framediff"])
    assert from_video.rows[0].counts == from_folder.rows[0].counts


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
    seq = write_sequence(tmp_path / "famA_one", roi=np.full((H, W + 8), 255, np.uint8))
    out = tmp_path / "out"
    assert main(["compare", str(seq), "--methods", "framediff", "-o", str(out)]) == 2
    assert "--no-roi-bmp" in capsys.readouterr().err
    assert not out.exists()
    assert main(["compare", str(seq), "--methods", "framediff", "-o", str(out), "-q",
                 "--no-roi-bmp"]) == 0


def test_gt_with_dataset_root_is_refused(tmp_path: Path) -> None:
    write_sequence(tmp_path / "root" / "famA_one")
    with pytest.raises(InputError, match="--gt"):
        compare_methods(tmp_path / "root", methods=["framediff"],
                        gt=tmp_path / "root" / "famA_one")


def test_ctrl_c_while_a_mask_is_written_leaves_every_output_the_same_length(
        sequence: Path, tmp_path: Path, monkeypatch) -> None:
    # Ctrl-C arriving while the first method's mask of frame 3 is written (the signal itself)
    # waits until frame 3 is in the other method's masks and the side-by-side video too.
    import signal

    from bgsub import sinks

    write_png = sinks.MaskFolderSink._write
    calls = []

    def write_then_ctrl_c(self, mask, index):
        write_png(self, mask, index)
        calls.append(index)
        if len(calls) == 2 * 3 - 1:  # two methods per frame: the first method's frame 3
            signal.raise_signal(signal.SIGINT)

    monkeypatch.setattr(sinks.MaskFolderSink, "_write", write_then_ctrl_c)
    out = tmp_path / "report"
    with pytest.raises(KeyboardInterrupt):
        compare_methods(sequence, methods=METHODS, report_dir=out)
    for method in METHODS:
        assert len(list((out / method).glob("bin*.png"))) == 3, method
    capture = cv2.VideoCapture(str(out / "side_by_side.mp4"))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
    capture.release()
