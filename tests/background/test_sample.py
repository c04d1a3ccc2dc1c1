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


def _scrambled(seed, shape, **params):
    """``(model, frame)``: a model of random samples and a random frame, ``shape`` (h, w, 3)."""
    rng = np.random.default_rng(seed)
    model = SampleBackground(**params)
    model.reset(rng.integers(0, 256, shape, dtype=np.uint8))
    model.s[:] = rng.integers(0, 256, model.s.shape, dtype=np.uint8)
    return model, rng.integers(0, 256, shape, dtype=np.uint8)


def test_sample_model_score_is_the_kth_smallest_sample_distance():
    model, frame = _scrambled(0, (12, 15, 3), samples=7, min_matches=3, radius=10)
    d = np.abs(model.s.astype(int) - frame.transpose(2, 0, 1)[None].astype(int)).max(axis=1)
    expected = np.sort(d, axis=0)[2] / 10.0
    assert np.allclose(model.score(frame), expected)


def test_a_box_is_scored_as_the_whole_frame_is_there():
    model, frame = _scrambled(1, (20, 30, 3), samples=7, min_matches=2, radius=12)
    box = np.s_[3:11, 7:25]
    assert np.allclose(model.score_box(frame, box), model.score(frame)[box])


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


def _learn(model, frames):
    """Score and learn each frame as background, as the still-camera switch does."""
    for frame in frames:
        model.score(frame)
        model.update(frame)


def _calm_and_rippling(n, seed=0):
    """``n`` (40, 50) frames: gray 100 with sensor noise, the right half rippling (water: each
    pixel swings by up to 30 gray levels from frame to frame)."""
    rng = np.random.default_rng(seed)
    frames = []
    for _ in range(n):
        f = 100 + rng.normal(0, 1, (40, 50))
        f[:, 25:] += rng.uniform(-30, 30, (40, 25))
        frames.append(np.clip(f, 0, 255).astype(np.uint8))
    return frames


def test_one_radius_for_all_pixels_without_a_spread():
    model = SampleBackground(radius=20)
    _learn(model, _calm_and_rippling(10))
    assert model.radii() is None


def test_a_rippling_pixel_gets_a_wider_radius_than_a_calm_one():
    model = SampleBackground(radius=20, radius_min=5, radius_gain=5)
    _learn(model, _calm_and_rippling(30))
    radii = model.radii()
    assert radii.shape == (40, 50) and radii.dtype == np.float32
    assert radii.min() >= 5 and radii.max() <= 20
    assert np.median(radii[:, :25]) < 8 < 15 < np.median(radii[:, 25:])


def test_a_faint_object_on_a_calm_pixel_is_found_with_a_radius_per_pixel():
    # A car in fog: 12 gray levels brighter than the calm background. One radius of 20 misses it;
    # the calm pixels' own radius finds it, while the rippling half stays background.
    frames = _calm_and_rippling(31)
    test = frames.pop().copy()
    test[10:20, 5:15] += 12
    for model, found in ((SampleBackground(radius=20), False),
                         (SampleBackground(radius=20, radius_min=5, radius_gain=5), True)):
        _learn(model, frames)
        score = model.score(test)
        assert (np.mean(score[10:20, 5:15] > 1.0) > 0.9) == found
        assert np.mean(score[:, 25:] > 1.0) < 0.05


def test_a_frame_the_model_did_not_score_adds_nothing_to_the_spread():
    # The still-camera switch skips scoring while the camera moves, yet the model learns.
    model = SampleBackground(radius=20, radius_min=5, radius_gain=5)
    frames = _calm_and_rippling(6)
    _learn(model, frames[:5])
    spread = model.spread.copy()
    model.update(frames[5])  # no score of this frame: its distances are not known
    assert np.array_equal(model.spread, spread)
