"""bgsub.background.sample: the sample-based background model of a still camera."""

import numpy as np
import pytest

from bgsub.background.sample import SampleBackground
from bgsub.errors import InputError


def _gray(value=100, h=40, w=50):
    return np.full((h, w), value, np.uint8)


def test_sample_model_scores_zeros_before_its_first_frame():
    score = SampleBackground().score(_gray())
    assert score.shape == (40, 50) and score.dtype == np.float32 and not score.any()


def test_sample_model_finds_a_new_object_and_nothing_else():
    model = SampleBackground(radius=20)
    model.reset(_gray(100))
    frame = _gray(100)
    frame[10:20, 10:20] = 160
    score = model.score(frame)
    assert np.allclose(score[10:20, 10:20], 3.0)  # 60 gray levels / radius 20
    assert (score[25:, 25:] == 0).all()


def test_sample_model_score_is_the_kth_smallest_sample_distance():
    rng = np.random.default_rng(0)
    model = SampleBackground(samples=7, min_matches=3, radius=10)
    model.reset(rng.integers(0, 256, (12, 15, 3), dtype=np.uint8))
    model.s[:] = rng.integers(0, 256, model.s.shape, dtype=np.uint8)
    frame = rng.integers(0, 256, (12, 15, 3), dtype=np.uint8)
    d = np.abs(model.s.astype(int) - frame.transpose(2, 0, 1)[None].astype(int)).max(axis=1)
    expected = np.sort(d, axis=0)[2] / 10.0
    assert np.allclose(model.score(frame), expected)


def test_sample_model_learns_background_but_not_foreground():
    frame = _gray(100)
    frame[10:20, 10:20] = 200
    fg = np.zeros(frame.shape, bool)
    fg[10:20, 10:20] = True
    kept, learnt = SampleBackground(seed=1), SampleBackground(seed=1)
    for model in (kept, learnt):
        model.reset(_gray(100))
    for _ in range(200):
        kept.update(frame, fg)
        learnt.update(frame)
    assert (kept.score(frame)[10:20, 10:20] > 1).all()
    assert np.median(learnt.score(frame)[10:20, 10:20]) == 0


def test_sample_model_learning_rates_follow_opencv():
    model = SampleBackground()
    model.reset(_gray(100))
    before = model.s.copy()
    model.update(_gray(200), learning_rate=0.0)
    assert np.array_equal(model.s, before)
    model.update(_gray(200), learning_rate=1.0)
    assert (model.s == 200).all()
    with pytest.raises(InputError, match="learning rate"):
        model.update(_gray(200), learning_rate=2.0)


def test_sample_model_refuses_a_frame_of_another_size():
    model = SampleBackground()
    model.reset(_gray())
    with pytest.raises(InputError, match="background model"):
        model.score(_gray(h=30))
    with pytest.raises(InputError, match="min_matches"):
        SampleBackground(samples=3, min_matches=4)


@pytest.mark.parametrize("shape", [(40, 50), (40, 50, 3)])
def test_sample_model_background_image_has_the_frames_shape(shape):
    model = SampleBackground()
    assert model.background_image() is None
    model.reset(np.full(shape, 77, np.uint8))
    img = model.background_image()
    assert img.shape == shape and img.dtype == np.uint8 and (img == 77).all()
