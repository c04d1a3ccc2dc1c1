"""Evaluation edge cases: bin000000.png, masks past sparse ground truth, the video suffix list."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Optional, Tuple

import numpy as np
import pytest

from bgsub.evaluation import cdnet as evaluation
from bgsub.io import flowio, sources
from bgsub.cli import main
from bgsub.errors import InputError
from bgsub.evaluation.cdnet import evaluate_sequence, find_prediction, open_ground_truth
from helpers import write_bins, write_gt_sequence, write_input_sequence, write_mask_video

# One labelled frame (4x5, two object columns) and its perfect 0/255 mask.
GT3 = np.array([[255, 255, 0, 0, 0]] * 4, np.uint8)
MASK = np.where(GT3 == 255, 255, 0).astype(np.uint8)


def _case(tmp_path: Path, gt_numbers: Iterable[int], mask_numbers: Iterable[int], *,
          temporal_roi: Optional[Tuple[int, int]] = None) -> Tuple[Path, Path]:
    """A sequence with ground truth for ``gt_numbers`` and a folder of perfect masks."""
    gt = write_gt_sequence(tmp_path / "seq", {n: GT3 for n in gt_numbers}, temporal_roi=temporal_roi)
    return write_bins(tmp_path / "pred", {n: MASK for n in mask_numbers}), gt


# --- bin000000.png -------------------------------------------------------------------------


def test_a_bin000000_png_is_ignored_with_one_warning(tmp_path):
    pred, gt = _case(tmp_path, range(1, 11), range(0, 11))  # 1-10 and one more, numbered 0
    result = evaluate_sequence(pred, gt)
    assert result.n_frames == 10 and result.metrics.f_measure == 1.0
    (warning,) = result.warnings
    assert warning.startswith(f"bin000000.png in {pred} is not a CDnet frame number (they "
                              "start at 1: bin000001.png is the mask of in000001.jpg) and was "
                              "ignored; the masks may be numbered from 0")
    assert "\n" not in warning and "renumber" not in warning  # bin1-bin10 are all there


def test_masks_numbered_from_0_are_named_shifted_with_the_fix(tmp_path):
    # bin000000-bin000009 for ground truth 1-10, temporal ROI 1-9: every frame scored has a mask,
    # each of the frame after it.
    pred, gt = _case(tmp_path, range(1, 11), range(0, 10), temporal_roi=(1, 9))
    (warning,) = evaluate_sequence(pred, gt).warnings
    assert ("and was ignored: the masks bin000000.png-bin000009.png look numbered from 0 for the "
            "ground truth's frames 1-10, so each is paired with the ground truth of the "
            "frame before its own; renumber them from 1 (binK.png -> bin(K+1).png, as `bgsub "
            "run` writes them)") in warning


def test_masks_numbered_from_0_missing_the_last_frame_say_why_not_which_range(tmp_path):
    pred, gt = _case(tmp_path, range(1, 11), range(0, 10))
    with pytest.raises(InputError) as caught:
        evaluate_sequence(pred, gt)
    text = str(caught.value)
    assert text.startswith("1 of 10 frames to evaluate have no prediction")
    # The error carries the warning (an error drops the warnings) and no option that would
    # score the masks against the wrong frames all the same.
    assert text.endswith("renumber them from 1 (binK.png -> bin(K+1).png, as `bgsub run` "
                         "writes them)")
    assert "--last-frame" not in text and "--allow-missing" not in text
    result = evaluate_sequence(pred, gt, allow_missing=True)
    assert result.missing == [10] and result.missing_hint == ""
    assert len(result.warnings) == 1 and "look numbered from 0" in result.warnings[0]


def test_a_bin000000_png_alone_is_refused_in_one_line(tmp_path):
    pred, gt = _case(tmp_path, range(1, 4), [0])
    with pytest.raises(InputError, match=r"the only mask in .* is bin000000.png, but CDnet "
                                         r"numbers frames from 1 .*: renumber the masks from 1$"):
        evaluate_sequence(pred, gt)


def test_eval_prints_the_bin000000_warning_once_on_one_line(tmp_path, capsys):
    pred, gt = _case(tmp_path, range(1, 11), range(0, 10), temporal_roi=(1, 9))
    assert main(["eval", str(pred), str(gt), "-q"]) == 0
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("bgsub: warning: seq: bin000000.png in ") and "renumber" in line


# --- masks past the end of the ground truth --------------------------------------------------


@pytest.mark.parametrize("gt_numbers, temporal_roi, end", [
    (range(1, 11), None, 10),  # CDnet's layout: a file for every frame
    (range(1, 11), (3, 8), 10),  # frames outside the temporal ROI have files too
    (range(1, 6), (1, 20), 20),  # a temporal ROI past the last file: the input goes on
    (range(10, 101, 10), None, None),  # every 10th frame labelled: a sample, not the length
    (range(20, 61), (20, 60), None),  # a labelled window of the input
    ([1, 2, 3, 5, 6], None, None),  # a gap
])
def test_the_ground_truth_states_the_inputs_end_only_when_it_labels_every_frame(
        tmp_path, gt_numbers, temporal_roi, end):
    gt = write_gt_sequence(tmp_path / "seq", {n: GT3 for n in gt_numbers}, temporal_roi=temporal_roi)
    assert open_ground_truth(gt).sequence_end == end


@pytest.mark.parametrize("gt_numbers, temporal_roi, scored", [
    (range(10, 101, 10), None, 10),  # sparse: labels every 10th of 105 frames
    (range(20, 61), (20, 60), 41),  # labels only the temporal ROI of a 105-frame input
])
def test_masks_past_sparse_ground_truth_are_not_warned_about(tmp_path, gt_numbers,
                                                             temporal_roi, scored):
    pred, gt = _case(tmp_path, gt_numbers, range(1, 106), temporal_roi=temporal_roi)
    result = evaluate_sequence(pred, gt)
    assert result.n_frames == scored and result.metrics.f_measure == 1.0
    assert result.warnings == []


def test_masks_past_dense_ground_truth_are_still_warned_about(tmp_path):
    pred, gt = _case(tmp_path, range(1, 11), range(1, 15))
    (warning,) = evaluate_sequence(pred, gt).warnings
    assert warning.startswith("4 of the 14 masks in ")
    assert f"{gt} has 10 ground-truth frames, up to gt000010.png): check" in warning


def test_masks_count_as_past_the_end_only_past_a_later_temporal_roi_end(tmp_path):
    pred, gt = _case(tmp_path, range(1, 6), range(1, 21), temporal_roi=(1, 20))
    assert evaluate_sequence(pred, gt).warnings == []
    longer = write_bins(tmp_path / "longer", {n: MASK for n in range(1, 23)})
    (warning,) = evaluate_sequence(longer, gt).warnings
    assert warning.startswith("2 of the 22 masks in ") and "(up to bin000022.png; " in warning
    assert "up to gt000005.png, and its temporal ROI ends at frame 20)" in warning


@pytest.mark.parametrize("gt_numbers, warned", [
    (range(1, 7), True),  # dense: 9 frames for 6 is another clip's length
    (range(2, 7, 2), False),  # every other frame: the labels stop, the clip need not
])
def test_a_longer_mask_video_is_warned_about_only_against_dense_ground_truth(tmp_path,
                                                                              gt_numbers, warned):
    blank = np.zeros((24, 32), np.uint8)
    gt = write_gt_sequence(tmp_path / "seq", {n: blank for n in gt_numbers})
    result = evaluate_sequence(write_mask_video(tmp_path / "m.mkv", [np.zeros((24, 32), np.uint8)] * 9), gt)
    assert result.n_frames == len(gt_numbers)
    assert [("holds 9 frames, past the end of the ground truth" in w) for w in result.warnings] \
        == ([True] if warned else [])


def test_compare_does_not_warn_of_an_input_longer_than_sparse_ground_truth(tmp_path):
    from bgsub.evaluation.compare import compare_methods

    scene = write_input_sequence(tmp_path / "famA_one", n_frames=8)
    for n in (1, 3, 5, 7):  # labels for every other frame
        (scene / "groundtruth" / f"gt{n:06d}.png").unlink()
    (scene / "groundtruth" / "gt000008.png").unlink()  # ... up to frame 6 of 8
    report = compare_methods(scene, methods=["framediff"])
    assert report.warnings == [] and report.rows[0].eval_frames == 3


# --- one list of video suffixes ---------------------------------------------------------------


def test_video_suffixes_have_one_home():
    assert evaluation.VIDEO_EXTENSIONS is sources.VIDEO_SUFFIXES
    assert flowio.VIDEO_SUFFIXES is sources.VIDEO_SUFFIXES
    assert sources.VIDEO_SUFFIXES[:2] == (".mkv", ".avi")  # lossless mask videos looked for first
    assert len(set(sources.VIDEO_SUFFIXES)) == len(sources.VIDEO_SUFFIXES)
    assert all(s == s.lower() and s.startswith(".") for s in sources.VIDEO_SUFFIXES)


def test_every_video_suffix_finds_a_dataset_prediction_and_names_a_video(tmp_path):
    for suffix in sources.VIDEO_SUFFIXES:
        (tmp_path / f"traffic{suffix}").write_bytes(b"not decoded here")
    # The lookup order: the first suffix wins.
    assert find_prediction(tmp_path, "cameraJitter/traffic") == tmp_path / "traffic.mkv"
    (tmp_path / "traffic.mkv").unlink()
    assert find_prediction(tmp_path, "cameraJitter/traffic") == tmp_path / "traffic.avi"
    for suffix in (".mpg", ".3gp"):  # found by eval, and named videos by flowio
        only = tmp_path / suffix.strip(".")
        only.mkdir()
        (only / f"clip{suffix}").write_bytes(b"not an image")
        assert find_prediction(only, "clip") == only / f"clip{suffix}"
        with pytest.raises(InputError, match="is a video, not an image"):
            flowio.read_image(only / f"clip{suffix}")
