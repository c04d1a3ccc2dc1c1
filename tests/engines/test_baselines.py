"""The classical engines: mog2, knn, framediff."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.engines import available_engines, create_engine, get_engine_spec
from bgsub.errors import InputError

CLASSICAL = ("mog2", "knn", "framediff")
H, W = 72, 96
SQUARE = 20


def _background(seed: int = 0) -> np.ndarray:
    """Smooth random texture, (H, W, 3) uint8."""
    rng = np.random.default_rng(seed)
    small = rng.integers(30, 220, (H // 8, W // 8, 3), dtype=np.uint8)
    return cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)


def _moving_square_clip(n_static: int = 50, n_moving: int = 10, seed: int = 0):
    """A static background (with sensor noise), then a checkered square moving 4 px/frame.

    Yields (frame (H, W, 3) uint8, square_mask (H, W) bool of the square in that frame).
    The warm-up is long enough that MOG2's start-up learning rate, 1 / (2 * frames seen), no
    longer absorbs a pixel the square has covered for a few frames.
    """
    rng = np.random.default_rng(seed)
    background = _background(seed).astype(np.int16)
    # A checkerboard with 4-px cells: moving by one cell per frame changes every pixel of it,
    # so even frame differencing sees the whole square, not only its leading edge.
    cells = (np.indices((SQUARE, SQUARE)) // 4).sum(axis=0) % 2
    sprite = np.repeat(np.where(cells, 230, 20)[..., None], 3, axis=2).astype(np.int16)
    for k in range(n_static + n_moving):
        frame = background + rng.normal(0, 2, background.shape).round().astype(np.int16)
        square = np.zeros((H, W), bool)
        if k >= n_static:
            x = 8 + 4 * (k - n_static)
            frame[26:26 + SQUARE, x:x + SQUARE] = sprite
            square[26:26 + SQUARE, x:x + SQUARE] = True
        yield np.clip(frame, 0, 255).astype(np.uint8), square


def test_registered_with_descriptions():
    names = [spec.name for spec in available_engines()]
    for name in CLASSICAL:
        assert name in names
        assert get_engine_spec(name).description


def test_mog2_defaults_are_opencvs():
    params = get_engine_spec("mog2").params
    reference = cv2.createBackgroundSubtractorMOG2()
    assert params["history"].default == reference.getHistory()
    assert params["var_threshold"].default == pytest.approx(reference.getVarThreshold())
    assert params["background_ratio"].default == pytest.approx(reference.getBackgroundRatio())
    assert params["n_mixtures"].default == reference.getNMixtures()
    assert params["var_threshold_gen"].default == pytest.approx(reference.getVarThresholdGen())
    assert params["var_init"].default == pytest.approx(reference.getVarInit())
    assert params["var_min"].default == pytest.approx(reference.getVarMin())
    assert params["var_max"].default == pytest.approx(reference.getVarMax())
    assert params["complexity_reduction_threshold"].default == pytest.approx(
        reference.getComplexityReductionThreshold())
    assert params["shadow_threshold"].default == pytest.approx(reference.getShadowThreshold())
    assert params["detect_shadows"].default is False  # bgsub's one deliberate change


def test_knn_defaults_are_opencvs():
    params = get_engine_spec("knn").params
    reference = cv2.createBackgroundSubtractorKNN()
    assert params["history"].default == reference.getHistory()
    assert params["dist2_threshold"].default == pytest.approx(reference.getDist2Threshold())
    assert params["n_samples"].default == reference.getNSamples()
    assert params["knn_samples"].default == reference.getkNNSamples()
    assert params["shadow_threshold"].default == pytest.approx(reference.getShadowThreshold())
    assert params["detect_shadows"].default is False


def test_parameters_reach_opencv():
    mog2 = create_engine("mog2", history=123, var_threshold=30.0, n_mixtures=3,
                         background_ratio=0.7, detect_shadows=True)
    assert mog2.subtractor.getHistory() == 123
    assert mog2.subtractor.getVarThreshold() == pytest.approx(30.0)
    assert mog2.subtractor.getNMixtures() == 3
    assert mog2.subtractor.getBackgroundRatio() == pytest.approx(0.7)
    assert mog2.subtractor.getDetectShadows() is True
    knn = create_engine("knn", dist2_threshold=250.0, n_samples=9, knn_samples=3)
    assert knn.subtractor.getDist2Threshold() == pytest.approx(250.0)
    assert knn.subtractor.getNSamples() == 9
    assert knn.subtractor.getkNNSamples() == 3


@pytest.mark.parametrize("name", CLASSICAL)
@pytest.mark.parametrize("gray", [False, True])
def test_masks_are_uint8_0_255(name, gray):
    engine = create_engine(name)
    for frame, _ in _moving_square_clip():
        image = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if gray else frame
        mask = engine.apply(image)
        assert mask.shape == (H, W) and mask.dtype == np.uint8
        assert set(np.unique(mask)) <= {0, 255}
    assert mask.any()  # the square was found at all (values checked above)


@pytest.mark.parametrize("name", CLASSICAL)
def test_moving_square_detected(name):
    engine = create_engine(name)
    previous = np.zeros((H, W), bool)
    for frame, square in _moving_square_clip():
        mask = engine.apply(frame) > 0
        changed = square | previous  # framediff also flags the background the square uncovers
        previous = square
    recall = mask[square].mean()
    false_alarms = mask[~changed].mean()
    assert recall > 0.9, f"{name} recall {recall:.3f}"
    assert false_alarms < 0.01, f"{name} false-alarm rate {false_alarms:.4f}"


@pytest.mark.parametrize("name", ["mog2", "knn"])
def test_shadows_become_background(name):
    """OpenCV marks shadows 127; bgsub's masks must turn them into 0, not 255."""
    background = np.full((H, W, 3), 180, np.uint8)
    background[:, :, 1] = 150
    shadowed = background.copy()
    shadowed[20:50, 20:60] = (background[20:50, 20:60] * 0.75).astype(np.uint8)  # darker copy
    engine = create_engine(name, detect_shadows=True)
    if name == "mog2":
        raw = cv2.createBackgroundSubtractorMOG2(detectShadows=True)
    else:
        raw = cv2.createBackgroundSubtractorKNN(detectShadows=True)
    for _ in range(30):
        engine.apply(background)
        raw.apply(background)
    mask = engine.apply(shadowed)
    opencv = raw.apply(shadowed)
    assert (opencv[20:50, 20:60] == 127).mean() > 0.9  # OpenCV does see a shadow here
    assert set(np.unique(mask)) <= {0, 255}
    assert not mask[20:50, 20:60].any()


@pytest.mark.parametrize("name", CLASSICAL)
def test_fgmask_written_in_place(name):
    engine, twin = create_engine(name), create_engine(name)
    buffer = np.full((H, W), 77, np.uint8)
    for frame, _ in _moving_square_clip():
        out = engine.apply(frame, fgmask=buffer)
        expected = twin.apply(frame)
        assert out is buffer
        np.testing.assert_array_equal(buffer, expected)
    assert buffer.any()


def test_fgmask_of_wrong_shape_refused():
    engine = create_engine("mog2")
    with pytest.raises(InputError, match="fgmask"):
        engine.apply(_background(), fgmask=np.zeros((H, W + 1), np.uint8))


@pytest.mark.parametrize("name", CLASSICAL)
def test_background_image(name):
    engine = create_engine(name)
    assert engine.get_background_image() is None  # before any frame (OpenCV's KNN would crash)
    frame = _background()
    engine.apply(frame)
    background = engine.get_background_image()
    assert background.shape == frame.shape and background.dtype == np.uint8
    assert engine.getBackgroundImage().shape == frame.shape


@pytest.mark.parametrize("name", CLASSICAL)
def test_bad_images_refused(name):
    engine = create_engine(name)
    with pytest.raises(InputError):
        engine.apply(np.zeros((H, W), np.float32))
    with pytest.raises(InputError):
        engine.apply(np.zeros((H, W, 2), np.uint8))


@pytest.mark.parametrize("name,params", [
    ("mog2", {"history": 0}),
    ("mog2", {"var_min": 80.0}),
    ("knn", {"knn_samples": 10}),
    ("framediff", {"threshold": 300}),
])
def test_bad_parameters_refused(name, params):
    with pytest.raises(InputError, match=name):
        create_engine(name, **params)


def test_learning_rate_above_one_refused():
    with pytest.raises(InputError, match="learning_rate"):
        create_engine("mog2").apply(_background(), learning_rate=2.0)


def test_framediff_threshold_and_first_frame():
    engine = create_engine("framediff", threshold=10)
    first = np.full((H, W), 100, np.uint8)
    assert not engine.apply(first).any()  # nothing to compare the first frame with
    second = first.copy()
    second[:, : W // 2] = 111  # +11 > 10
    second[:, W // 2:] = 110  # +10, not above the threshold
    mask = engine.apply(second)
    assert mask[:, : W // 2].all() and not mask[:, W // 2:].any()


def test_framediff_learning_rate_zero_keeps_reference():
    engine = create_engine("framediff", threshold=10)
    reference = np.full((H, W), 100, np.uint8)
    engine.apply(reference)
    engine.apply(np.full((H, W), 150, np.uint8), learning_rate=0.0)
    # Still compared with the reference (100), not with the frame of value 150.
    assert engine.apply(np.full((H, W), 150, np.uint8)).all()


def test_framediff_morphology_removes_speckle():
    frame = np.full((H, W), 100, np.uint8)
    speckled = frame.copy()
    speckled[10, 10] = speckled[40, 60] = 200
    speckled[30:45, 30:45] = 200
    plain, opened = create_engine("framediff"), create_engine("framediff", morph_size=3)
    for engine in (plain, opened):
        engine.apply(frame)
    assert plain.apply(speckled)[10, 10] == 255
    mask = opened.apply(speckled)
    assert mask[10, 10] == 0 and mask[40, 60] == 0 and mask[37, 37] == 255


def test_knn_is_reproducible_when_seeded():
    """OpenCV's KNN draws random numbers; the engine seeds OpenCV's generator when created."""
    rng = np.random.default_rng(0)
    background = rng.integers(0, 255, (48, 64, 3)).astype(np.float32)
    frames = [np.clip(background + rng.normal(0, 12, background.shape), 0, 255).astype(np.uint8)
              for _ in range(40)]

    def run(seed):
        engine = create_engine("knn", seed=seed)
        return np.stack([engine.apply(frame) for frame in frames])

    first = run(0)
    cv2.randu(np.zeros(100), 0, 1)  # other code using OpenCV's generator in between
    np.testing.assert_array_equal(first, run(0))


@pytest.mark.parametrize("name", ["mog2", "knn", "framediff"])
def test_every_numeric_parameter_states_its_range(name):
    """`bgsub methods` shows a parameter's range from its Param bounds: a bound checked only
    inside the factory would be enforced but never shown."""
    from bgsub.engines import get_engine_spec

    for key, p in get_engine_spec(name).params.items():
        if isinstance(p.default, (int, float)) and not isinstance(p.default, bool):
            assert (p.low, p.high, p.above) != (None, None, None), key



def test_apply_takes_opencvs_keyword_spelling():
    """Code written for cv2 passes ``learningRate=``; it must reach the model as
    ``learning_rate=`` does (and change the masks, so it is not silently dropped)."""
    rng = np.random.default_rng(3)
    frames = [_background()] * 4 + [rng.integers(0, 256, (H, W, 3), np.uint8) for _ in range(3)]
    cv_style, ours, default = create_engine("mog2"), create_engine("mog2"), create_engine("mog2")
    changed = False
    for frame in frames:
        expected = ours.apply(frame, learning_rate=0.0)
        np.testing.assert_array_equal(cv_style.apply(frame, learningRate=0.0), expected)
        changed |= not np.array_equal(default.apply(frame), expected)
    assert changed


@pytest.mark.parametrize("name", ["mog2", "knn", "framediff", "grbm", "compensated"])
def test_every_engine_takes_opencvs_keyword_spelling(name):
    import inspect

    apply = type(create_engine(name)).apply
    assert "learningRate" in inspect.signature(apply, follow_wrapped=False).parameters


def test_both_spellings_of_the_learning_rate_are_refused():
    with pytest.raises(InputError, match="not both"):
        create_engine("mog2").apply(_background(), learning_rate=0.5, learningRate=0.5)


def test_framediff_help_says_gray_like_everything_else():
    # "gray" throughout bgsub (gray frames, read as gray); framediff said "grey-level".
    import bgsub.engines.baselines as baselines

    spec = get_engine_spec("framediff")
    texts = [spec.params["threshold"].help, baselines.__doc__, baselines.FrameDifference.__doc__]
    assert "gray-level" in spec.params["threshold"].help
    assert not any("grey" in text.lower() for text in texts)


@pytest.mark.parametrize("name", ["mog2", "knn"])
def test_a_fresh_opencv_engine_pickles_and_gives_the_masks_of_the_original(name):
    import pickle

    eng = create_engine(name, history=20)
    twin = pickle.loads(pickle.dumps(eng))  # as a process pool sends it to its workers
    cv2.setRNGSeed(0)
    ours = [eng.apply(frame) for frame, _ in _moving_square_clip(n_static=10, n_moving=5)]
    cv2.setRNGSeed(0)
    theirs = [twin.apply(frame) for frame, _ in _moving_square_clip(n_static=10, n_moving=5)]
    assert twin.subtractor is not eng.subtractor
    assert twin.subtractor.getHistory() == 20
    assert all(np.array_equal(a, b) for a, b in zip(ours, theirs))
    assert any(a.any() for a in ours)  # (the comparison is not of empty masks)


@pytest.mark.parametrize("name", ["mog2", "knn"])
def test_an_opencv_engine_mid_video_refuses_pickling_in_words(name):
    import copy
    import pickle

    eng = create_engine(name)
    eng.apply(_background())
    for dump in (pickle.dumps, copy.deepcopy):
        with pytest.raises(TypeError, match=f"a {name} engine that has processed frames cannot "
                                            "be pickled or copied"):
            dump(eng)
