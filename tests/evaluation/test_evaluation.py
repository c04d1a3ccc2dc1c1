"""CDnet 2014 evaluation: counts, metrics, frame/pixel selection, datasets, real ground truth."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np
import pytest

from bgsub.errors import InputError
from bgsub.evaluation.cdnet import (
    Counts, Metrics, category_of, count_frame, evaluate, evaluate_dataset, evaluate_sequence,
    find_sequences, is_uniform_scale, metrics, open_ground_truth,
)
from bgsub.io.sources import output_size
from helpers import write_bins, write_gt_sequence, write_mask_video


def u8(rows: Sequence[Sequence[int]]) -> np.ndarray:
    return np.array(rows, np.uint8)


# The hand-computed case. Frames 1-4 exist, the temporal ROI is 2-3, ROI.bmp excludes column 4.
GT2 = u8([[0, 0, 50, 85, 255],
          [255, 255, 170, 0, 0],
          [0, 50, 255, 255, 170],
          [0, 0, 0, 0, 255]])
PRED2 = u8([[255, 0, 255, 255, 255],
            [255, 0, 255, 0, 0],
            [0, 0, 255, 0, 0],
            [0, 255, 0, 0, 0]])
# Columns 0-3 of frame 2, pixel by pixel (gt, pred):
#   row 0: (0,255) FP, (0,0) TN, (50,255) FP, (85,.) ignored
#   row 1: (255,255) TP, (255,0) FN, (170,.) ignored, (0,0) TN
#   row 2: (0,0) TN, (50,0) TN, (255,255) TP, (255,0) FN
#   row 3: (0,0) TN, (0,255) FP, (0,0) TN, (0,0) TN        -> TP 2, FP 3, FN 2, TN 7
GT3 = u8([[255, 255, 0, 0, 0]] * 4)
PRED3 = u8([[255, 0, 255, 0, 0],
            [255, 0, 0, 0, 0],
            [0, 0, 0, 0, 0],
            [0, 0, 0, 0, 0]])
# Frame 3, columns 0-3: 8 positives of which 2 found (TP 2, FN 6); 8 negatives, 1 marked
# (FP 1, TN 7). Frames 1 and 4 are outside the temporal ROI: an all-255 prediction there on
# all-0 ground truth would add 40 false positives if they were counted.
ROI = np.full((4, 5), 255, np.uint8)
ROI[:, 4] = 0
HAND_COUNTS = Counts(tp=4, fp=4, fn=8, tn=14)
HAND_METRICS = dict(recall=4 / 12, specificity=14 / 18, fpr=4 / 18, fnr=8 / 12,
                    pwc=100 * 12 / 30, precision=4 / 8, f_measure=0.4)


@pytest.fixture
def hand_case(tmp_path):
    zeros, ones = np.zeros((4, 5), np.uint8), np.full((4, 5), 255, np.uint8)
    gt = write_gt_sequence(tmp_path / "cat" / "seq", {1: zeros, 2: GT2, 3: GT3, 4: zeros},
                        temporal_roi=(2, 3), roi=ROI)
    pred = write_bins(tmp_path / "pred", {1: ones, 2: PRED2, 3: PRED3, 4: ones})
    return pred, gt


def test_hand_computed_counts_and_metrics(hand_case):
    pred, gt = hand_case
    result = evaluate_sequence(pred, gt)
    assert result.counts == HAND_COUNTS
    assert (result.n_frames, result.first_frame, result.last_frame) == (2, 2, 3)
    for name, value in HAND_METRICS.items():
        assert getattr(result.metrics, name) == pytest.approx(value, abs=1e-12), name


def test_roi_bmp_can_be_ignored(hand_case):
    pred, gt = hand_case
    result = evaluate_sequence(pred, gt, ignore_roi_bmp=True)
    # Column 4 joins: frame 2 (255,255) TP, (0,0) TN, 170 ignored, (255,0) FN; frame 3 four TN.
    assert result.counts == Counts(tp=5, fp=4, fn=9, tn=19)


def test_without_temporal_roi_every_gt_frame_counts(tmp_path):
    zeros, ones = np.zeros((4, 5), np.uint8), np.full((4, 5), 255, np.uint8)
    gt = write_gt_sequence(tmp_path / "seq", {1: zeros, 2: GT2})
    pred = write_bins(tmp_path / "pred", {1: ones, 2: PRED2})
    # Frame 1: 20 FP. Frame 2 over all 5 columns: TP 3, FP 3, FN 3, TN 8 (2 pixels ignored).
    assert evaluate_sequence(pred, gt).counts == Counts(tp=3, fp=23, fn=3, tn=8)


def test_sparse_ground_truth_is_scored_where_it_exists_and_said_so(tmp_path):
    ones = np.full((4, 5), 255, np.uint8)
    gt = write_gt_sequence(tmp_path / "seq", {1: GT2, 3: GT2, 4: GT2})  # no label for frame 2
    pred = write_bins(tmp_path / "pred", {1: PRED2, 2: ones, 3: PRED2, 4: PRED2})
    result = evaluate_sequence(pred, gt)
    assert result.n_frames == 3 and (result.first_frame, result.last_frame) == (1, 4)
    assert result.counts == Counts(tp=9, fp=9, fn=9, tn=24)  # frame 2's 20 FP not counted
    assert "no ground truth for 1 of the frames in that range" in result.notes


def test_frame_restrictions(hand_case):
    pred, gt = hand_case
    only3 = evaluate_sequence(pred, gt, first_frame=3)
    assert only3.counts == Counts(tp=2, fp=1, fn=6, tn=7) and only3.first_frame == 3
    assert evaluate_sequence(pred, gt, last_frame=2).counts == Counts(tp=2, fp=3, fn=2, tn=7)
    assert evaluate_sequence(pred, gt, frames=[3, 4]).counts == only3.counts  # 4: outside ROI
    with pytest.raises(InputError, match="no ground-truth frames"):
        evaluate_sequence(pred, gt, first_frame=4)
    # The temporal ROI (2-3) already leaves frame 1 out: skip_first changes nothing.
    assert evaluate_sequence(pred, gt, skip_first=True).counts == HAND_COUNTS


def test_skip_first_leaves_out_frame_1(tmp_path):
    zeros, ones = np.zeros((4, 5), np.uint8), np.full((4, 5), 255, np.uint8)
    gt = write_gt_sequence(tmp_path / "seq", {1: zeros, 2: GT2})
    pred = write_bins(tmp_path / "pred", {1: ones, 2: PRED2})
    result = evaluate_sequence(pred, gt, skip_first=True)
    assert (result.n_frames, result.first_frame) == (1, 2)
    assert result.counts == Counts(tp=3, fp=3, fn=3, tn=8)  # frame 2 alone


def test_undefined_metrics():
    nothing_to_find = metrics(Counts(tn=10))
    assert math.isnan(nothing_to_find.recall) and math.isnan(nothing_to_find.precision)
    assert math.isnan(nothing_to_find.f_measure) and nothing_to_find.specificity == 1.0
    missed_all = Counts(fn=5, tn=5).metrics()
    assert missed_all.f_measure == 0.0 and missed_all.recall == 0.0
    assert math.isnan(missed_all.precision)
    assert missed_all.as_dict()["precision"] is None


def test_metrics_mean_skips_undefined():
    a = Counts(tp=1, fn=1, tn=2).metrics()  # recall 0.5
    b = Counts(tn=4).metrics()  # recall undefined
    c = Counts(tp=1, fn=3, tn=4).metrics()  # recall 0.25
    assert Metrics.mean([a, b, c]).recall == pytest.approx(0.375)


def test_count_frame_matches_independent_numpy():
    rng = np.random.default_rng(3)
    labels = rng.choice(np.array([0, 50, 85, 170, 255], np.uint8), size=(37, 53))
    pred = rng.integers(0, 256, (37, 53)).astype(np.uint8)
    roi = rng.random((37, 53)) > 0.3
    p, valid = pred > 127, roi & np.isin(labels, [0, 50, 255])
    pos, neg = valid & (labels == 255), valid & np.isin(labels, [0, 50])
    expected = Counts(tp=int((p & pos).sum()), fp=int((p & neg).sum()),
                      fn=int((~p & pos).sum()), tn=int((~p & neg).sum()))
    assert count_frame(pred, labels, roi) == expected


def test_values_other_than_cdnet_labels_rejected(tmp_path):
    bad = GT2.copy()
    bad[0, 0] = 128
    gt = write_gt_sequence(tmp_path / "seq", {1: bad})
    pred = write_bins(tmp_path / "pred", {1: PRED2})
    with pytest.raises(InputError, match=r"gt000001\.png.*\[128\]"):
        evaluate_sequence(pred, gt)


def test_colour_ground_truth_with_equal_channels_accepted(tmp_path):
    gt = write_gt_sequence(tmp_path / "seq", {2: cv2.cvtColor(GT2, cv2.COLOR_GRAY2BGR)})
    pred = write_bins(tmp_path / "pred", {2: PRED2})
    assert evaluate_sequence(pred, gt).counts == Counts(tp=3, fp=3, fn=3, tn=8)


def test_missing_frame_reported(hand_case):
    pred, gt = hand_case
    (pred / "bin000003.png").unlink()
    with pytest.raises(InputError, match=r"1 of 2 frames.*bin000003\.png.*--allow-missing"):
        evaluate_sequence(pred, gt)
    result = evaluate_sequence(pred, gt, allow_missing=True)
    assert result.missing == [3]
    # Frame 3 counted as all background: its 8 positives are false negatives.
    assert result.counts == Counts(tp=2, fp=3, fn=2 + 8, tn=7 + 8)


def test_size_mismatch_names_both_sizes(tmp_path):
    gt = write_gt_sequence(tmp_path / "seq", {1: GT2})
    # 10x4 is no scale of 5x4 (7x6 would be: 5x4 times 1.4, rounded).
    pred = write_bins(tmp_path / "pred", {1: np.zeros((4, 10), np.uint8)})
    with pytest.raises(InputError, match=r"10x4.*5x4"):
        evaluate_sequence(pred, gt)


@pytest.mark.parametrize("width, height", [(321, 239), (320, 240), (352, 288), (97, 61)])
def test_every_size_bgsub_run_resizes_to_is_a_uniform_scale(width, height):
    sizes = [output_size(width, height, target_width=w) for w in range(13, 2 * width, 3)]
    sizes += [output_size(width, height, scale=s) for s in np.arange(0.05, 2.0, 0.0125)]
    assert all(is_uniform_scale(size, (width, height)) for size in sizes)


def test_other_sizes_are_not_a_uniform_scale():
    assert not is_uniform_scale((352, 240), (320, 240))  # CDnet traffic's ROI.bmp
    assert not is_uniform_scale((160, 121), (320, 240))  # 1 pixel more than the rounding gives
    assert not is_uniform_scale((120, 160), (320, 240))  # turned


def test_prediction_at_a_scale_of_the_ground_truth_is_scaled_back(tmp_path):
    """Masks of `bgsub run --scale 0.5` score as the same masks at full size, with one note."""
    rng = np.random.default_rng(5)
    labels = {n: rng.choice(np.array([0, 50, 170, 255], np.uint8), size=(24, 32))
              for n in (1, 2)}
    half = {n: np.where(rng.random((12, 16)) > 0.5, 255, 0).astype(np.uint8) for n in (1, 2)}
    gt = write_gt_sequence(tmp_path / "seq", labels)
    pred = write_bins(tmp_path / "pred", half)
    # Nearest neighbour at exactly twice the size: every pixel becomes a 2x2 block.
    full = {n: m.repeat(2, axis=0).repeat(2, axis=1) for n, m in half.items()}
    result = evaluate_sequence(pred, gt)
    assert result.counts == evaluate_sequence(full, gt).counts
    assert [n for n in result.notes if "scaled" in n] == ["16x12 predictions scaled to 32x24 "
                                                          "(nearest neighbour)"]


def test_roi_bmp_of_wrong_size(tmp_path):
    gt = write_gt_sequence(tmp_path / "seq", {1: GT2}, roi=np.full((4, 6), 255, np.uint8))
    pred = write_bins(tmp_path / "pred", {1: PRED2})
    with pytest.raises(InputError, match=r"ROI\.bmp is 6x4.*5x4.*--no-roi-bmp"):
        evaluate_sequence(pred, gt)
    assert evaluate_sequence(pred, gt, ignore_roi_bmp=True).n_frames == 1


def _video_case(tmp_path, n_video_frames: int):
    """GT frames 1-6 (temporal ROI 2-6) of 32x24 and a lossless mask video of the predictions."""
    from bgsub.io.sinks import open_mask_sink

    rng = np.random.default_rng(7)
    gts = {n: rng.choice(np.array([0, 50, 170, 255], np.uint8), size=(24, 32)) for n in range(1, 7)}
    preds = {n: np.where(rng.random((24, 32)) > 0.5, 255, 0).astype(np.uint8)
             for n in range(1, 7)}
    gt = write_gt_sequence(tmp_path / "seq", gts, temporal_roi=(2, 6))
    video = tmp_path / "masks.mkv"
    with open_mask_sink(video, width=32, height=24, fps=25.0) as sink:
        for n in range(1, n_video_frames + 1):
            sink.write(preds[n], n - 1)
    folder = write_bins(tmp_path / "bins", preds)
    return video, folder, gt


def test_mask_video_input(tmp_path):
    video, folder, gt = _video_case(tmp_path, 6)
    from_video = evaluate_sequence(video, gt)
    assert from_video.counts == evaluate_sequence(folder, gt).counts
    assert from_video.n_frames == 5 and from_video.counts.total > 0


def test_short_mask_video_reported(tmp_path):
    video, _, gt = _video_case(tmp_path, 4)
    with pytest.raises(InputError, match=r"ends after frame 4.*frames up to 6.*2 of 5"):
        evaluate_sequence(video, gt)
    assert evaluate_sequence(video, gt, allow_missing=True).missing == [5, 6]


def test_short_mask_video_message_names_the_run_flags(tmp_path):
    video, _, gt = _video_case(tmp_path, 4)
    with pytest.raises(InputError, match=r"no frame numbers.*--start/--step/--stop"):
        evaluate_sequence(video, gt)


def _ranged_video(tmp_path, indices: Sequence[int]):
    """GT frames 1-10 (32x24, random labels), the masks of all of them as bin pngs, and a mask
    video of the masks of the 0-based input ``indices`` only (what `bgsub run --start
    --step --stop` writes)."""
    from bgsub.io.sinks import open_mask_sink

    rng = np.random.default_rng(11)
    numbers = range(1, 11)
    gts = {n: rng.choice(np.array([0, 50, 170, 255], np.uint8), size=(24, 32)) for n in numbers}
    preds = {n: np.where(rng.random((24, 32)) > 0.5, 255, 0).astype(np.uint8) for n in numbers}
    gt = write_gt_sequence(tmp_path / "seq", gts)
    video = tmp_path / "masks.mkv"
    with open_mask_sink(video, width=32, height=24, fps=25.0) as sink:
        for index in indices:
            sink.write(preds[index + 1], index)
    return video, write_bins(tmp_path / "bins", preds), gt


def test_mask_video_start_and_step_pair_its_frames_with_the_right_ground_truth(tmp_path):
    video, bins, gt = _ranged_video(tmp_path, range(2, 10, 3))  # frames 3, 6, 9
    result = evaluate_sequence(video, gt, video_start=2, video_step=3)
    assert (result.n_frames, result.first_frame, result.last_frame) == (3, 3, 9)
    assert result.missing == [] and result.counts.total > 0
    assert result.counts == evaluate_sequence(bins, gt, frames=[3, 6, 9]).counts
    assert not any("no ground truth" in n for n in result.notes)  # the step is no gap


def test_mask_video_stop_ends_the_frames_and_skip_first_drops_its_first(tmp_path):
    video, bins, gt = _ranged_video(tmp_path, range(4, 8))  # frames 5-8
    result = evaluate_sequence(video, gt, video_start=4, video_stop=8, skip_first=True)
    assert (result.first_frame, result.last_frame, result.missing) == (6, 8, [])
    assert result.counts == evaluate_sequence(bins, gt, frames=[6, 7, 8]).counts


def test_a_folder_range_selects_the_frames_bgsub_run_read(tmp_path):
    """The masks `bgsub run --start 1 --step 3` writes to a folder (bin000002.png,
    bin000005.png, ...) score with the same flags, as the same masks in a video do."""
    video, bins, gt = _ranged_video(tmp_path, range(1, 10, 3))  # frames 2, 5, 8
    stepped = write_bins(tmp_path / "stepped", {n: cv2.imread(str(bins / f"bin{n:06d}.png"),
                                                              cv2.IMREAD_GRAYSCALE)
                                                for n in (2, 5, 8)})
    result = evaluate_sequence(stepped, gt, video_start=1, video_step=3)
    assert (result.n_frames, result.first_frame, result.last_frame) == (3, 2, 8)
    assert result.missing == [] and result.counts.total > 0
    assert result.counts == evaluate_sequence(video, gt, video_start=1, video_step=3).counts
    assert result.counts == evaluate_sequence(bins, gt, frames=[2, 5, 8]).counts
    assert not any("no ground truth" in n for n in result.notes)  # the step is no gap
    # --stop and skip_first as for a video: of frames 2 and 5 (indices 1, 4 < 7), frame 5.
    assert evaluate_sequence(bins, gt, video_start=1, video_step=3, video_stop=7,
                             skip_first=True).counts == evaluate_sequence(
        bins, gt, frames=[5]).counts
    with pytest.raises(InputError, match=r"--step 2.*masks from Python"):
        evaluate_sequence({1: GT2}, gt, video_step=2)


def _ten_frames(tmp_path, numbers):
    """GT frames 1-10 (GT3) and a folder of perfect masks of ``numbers`` only."""
    gt = write_gt_sequence(tmp_path / "seq", {n: GT3 for n in range(1, 11)})
    return write_bins(tmp_path / "pred", {n: GT3 for n in numbers}), gt


@pytest.mark.parametrize("numbers, options, flags", [
    (range(4, 8), {}, dict(first_frame=4, last_frame=7)),  # `run --start 3 --stop 7`
    (range(1, 8), {}, dict(last_frame=7)),  # a run stopped early
    (range(1, 11, 2), {}, dict(video_step=2)),  # `run --step 2`
    (range(2, 11, 2), dict(video_step=2), dict(video_start=1, video_step=2)),  # wrong phase
    (range(3, 9, 2), {}, dict(video_start=2, video_step=2, video_stop=7)),
])
def test_missing_masks_of_one_run_name_the_options_that_score_just_them(tmp_path, numbers,
                                                                         options, flags):
    pred, gt = _ten_frames(tmp_path, numbers)
    with pytest.raises(InputError) as caught:
        evaluate_sequence(pred, gt, **options)
    message = str(caught.value)
    named = " ".join(f"--{k.replace('video_', '').replace('_', '-')} {v}"
                     for k, v in flags.items())
    assert f"to score just the frames with a mask ({len(numbers)}, " in message
    assert message.count(named) == 1 and message.endswith(
        "without one as background") and "--allow-missing" in message
    # Following it scores exactly those masks: perfect.
    result = evaluate_sequence(pred, gt, **flags)
    assert result.missing == [] and result.n_frames == len(numbers)
    assert result.metrics.f_measure == 1.0
    # With --allow-missing the result keeps the hint for the warning.
    assert evaluate_sequence(pred, gt, allow_missing=True, **options).missing_hint.endswith(
        f"use {named}")


def test_with_skip_first_the_hint_leaves_out_the_masks_first_frame(tmp_path):
    # Masks of `run --start 3 --stop 7` (frames 4-7) scored with --skip-first: the frame to
    # leave out is 4, the first the run's model met, which --first-frame 4 would keep.
    pred, gt = _ten_frames(tmp_path, range(4, 8))
    with pytest.raises(InputError) as caught:
        evaluate_sequence(pred, gt, skip_first=True)
    assert "use --start 3 --stop 7" in str(caught.value)
    result = evaluate_sequence(pred, gt, skip_first=True, video_start=3, video_stop=7)
    assert result.first_frame == 5 and result.n_frames == 3


def test_missing_masks_with_holes_suggest_only_allow_missing(tmp_path):
    pred, gt = _ten_frames(tmp_path, [1, 2, 3, 5, 6])
    with pytest.raises(InputError) as caught:
        evaluate_sequence(pred, gt)
    assert str(caught.value).endswith("; use --allow-missing to count them as background")
    assert "to score just" not in str(caught.value)
    assert evaluate_sequence(pred, gt, allow_missing=True).missing_hint == ""


def test_a_mask_video_longer_than_the_ground_truth_is_scored_with_a_warning(tmp_path):
    video, _, gt = _video_case(tmp_path, 6)  # 6 frames: as long as the ground truth
    assert evaluate_sequence(video, gt).warnings == []
    from bgsub.io.sinks import open_mask_sink
    longer = tmp_path / "longer.mkv"
    with open_mask_sink(longer, width=32, height=24, fps=25.0) as sink:
        for k in range(9):
            sink.write(np.zeros((24, 32), np.uint8), k)
    # The frames with ground truth are scored as before, with a warning saying the counts.
    result = evaluate_sequence(longer, gt)
    assert result.n_frames == 5 and result.missing == []
    (warning,) = result.warnings
    assert "longer.mkv holds 9 frames, past the end of the ground truth" in warning
    assert "has 6 ground-truth frames, up to gt000006.png" in warning
    assert result.to_dict()["warnings"] == [warning]
    # Also when reading stops earlier (--last-frame): the container's count is confirmed.
    assert evaluate_sequence(longer, gt, last_frame=3).warnings == [warning]
    # Read with --step 2, 9 frames are frames 1-17: still past; with --stop 6 they are not.
    (stepped,) = evaluate_sequence(longer, gt, video_step=2).warnings
    assert "holds 9 frames (frames 1-17 read with --step 2)" in stepped
    assert evaluate_sequence(longer, gt, video_stop=6).warnings == []


def test_masks_numbered_past_the_ground_truth_are_scored_with_a_warning(tmp_path):
    pred, gt = _ten_frames(tmp_path, range(1, 15))
    result = evaluate_sequence(pred, gt)
    assert result.n_frames == 10 and result.metrics.f_measure == 1.0
    (warning,) = result.warnings
    assert warning.startswith("4 of the 14 masks in ") and "(up to bin000014.png; " in warning
    assert "has 10 ground-truth frames, up to gt000010.png" in warning
    assert evaluate_sequence(_ten_frames(tmp_path / "b", range(1, 11))[0], gt).warnings == []


@pytest.mark.parametrize("options, words", [
    (dict(video_start=-1), r"start \(--start\) takes a 0-based frame index >= 0"),
    (dict(video_step=0), r"step \(--step\) must be at least 1"),
    (dict(video_start=5, video_stop=5), r"stop \(--stop, 5\) must be after start \(5\)"),
])
def test_invalid_video_frame_range(tmp_path, options, words):
    video, _, gt = _ranged_video(tmp_path, range(10))
    with pytest.raises(InputError, match=words):
        evaluate_sequence(video, gt, **options)


def test_python_masks_input(hand_case):
    _, gt = hand_case
    masks = ((n, m) for n, m in [(2, PRED2), (3, PRED3)])  # a generator, consumed once
    assert evaluate_sequence(masks, gt).counts == HAND_COUNTS


@pytest.mark.parametrize("first", [0, -1])
def test_a_frame_number_below_1_is_refused_as_a_0_based_index(hand_case, first):
    # 0-based indices (FrameSource's) would pair each mask with the frame before its own, the
    # mask numbered 0 silently left out.
    _, gt = hand_case
    masks = ((first + k, m) for k, m in enumerate([PRED2, PRED2, PRED3]))
    with pytest.raises(InputError, match=rf"frame number {first}: CDnet frame numbers start "
                                         r"at 1 \(in000001.jpg is frame 1\)"):
        evaluate_sequence(masks, gt, allow_missing=True)


def test_zero_one_masks_are_refused_not_scored_as_background(hand_case, tmp_path):
    _, gt = hand_case
    slip = {2: (PRED2 > 127).astype(np.uint8), 3: (PRED3 > 127).astype(np.uint8)}
    with pytest.raises(InputError, match=r"holds 0/1 values; masks are 0/255"):
        evaluate_sequence(slip, gt)
    write_bins(tmp_path / "pngs", slip)  # the same slip written to PNGs
    with pytest.raises(InputError, match=r"bin000002.png\) holds 0/1 values"):
        evaluate_sequence(tmp_path / "pngs", gt)
    as_bool = {n: m.astype(bool) for n, m in slip.items()}
    assert evaluate_sequence(as_bool, gt).counts == HAND_COUNTS


def test_categories():
    assert category_of("BMS26_cars1") == "BMS26"
    assert category_of("static_s1") == "static"
    assert category_of("pan-zoom_s12") == "pan-zoom"
    assert category_of("cameraJitter/traffic") == "cameraJitter"
    assert category_of("highway") == "highway"
    # The family is the prefix before the first '_', so a long name keeps its dataset's family.
    assert category_of("CDnet2014_cameraJitter_traffic") == "CDnet2014"
    assert category_of("DAVIS2016_car-roundabout") == "DAVIS2016"


def test_dataset_averaging_the_cdnet_way(tmp_path):
    """Categories = mean of sequences, overall = mean of categories (not pooled counts)."""
    gt_root, pred_root = tmp_path / "gt", tmp_path / "pred"
    gt = u8([[255, 255, 0, 0]] * 2)  # 4 positives, 4 negatives
    cases = {  # sequence -> prediction; recall 1, 0.5 in category A; 0.25 in B
        "catA/one": u8([[255, 255, 0, 0]] * 2),
        "catA/two": u8([[255, 0, 0, 0]] * 2),
        "catB/three": u8([[255, 0, 0, 0], [0, 0, 0, 0]]),
    }
    for rel, pred in cases.items():
        write_gt_sequence(gt_root / rel, {1: gt})
        write_bins(pred_root / Path(rel).name, {1: pred})
    result = evaluate(pred_root, gt_root)
    assert [s.name for s in result.sequences] == ["one", "two", "three"]
    by_name = {c.name: c for c in result.categories}
    assert by_name["catA"].metrics.recall == pytest.approx(0.75)
    assert by_name["catB"].metrics.recall == pytest.approx(0.25)
    assert result.overall.recall == pytest.approx(0.5)  # pooled counts would give 7/12
    assert by_name["catA"].counts == Counts(tp=6, fp=0, fn=2, tn=8)


def test_dataset_finds_mirrored_layout_and_videos(tmp_path):
    gt_root, pred_root = tmp_path / "gt", tmp_path / "pred"
    gt = np.zeros((16, 16), np.uint8)
    write_gt_sequence(gt_root / "a" / "deep" / "seq", {1: gt})
    write_gt_sequence(gt_root / "fam_x", {1: gt})
    write_bins(pred_root / "a" / "deep" / "seq", {1: gt})
    write_bins(pred_root / "fam_x", {1: gt})
    assert [p.name for p in find_sequences(gt_root)] == ["seq", "fam_x"]
    result = evaluate_dataset(pred_root, gt_root)
    assert {s.name: s.category for s in result.sequences} == {"seq": "deep", "fam_x": "fam"}


def test_dataset_missing_sequence_prediction(tmp_path):
    gt_root, pred_root = tmp_path / "gt", tmp_path / "pred"
    write_gt_sequence(gt_root / "c" / "s1", {1: GT3})
    write_gt_sequence(gt_root / "c" / "s2", {1: GT3})
    write_bins(pred_root / "s1", {1: GT3})
    with pytest.raises(InputError, match=r"1 of 2 sequences \(c/s2\)"):
        evaluate_dataset(pred_root, gt_root)
    result = evaluate_dataset(pred_root, gt_root, allow_missing=True)
    assert result.sequences[1].missing == [1] and result.sequences[1].metrics.recall == 0.0


def test_not_a_sequence(tmp_path):
    with pytest.raises(InputError, match="groundtruth"):
        open_ground_truth(tmp_path)
    with pytest.raises(InputError, match="no CDnet sequences"):
        evaluate(tmp_path, tmp_path)


TRAFFIC = "real/CDnet2014_cameraJitter_traffic"
TRAFFIC_FRAMES = (960, 1000, 1100, 1480, 1540)  # inside the temporal ROI, all five labels but 85


def test_real_cdnet_ground_truth_scores_itself_perfectly(shared_data, tmp_path):
    source = shared_data / TRAFFIC
    gt = tmp_path / "traffic"
    (gt / "groundtruth").mkdir(parents=True)
    shutil.copy(source / "temporalROI.txt", gt)
    shutil.copy(source / "ROI.bmp", gt)  # the real, malformed one (352x240)
    expected = Counts()
    masks = {}
    for n in (899,) + TRAFFIC_FRAMES:  # 899: all 85, outside the temporal ROI
        name = f"gt{n:06d}.png"
        shutil.copy(source / "groundtruth" / name, gt / "groundtruth")
        labels = cv2.imread(str(source / "groundtruth" / name), cv2.IMREAD_GRAYSCALE)
        masks[n] = np.where(labels == 255, 255, 0).astype(np.uint8)
        if n in TRAFFIC_FRAMES:
            counted = (labels == 0) | (labels == 50) | (labels == 255)
            expected += Counts(tp=int((labels == 255).sum()), fp=0, fn=0,
                               tn=int((counted & (labels != 255)).sum()))
    pred = write_bins(tmp_path / "pred", masks)
    with pytest.raises(InputError, match="352x240"):
        evaluate_sequence(pred, gt)
    result = evaluate_sequence(pred, gt, ignore_roi_bmp=True)
    assert result.n_frames == len(TRAFFIC_FRAMES)
    assert result.counts == expected
    assert result.counts.total < len(TRAFFIC_FRAMES) * 320 * 240  # the 170 pixels left out
    m = result.metrics
    assert (m.recall, m.specificity, m.precision, m.f_measure) == (1.0, 1.0, 1.0, 1.0)
    assert (m.fpr, m.fnr, m.pwc) == (0.0, 0.0, 0.0)


def test_python_bool_masks_and_bad_dtype(hand_case):
    _, gt = hand_case
    as_bool = {2: PRED2 > 127, 3: PRED3 > 127}
    assert evaluate_sequence(as_bool, gt).counts == HAND_COUNTS
    with pytest.raises(InputError, match="float64"):
        evaluate_sequence({2: PRED2 / 255.0, 3: PRED3 / 255.0}, gt)


def test_a_temporal_roi_that_is_a_folder_is_an_error_not_ignored(tmp_path):
    gt = write_gt_sequence(tmp_path / "seq", {1: np.zeros((4, 5), np.uint8)})
    (gt / "temporalROI.txt").mkdir()
    with pytest.raises(InputError, match=r"temporalROI\.txt is not a file"):
        open_ground_truth(gt)


def test_a_sequence_without_prediction_counts_only_the_frames_the_videos_hold(tmp_path):
    """With --step 2 --allow-missing, a sequence with no mask video is scored on the frames the
    others' videos hold, not on every frame."""
    from bgsub.io.sinks import open_mask_sink

    gt_root, pred_root = tmp_path / "gt", tmp_path / "pred"
    labels = {n: np.full((16, 16), 255, np.uint8) for n in range(1, 9)}
    write_gt_sequence(gt_root / "c" / "s1", labels)
    write_gt_sequence(gt_root / "c" / "s2", labels)
    pred_root.mkdir()
    with open_mask_sink(pred_root / "s1.mkv", width=16, height=16, fps=25.0) as sink:
        for index in range(0, 8, 2):
            sink.write(labels[index + 1], index)
    result = evaluate_dataset(pred_root, gt_root, allow_missing=True, video_step=2)
    held, missing = result.sequences
    assert held.n_frames == missing.n_frames == 4
    assert missing.missing == [1, 3, 5, 7]


@pytest.mark.parametrize("pred, gt", [("", "seq"), ("pred", "")])
def test_an_empty_path_is_refused_not_read_as_the_current_folder(tmp_path, pred, gt):
    write_gt_sequence(tmp_path / "seq", {1: GT2})
    write_bins(tmp_path / "pred", {1: PRED2})
    pred = str(tmp_path / pred) if pred else pred
    gt = str(tmp_path / gt) if gt else gt
    with pytest.raises(InputError, match="path is empty"):
        evaluate(pred, gt)


def test_a_video_range_outside_the_selected_frames_names_both(tmp_path):
    video, _, gt = _ranged_video(tmp_path, range(2))  # the masks of frames 1-2
    with pytest.raises(InputError, match=r"--stop 2\).*selected frames are 5-10"):
        evaluate_sequence(video, gt, video_stop=2, first_frame=5)


# ------------------------------------------------- messages that say what went wrong, --method


def test_first_frame_after_last_frame_says_so(hand_case):
    pred, gt = hand_case
    with pytest.raises(InputError, match=r"first_frame \(--first-frame 3\) is after last_frame "
                                         r"\(--last-frame 2\)"):
        evaluate_sequence(pred, gt, first_frame=3, last_frame=2)
    assert evaluate_sequence(pred, gt, first_frame=3, last_frame=3).n_frames == 1


def _compare_report(tmp_path):
    """A sequence (frames 1-2 of 16x16) and the layout `bgsub compare` writes for it: one
    mask set per method, a .mkv for "good" (perfect) and a bin png folder for "empty"."""
    gt_frame = np.zeros((16, 16), np.uint8)
    gt_frame[4:12, 4:12] = 255
    gt = write_gt_sequence(tmp_path / "scenes" / "pan_s0", {1: gt_frame, 2: gt_frame})
    report = tmp_path / "cmp" / "pan_s0"
    report.mkdir(parents=True)
    write_mask_video(report / "good.mkv", [gt_frame, gt_frame])
    write_bins(report / "empty", {1: 0 * gt_frame, 2: 0 * gt_frame})
    (report.parent / "report.txt").write_text("")
    return report, gt


def test_a_compare_report_folder_is_refused_saying_what_it_holds(tmp_path):
    report, gt = _compare_report(tmp_path)
    with pytest.raises(InputError) as caught:
        evaluate_sequence(report, gt)
    message = str(caught.value)
    assert f"no binNNNNNN.png masks in {report}: it holds the mask sets empty/, good.mkv" in message
    assert "(`bgsub compare` writes one per method)" in message and "--method empty" in message
    assert f"`bgsub eval {report / 'empty/'} {gt}`" in message


@pytest.mark.parametrize("content, words", [
    ({}, "(the folder is empty)"),
    ({"in000001.jpg": b"x", "notes.txt": b"y"}, "(none of its 2 files and folders is one)"),
])
def test_a_folder_without_masks_says_what_it_holds(tmp_path, content, words):
    gt = write_gt_sequence(tmp_path / "seq", {1: GT3})
    folder = tmp_path / "pred"
    folder.mkdir()
    for name, data in content.items():
        (folder / name).write_bytes(data)
    with pytest.raises(InputError, match=re.escape(f"no binNNNNNN.png masks in {folder} {words}")):
        evaluate_sequence(folder, gt)


def test_masks_numbered_from_1_for_later_frames_hint_at_the_numbering(tmp_path):
    gt = write_gt_sequence(tmp_path / "seq", {n: GT3 for n in range(20, 23)})
    # What `bgsub run 'input/in00002*.jpg'` writes: the same frames, numbered from 1.
    pred = write_bins(tmp_path / "pred", {n: GT3 for n in range(1, 4)})
    with pytest.raises(InputError) as caught:
        evaluate_sequence(pred, gt)
    message = str(caught.value)
    assert message.startswith("3 of 3 frames to evaluate have no prediction")
    assert "the folder's masks are numbered 1-3" in message and "by position" in message
    # Some of the wanted numbers there: a plain gap, no numbering hint.
    write_bins(tmp_path / "more", {n: GT3 for n in (1, 20)})
    with pytest.raises(InputError) as caught:
        evaluate_sequence(tmp_path / "more", gt)
    assert "2 of 3 frames" in str(caught.value) and "masks are numbered" not in str(caught.value)


def test_method_picks_one_mask_set_of_a_compare_report(tmp_path):
    report, gt = _compare_report(tmp_path)
    good = evaluate(report, gt, method="good")
    assert good.overall.f_measure == pytest.approx(1.0)
    assert good.sequences[0].pred_path == str(report / "good.mkv")
    empty = evaluate(report, gt, method="empty")
    assert empty.overall.recall == 0.0
    # A dataset: the method's masks in each sequence's folder of the report.
    dataset = evaluate(report.parent, gt.parent, method="good")
    assert [s.name for s in dataset.sequences] == ["pan_s0"]
    assert dataset.overall.f_measure == pytest.approx(1.0)


@pytest.mark.parametrize("method, pred, words", [
    ("knn", "report", "no masks of method 'knn' in"),
    ("knn", "report", "it holds the methods empty, good"),
    ("", "report", "method (--method) is empty"),
    ("a/b", "report", "not a path"),
    ("good", "video", "is not a folder"),
])
def test_method_refusals(tmp_path, method, pred, words):
    report, gt = _compare_report(tmp_path)
    path = report if pred == "report" else report / "good.mkv"
    with pytest.raises(InputError, match=re.escape(words)):
        evaluate(path, gt, method=method)


@pytest.mark.parametrize("allow_missing", [False, True])
def test_a_method_no_sequence_has_is_refused_naming_those_there(tmp_path, allow_missing):
    """A misspelt method: --allow-missing would only score every sequence as empty."""
    report, gt = _compare_report(tmp_path)
    with pytest.raises(InputError, match=r"no masks of method 'knn' in .* for any of its 1 "
                                         r"sequences; it holds the methods empty, good"):
        evaluate(report.parent, gt.parent, method="knn", allow_missing=allow_missing)


def test_a_method_some_sequences_lack_can_be_counted_as_background(tmp_path):
    report, gt = _compare_report(tmp_path)
    other = write_gt_sequence(gt.parent / "static_s0", {1: np.zeros((16, 16), np.uint8)})
    write_bins(report.parent / other.name / "empty", {1: np.zeros((16, 16), np.uint8)})
    with pytest.raises(InputError, match=r"no prediction of method 'good' in .* for 1 of 2 "
                                         r"sequences .*static_s0.*--allow-missing"):
        evaluate(report.parent, gt.parent, method="good")
    result = evaluate(report.parent, gt.parent, method="good", allow_missing=True)
    assert len(result.sequences) == 2
