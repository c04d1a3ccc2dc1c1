"""bgsub.camera.KnownMotion: a camera motion given (``known_motion``, ``--motion-in``)
replaces the fit; entries all NaN, and frames past its end, are fitted as usual.

The scene: a textured world panning exactly 5 px a frame to the right, with a large textured
object (half the frame wide) moving 1 px a frame, enough vectors to pull a RANSAC fit."""

import cv2
import numpy as np
import pytest
from helpers import model_path

from bgsub.engines import create_engine
from bgsub.camera import KnownMotion
from bgsub.errors import InputError

H, W, PAN, N = 120, 160, 5, 14


def _world(seed, h, w):
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 4, w // 4, 3)).astype(np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def _scene(n=N, width=80):
    """``(frame (H, W, 3) uint8, ground truth (H, W) bool)`` per frame."""
    world, thing = _world(0, H, W + PAN * n + 8), _world(2, 90, width)
    for k in range(n):
        frame = world[:, PAN * (n - k):PAN * (n - k) + W].copy()
        truth = np.zeros((H, W), bool)
        frame[15:105, 10 + k:10 + k + width] = thing
        truth[15:105, 10 + k:10 + k + width] = True
        yield frame, truth


def _pan(dx=PAN, n=N):
    """The exact camera motion of the scene: ``(n, 3, 3)``, entry 0 the identity."""
    motion = np.repeat(np.eye(3)[None], n, axis=0)
    motion[1:, 0, 2] = dx
    return motion


def _engine(name, **params):
    if name == "grbm":
        params["model"] = model_path()
    # The scene's one large object moves steadily along the pan: frame by frame that is what a
    # near layer's parallax looks like (docs/decisions.md), and this test is about the fit.
    return create_engine(name, parallax=0, **params)


def _f_measure(engine):
    tp = fp = fn = 0
    for k, (frame, truth) in enumerate(_scene()):
        mask = engine.apply(frame) > 0
        if k:
            tp += np.count_nonzero(mask & truth)
            fp += np.count_nonzero(mask & ~truth)
            fn += np.count_nonzero(~mask & truth)
    return 2 * tp / max(2 * tp + fp + fn, 1)


def _masks(engine, n=N, width=80):
    return [engine.apply(frame) for frame, _ in _scene(n, width)]


@pytest.mark.parametrize("name", ["compensated", "grbm"])
def test_the_true_motion_gives_masks_at_least_as_good_as_estimated(name):
    estimated = _f_measure(_engine(name))
    given = _f_measure(_engine(name, known_motion=_pan()))
    assert given >= estimated and given > 0.8


def test_a_wrong_motion_changes_the_masks():
    right = _masks(create_engine("compensated", known_motion=_pan()))
    wrong = _masks(create_engine("compensated", known_motion=_pan(dx=-PAN)))
    assert any(not np.array_equal(a, b) for a, b in zip(right, wrong))


def test_the_motion_applied_is_the_one_given_in_input_pixels():
    # work_width 80: the engine works at half size, the given motion is in input pixels.
    engine = create_engine("compensated", known_motion=_pan(), work_width=80)
    for frame, _ in _scene(4):
        engine.apply(frame)
    np.testing.assert_allclose(engine.last_motion, _pan()[3], atol=1e-9)


def test_entries_all_nan_are_estimated_as_without_a_known_motion():
    unknown = np.full((N, 3, 3), np.nan)
    assert all(np.array_equal(a, b) for a, b in zip(
        _masks(create_engine("compensated")),
        _masks(create_engine("compensated", known_motion=unknown))))


def test_nan_entries_are_fitted_between_given_ones():
    motion = _pan(dx=-PAN)  # wrong where given ...
    motion[5] = np.nan  # ... but fitted here
    engine = create_engine("compensated", known_motion=motion)
    applied = []
    for frame, _ in _scene(7, width=20):  # (a small object: the fit finds the pan)
        engine.apply(frame)
        applied.append(engine.last_motion)
    assert applied[4] is None or applied[4][0, 2] < 0  # (the given one: a scene cut or -5)
    assert applied[5] is not None and abs(applied[5][0, 2] - PAN) < 1.0


def test_frames_past_the_end_are_estimated_and_counted():
    engine = create_engine("compensated", known_motion=_pan(n=4))
    _masks(engine, n=7, width=20)
    assert engine.known_motion.frames_past_end == 3
    assert engine.last_motion is not None and abs(engine.last_motion[0, 2] - PAN) < 1.0


def test_a_file_as_motion_writes_it_is_read(tmp_path):
    path = tmp_path / "cam.npy"
    np.save(path, _pan())
    by_file = create_engine("compensated", known_motion=str(path))
    by_array = create_engine("compensated", known_motion=_pan())
    assert all(np.array_equal(a, b) for a, b in zip(_masks(by_file, 5), _masks(by_array, 5)))


@pytest.mark.parametrize("value, words", [
    (np.zeros((4, 2, 3)), r"\(N, 3, 3\) array"),
    (np.zeros((0, 3, 3)), r"\(N, 3, 3\) array"),
    (np.array([[["a"] * 3] * 3]), r"\(N, 3, 3\) array"),
    (np.where(np.eye(3, dtype=bool), np.nan, 0.0)[None].repeat(2, 0),
     "entry 0 is partly not finite"),
    (np.concatenate([_pan(n=2), np.zeros((1, 3, 3))]), "entry 2 is singular"),
])
def test_bad_motion_arrays_are_refused(value, words):
    with pytest.raises(InputError, match=words):
        create_engine("compensated", known_motion=value)


def test_bad_motion_files_are_refused(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        KnownMotion.from_value(str(tmp_path / "none.npy"))
    garbage = tmp_path / "cam.npy"
    garbage.write_bytes(b"not an array")
    with pytest.raises(InputError, match="not an .npy file; the known camera motion is an "):
        KnownMotion.from_value(str(garbage))


def test_baselines_take_no_known_motion():
    with pytest.raises(InputError, match="unknown parameter 'known_motion'"):
        create_engine("mog2", known_motion=_pan())


def test_grbm_fits_the_pan_beside_an_object_that_outnumbers_it():
    """The object holds most of the textured patches, so fewer refined vectors agree with the
    pan than vectors as read agree with the object: that is no motion blur, and the engine
    keeps the pan on every frame it measures instead of re-reading coarser levels, where the
    object dominates."""
    engine = _engine("grbm")
    shifts = []
    for k, (frame, _) in enumerate(_scene()):
        engine.apply(frame)
        if k and engine.last_motion is not None:
            shifts.append(engine.last_motion[0, 2])
    assert len(shifts) >= N - 4
    np.testing.assert_allclose(shifts, PAN, atol=0.5)
