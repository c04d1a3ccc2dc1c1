"""bgsub.evaluation.scoring: SequenceScorer, and GroundTruthScorer as a consumer of the frame loop."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.engines import Engine, register_engine
from bgsub.errors import InputError
from bgsub.evaluation.cdnet import Counts, evaluate_sequence, open_ground_truth
from bgsub.evaluation.compare import compare_methods
from bgsub.evaluation.scoring import GroundTruthScorer, SequenceScorer
from bgsub.io.loop import Consumer, FrameLoop
from bgsub.io.sources import open_source
from helpers import write_bins, write_gt_sequence, write_input_sequence


class _Bright(Engine):
    """Foreground where the gray level is above 200 (the square of write_input_sequence)."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        return np.where(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) > 200, 255, 0).astype(np.uint8)


class _BrightBool(_Bright):
    """The same masks as bool arrays."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        return super().apply(image) > 0


register_engine("_test_bright_u8", "test: bright pixels, 0/255")(_Bright)
register_engine("_test_bright_bool", "test: bright pixels, bool")(_BrightBool)


@pytest.fixture
def sequence(tmp_path: Path) -> Path:
    return write_input_sequence(tmp_path / "famA_one", temporal_roi="2 8")


def test_the_loop_scorer_counts_what_evaluate_sequence_counts_on_the_masks(sequence, tmp_path):
    gt = open_ground_truth(sequence)
    scorer = GroundTruthScorer(gt, gt.select_frames())
    masks = {}

    class Keep(Consumer):
        def add(self, result):
            masks[result.index + 1] = result.masks["bright"]

    with open_source(str(sequence)) as source:
        FrameLoop({"bright": _Bright()}, [scorer, Keep()]).run(source)
    reference = evaluate_sequence(write_bins(tmp_path / "bins", masks), sequence)
    assert scorer.scored == list(range(2, 9))
    assert scorer.counts("bright") == reference.counts and reference.counts.tp > 0


def test_an_interrupt_while_preparing_leaves_the_frame_uncounted(sequence):
    gt = open_ground_truth(sequence)
    scorer = GroundTruthScorer(gt, range(1, 9))

    class CtrlCAtFrame3(Consumer):
        def prepare(self, result):
            if result.index == 2:  # after the scorer counted frame 3, before anyone added it
                raise KeyboardInterrupt

        def add(self, result):
            pass

    with open_source(str(sequence)) as source, pytest.raises(KeyboardInterrupt):
        FrameLoop({"bright": _Bright()}, [scorer, CtrlCAtFrame3()]).run(source)
    assert scorer.scored == [1, 2]
    two = SequenceScorer(gt)
    for number in (1, 2):
        two.add(two.count(number, _Bright().apply(cv2.imread(
            str(sequence / "input" / f"in{number:06d}.png")))))
    assert scorer.counts("bright") == two.counts


def test_compare_scores_bool_masks_as_0_255(sequence):
    report = compare_methods(sequence, methods=["_test_bright_u8", "_test_bright_bool"])
    u8, as_bool = report.rows
    assert as_bool.counts == u8.counts and u8.counts.tp > 0


def test_sequence_scorer_resizes_a_uniform_scale_and_refuses_other_sizes(tmp_path):
    gt = open_ground_truth(write_gt_sequence(tmp_path / "seq", {1: np.full((24, 32), 255,
                                                                          np.uint8)}))
    scorer = SequenceScorer(gt)
    scorer.score(1, np.full((12, 16), 255, np.uint8), source="half")
    assert scorer.counts == Counts(tp=24 * 32) and scorer.scaled_from == "16x12"
    with pytest.raises(InputError, match=r"prediction odd is 16x16 but ground truth .* is 32x24"):
        scorer.score(1, np.zeros((16, 16), np.uint8), source="odd")
    with pytest.raises(InputError, match="holds 0/1 values"):
        scorer.score(1, np.ones((24, 32), np.uint8), source="ones")
