"""bgsub.background: the camera-compensated background model (compensated), flow violation and
fusion (fusion)."""

import cv2
import numpy as np
import pytest

from bgsub.errors import InputError, describe_shape
from bgsub.background.compensated import BackgroundConfig, CompensatedBackground, warp_image
from bgsub.background.evidence import motion_evidence_map
from bgsub.background.fusion import clean_mask, flow_violation_map, fuse_masks, persistent_blobs


def _scene(h=120, w=160, seed=0):
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 6 + 4, w // 6 + 4, 3)).astype(np.uint8)
    return cv2.resize(small, (w + 60, h + 60), interpolation=cv2.INTER_CUBIC)


def _view(world, x0, h=120, w=160):
    m = np.float32([[1, 0, -x0], [0, 1, -10]])
    return cv2.warpAffine(world, m, (w, h), flags=cv2.INTER_LINEAR)


def test_pure_pan_gives_no_foreground():
    world = _scene()
    bg = CompensatedBackground()
    masks = []
    for k in range(12):
        frame = _view(world, 3.0 * k)
        if k == 0:
            bg.reset(frame)
            bg.update(frame)
            continue
        h = np.array([[1, 0, -3.0], [0, 1, 0], [0, 0, 1]])  # content moves 3 px left
        bg.warp(h)
        mask = fuse_masks(bg.score(frame))
        bg.update(frame, mask)
        masks.append(mask)
    assert max(np.count_nonzero(m) for m in masks) < 0.005 * masks[0].size


@pytest.mark.parametrize("sharp, kept", [(False, 0.6), (True, 0.8)])
def test_a_sharp_warp_keeps_a_frozen_models_detail(sharp, kept):
    # Ten sub-pixel shifts there and back: what a model that does not learn (learning_rate=0)
    # goes through in ten frames of a pan. Bilinear resampling blurs it at every step.
    rng = np.random.default_rng(4)
    texture = cv2.resize(rng.integers(0, 256, (30, 40)).astype(np.uint8), (160, 120),
                         interpolation=cv2.INTER_CUBIC)
    bg = CompensatedBackground()
    bg.update(texture)
    detail = cv2.Laplacian(bg.mean[:, :, 0], cv2.CV_32F)[20:-20, 20:-20].var()
    for k in range(10):
        shift = 0.4 if k % 2 == 0 else -0.4
        bg.warp(np.array([[1, 0, shift], [0, 1, shift], [0, 0, 1.0]]), sharp=sharp)
    after = cv2.Laplacian(bg.mean[:, :, 0], cv2.CV_32F)[20:-20, 20:-20].var()
    if sharp:
        assert after > kept * detail, after / detail
        assert 0.0 <= bg.mean.min() and bg.mean.max() <= 255.0
    else:
        assert after < kept * detail, after / detail


def test_uncovered_border_has_no_history_and_is_not_foreground():
    bg = CompensatedBackground(BackgroundConfig())
    first = np.full((50, 60, 3), 100, np.uint8)
    bg.reset(first)
    bg.update(first)
    bg.warp(np.array([[1, 0, -10.0], [0, 1, 0], [0, 0, 1]]))
    assert np.all(bg.age[:, -9:] == 0) and np.all(bg.age[:, :40] >= 1)
    new = first.copy()
    new[:, -10:] = 250  # new content scrolling in: different, but no history there
    young = bg.config.young_score
    assert 0 < young < 1  # below the decision: only motion evidence can make it foreground
    assert np.all(bg.score(new)[:, -9:] == np.float32(young))
    assert not fuse_masks(bg.score(new)).any()


def test_young_pixels_are_foreground_only_with_motion_evidence():
    bg = CompensatedBackground(BackgroundConfig())
    first = np.full((50, 60), 100, np.uint8)
    bg.reset(first)
    bg.update(first)
    bg.warp(np.array([[1, 0, -20.0], [0, 1, 0], [0, 0, 1]]))  # a 20-px band without history
    score = bg.score(first)
    violation = np.full(score.shape, 0.5, np.float32)
    violation[:, 30:] = 1.0  # the local motion strongly violates the camera's right of x=30
    mask = fuse_masks(score, violation, flow_boost=1.5, flow_damp=0.2, min_area=0)
    assert mask[:, -19:].all()  # young and violating
    assert not mask[:, 30:40].any()  # violating but matching its history
    assert not fuse_masks(score, None, min_area=0).any()  # young without evidence


def test_object_on_static_background_is_found():
    world = _scene()
    frame0 = _view(world, 0)
    bg = CompensatedBackground()
    bg.reset(frame0)
    bg.update(frame0)
    frame = frame0.copy()
    frame[40:70, 50:90] = (0, 0, 255)
    mask = fuse_masks(bg.score(frame))
    assert mask.dtype == np.uint8 and set(np.unique(mask)) <= {0, 255}
    inside = mask[45:65, 55:85] > 0
    assert inside.mean() > 0.95
    assert np.count_nonzero(mask) < 1.3 * 30 * 40


def _learn(bg, frame, updates):
    """``updates`` frames of ``frame`` as the engines learn them: foreground where it differs."""
    for _ in range(updates):
        bg.update(frame, bg.score(frame) > 1)
    return bg.score(frame)


@pytest.mark.parametrize("radius, shows, healed", [
    (6, "background", True),    # the ghost heals from its edges, up to 6 px per frame
    (0, "background", False),   # off: the ghost stays (it learns at fg_alpha)
    (6, "other", False),        # what is uncovered matches no background around it
])
def test_the_ghost_of_an_object_present_at_the_start_heals(radius, shows, healed):
    background = _view(_scene(), 0) // 4 + 100  # a gently varying, colourless-ish scene
    start = background.copy()
    start[40:80, 60:100] = (20, 240, 20)  # an object when the model began
    now = background.copy()  # it has left: the background shows ...
    if shows == "other":
        now[40:80, 60:100] = (250, 60, 60)  # ... or something unlike it
    bg = CompensatedBackground(BackgroundConfig(ghost_radius=radius))
    bg.reset(start)
    bg.update(start)
    score = _learn(bg, now, 8)  # 20 px from the ghost's edges to its centre
    assert (score[40:80, 60:100].max() < 1) == healed


@pytest.mark.parametrize("seen", [True, False])
def test_an_object_over_background_the_model_has_seen_is_not_healed(seen):
    background = np.full((60, 80, 3), 60, np.uint8)
    background[:, 40:] = 180
    bg = CompensatedBackground(BackgroundConfig(ghost_radius=6))
    bg.reset(background)
    if seen:
        bg.update(background, np.zeros(background.shape[:2], bool))  # all called background
    now = background.copy()
    now[20:40, 30:40] = 180  # the colour of the background just right of it
    score = _learn(bg, now, 5)
    assert (score[20:40, 30:40].min() > 1) == seen


@pytest.mark.parametrize("seen, rate, takes", [
    (False, -1.0, True),  # the first frame's content, never judged: the frames' motion wins
    (True, -1.0, False),  # background the model has seen: an object over it stays foreground
    (False, 0.05, False),  # a caller's rate: the model learns only at that rate
])
def test_foreground_confirmed_as_background_replaces_a_model_that_never_saw_it(seen, rate, takes):
    start = np.full((20, 30, 3), 40, np.uint8)
    bg = CompensatedBackground()
    bg.reset(start)
    bg.update(start, np.zeros((20, 30), bool) if seen else None)
    now = np.full((20, 30, 3), 200, np.uint8)
    everywhere = np.ones((20, 30), bool)
    bg.update(now, everywhere, rate, confirmed=everywhere)
    assert (bg.score(now).max() < 1.0) == takes


def test_a_pixel_is_sensitive_where_its_threshold_is_within_the_limit():
    model = CompensatedBackground(BackgroundConfig(k_sigma=2.0, min_diff=10.0))
    frame = np.zeros((4, 6, 3), np.uint8)
    model.reset(frame)
    model.var[...] = 8.0 ** 2  # threshold 16 gray levels
    model.var[0, 0, 2] = 25.0 ** 2  # one channel's spread is enough to blind a pixel
    seen = model.sensitive(within=20.0)
    assert seen.shape == (4, 6) and seen.sum() == 23 and not seen[0, 0]
    assert not model.sensitive(within=8.0).any()  # below min_diff nothing can be seen


def test_flow_violation_marks_disagreeing_vectors():
    ys, xs = np.mgrid[4:100:8, 4:100:8]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    cam = np.array([[1, 0, 2.0], [0, 1, 0], [0, 0, 1]])
    disp = np.tile([2.0, 0.0], (len(pts), 1))
    moving = (pts[:, 0] > 60) & (pts[:, 1] > 60)
    disp[moving] = [-3.0, 1.0]
    vmap = flow_violation_map(pts, disp, cam, weights=np.ones(len(pts)), shape=(100, 100))
    assert vmap.shape == (100, 100) and vmap.dtype == np.float32
    assert vmap[85, 85] > 0.9
    assert vmap[20, 20] < 0.1


def test_fusion_damps_agreeing_and_boosts_violating_regions():
    score = np.full((40, 40), 1.2, np.float32)
    violation = np.zeros((40, 40), np.float32)
    violation[:, 20:] = 1.0
    mask = fuse_masks(score, violation, flow_boost=0.8, flow_damp=0.8, min_area=1, close=0)
    assert not mask[:, :18].any() and mask[:, 22:].all()


def test_clean_mask_drops_small_blobs():
    m = np.zeros((50, 50), np.uint8)
    m[5:8, 5:8] = 255  # 9 px speck
    m[20:40, 20:40] = 255
    out = clean_mask(m, min_area=30)
    assert out[30, 30] == 255 and out[6, 6] == 0


def test_update_after_score_of_the_same_frame_equals_a_fresh_update():
    """score() keeps the frame's difference for update(); the result must not depend on it."""
    world = _scene(seed=3)
    frames = [_view(world, x0) for x0 in (0, 2, 4, 6)]
    shift = np.array([[1, 0, -2.0], [0, 1, 0], [0, 0, 1]])
    models = [CompensatedBackground(BackgroundConfig()) for _ in range(2)]
    for bg in models:
        bg.reset(frames[0])
        bg.update(frames[0])
    for frame in frames[1:]:
        masks = []
        for k, bg in enumerate(models):
            bg.warp(shift)
            masks.append(fuse_masks(bg.score(frame)))
        np.testing.assert_array_equal(masks[0], masks[1])
        models[0].update(frame, masks[0])  # the scored object: reuses the difference
        models[1].update(frame.copy(), masks[1])  # another object: recomputes it
        for name in ("mean", "var", "age"):
            np.testing.assert_allclose(getattr(models[0], name), getattr(models[1], name),
                                       rtol=1e-6, atol=1e-4)


def test_violation_threshold_scales_with_the_vectors_noise():
    """Noisy background vectors (+-1 px scatter) violate a fixed 0.75 px threshold in most
    cells; scaled by their robust spread (threshold ~4.6 px) they do not, while an 8 px object
    still does."""
    rng = np.random.default_rng(0)
    ys, xs = np.mgrid[4:100:4, 4:100:4]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)
    cam = np.eye(3)
    disp = rng.uniform(-1.0, 1.0, (len(pts), 2))
    moving = (pts[:, 0] > 70) & (pts[:, 1] > 70)
    disp[moving] += [8.0, 0.0]
    w = np.ones(len(pts))
    fixed = flow_violation_map(pts, disp, cam, weights=w, shape=(100, 100), threshold=0.75,
                               noise_scale=0.0)
    scaled = flow_violation_map(pts, disp, cam, weights=w, shape=(100, 100), threshold=0.75,
                                noise_scale=4.0)
    assert fixed[30, 30] > 0.3
    assert scaled[30, 30] < 0.1
    assert scaled[88, 88] > 0.9


def test_clean_mask_fills_a_hole_enclosed_by_a_blob():
    m = np.zeros((60, 60), np.uint8)
    m[10:50, 10:50] = 255
    m[20:40, 20:40] = 0  # a 400 px hole
    out = clean_mask(m, min_area=1, close=0, fill_holes=500)
    assert out[10:50, 10:50].all() and not out[:10].any()


def test_clean_mask_keeps_holes_larger_than_the_limit():
    m = np.zeros((60, 60), np.uint8)
    m[10:50, 10:50] = 255
    m[20:40, 20:40] = 0
    out = clean_mask(m, min_area=1, close=0, fill_holes=399)
    assert not out[20:40, 20:40].any()


def test_clean_mask_does_not_fill_background_open_to_the_border():
    m = np.zeros((60, 60), np.uint8)
    m[10:50, 10:50] = 255
    m[20:40, 20:60] = 0  # a notch reaching the right edge, not a hole
    out = clean_mask(m, min_area=1, close=0, fill_holes=10_000)
    assert not out[20:40, 20:60].any() and not out[:10].any()


def test_clean_mask_does_not_fill_a_notch_open_to_the_empty_frame_around_the_blob():
    # The notch reaches the blob's own edge, not the frame's: open through the empty pixels.
    m = np.zeros((60, 60), np.uint8)
    m[10:50, 10:50] = 255
    m[20:40, 30:50] = 0
    m[0:3, 0:3] = 255  # a second blob, so the foreground's extent is not the first blob's alone
    out = clean_mask(m, min_area=1, close=0, fill_holes=10_000)
    assert not out[20:40, 30:50].any() and out[10:20, 10:50].all()


def test_fusion_fills_the_inside_of_an_object_seen_only_at_its_outline():
    score = np.zeros((60, 60), np.float32)
    score[10:50, 10:50] = 2.0
    score[16:44, 16:44] = 0.0  # a flat interior that matches the background it covered
    mask = fuse_masks(score, min_area=1, close=0, fill_holes=5000)
    assert mask[10:50, 10:50].all() and not mask[:10].any()


def _gray_view(world, x0):
    return cv2.cvtColor(_view(world, x0), cv2.COLOR_BGR2GRAY)


def test_image_evidence_marks_what_the_camera_follows():
    world = _scene()
    thing = cv2.cvtColor(_scene(seed=7), cv2.COLOR_BGR2GRAY)[:40, :40]
    prev, cur = _gray_view(world, 0.0), _gray_view(world, 4.0)
    for frame in (prev, cur):  # the camera pans, the object stays put in the image
        frame[40:80, 60:100] = thing
    pan = np.array([[1, 0, -4.0], [0, 1, 0], [0, 0, 1]])
    still = motion_evidence_map(prev, cur, pan)
    assert still.dtype == np.float32 and still.shape == cur.shape
    assert still[44:76, 64:96].mean() > 0.9
    background = np.ones(cur.shape, bool)
    background[30:90, 50:110] = False  # away from the object's outline (window 7)
    background[:, -8:] = False  # and from the border the pan uncovers
    assert still[background].mean() < 0.05


def test_image_evidence_has_no_opinion_without_camera_motion():
    world = _scene()
    prev, cur = _gray_view(world, 0.0), _gray_view(world, 0.0)
    cur[40:80, 60:100] = 255 - cur[40:80, 60:100]  # a change, but nothing to tell apart
    assert motion_evidence_map(prev, cur, np.eye(3)).max() == 0.0


# ---------------------------------------------------------------- bad input: InputError, one line


def _reset_model(shape=(40, 50, 3)):
    bg = CompensatedBackground()
    bg.reset(np.full(shape, 100, np.uint8))
    return bg


@pytest.mark.parametrize("method", ["score", "update"])
@pytest.mark.parametrize("shape", [(40, 60, 3), (40, 50), (40, 50, 4)])
def test_frames_of_another_size_or_channel_count_are_refused(method, shape):
    bg = _reset_model()
    with pytest.raises(InputError, match=r"the frame is .*, the background model 50x40 BGR"):
        getattr(bg, method)(np.full(shape, 100, np.uint8))


@pytest.mark.parametrize("shape, words", [((40, 50), "50x40 gray"), ((40, 50, 1), "50x40 gray"),
                                          ((40, 50, 3), "50x40 BGR"),
                                          ((40, 50, 4), "50x40 with 4 channels")])
def test_shapes_are_described_as_a_user_reads_them(shape, words):
    assert describe_shape(shape) == words


def test_a_gray_model_takes_h_w_and_h_w_1_frames():
    bg = _reset_model((40, 50))
    for frame in (np.full((40, 50), 100, np.uint8), np.full((40, 50, 1), 100, np.uint8)):
        assert bg.score(frame).shape == (40, 50)
        bg.update(frame)


def test_update_refuses_a_mask_of_another_size():
    bg = _reset_model()
    with pytest.raises(InputError, match=r"mask has shape \(40, 49\)"):
        bg.update(np.full((40, 50, 3), 100, np.uint8), np.zeros((40, 49), bool))


@pytest.mark.parametrize("rate", [1.5, 2.0, float("nan")])
def test_update_refuses_a_learning_rate_above_one(rate):
    bg = _reset_model()
    with pytest.raises(InputError, match="learning rate must be at most 1"):
        bg.update(np.full((40, 50, 3), 100, np.uint8), learning_rate=rate)


def test_a_restart_may_change_the_size_and_score_before_any_frame_is_zero():
    bg = CompensatedBackground()
    np.testing.assert_array_equal(bg.score(np.full((8, 9), 7, np.uint8)), np.zeros((8, 9)))
    bg = _reset_model()
    bg.update(np.full((20, 30), 100, np.uint8), learning_rate=1.0)  # restarts, documented
    assert bg.mean.shape == (20, 30, 1)


def test_clean_mask_refuses_a_colour_mask():
    with pytest.raises(InputError, match=r"mask must be \(H, W\).*\(20, 20, 3\)"):
        clean_mask(np.zeros((20, 20, 3), np.uint8))
    assert clean_mask(np.zeros((20, 20, 1), np.uint8)).shape == (20, 20)


def test_flow_violation_map_refuses_missing_or_mismatched_weights():
    pts = np.array([[10.0, 10.0], [20.0, 20.0]])
    disp = np.zeros_like(pts)
    with pytest.raises(InputError, match="needs weights"):
        flow_violation_map(pts, disp, np.eye(3), weights=None, shape=(32, 32))
    with pytest.raises(InputError, match=r"\(2, 2\), \(2, 2\) and \(3,\)"):
        flow_violation_map(pts, disp, np.eye(3), weights=np.ones(3), shape=(32, 32))
    with pytest.raises(InputError, match=r"\(2, 2\), \(1, 2\) and \(2,\)"):
        flow_violation_map(pts, disp[:1], np.eye(3), weights=np.ones(2), shape=(32, 32))
    with pytest.raises(InputError, match=r"\(3, 3\) matrix"):
        flow_violation_map(pts, disp, np.eye(3)[:2], weights=np.ones(2), shape=(32, 32))


def test_image_evidence_refuses_float_or_mismatched_frames():
    gray = np.zeros((30, 40), np.uint8)
    with pytest.raises(InputError, match="prev is float32"):
        motion_evidence_map(gray.astype(np.float32), gray, np.eye(3))
    with pytest.raises(InputError, match="differ in shape"):
        motion_evidence_map(gray, gray[:, :39].copy(), np.eye(3))
    with pytest.raises(InputError, match="differ in shape"):
        motion_evidence_map(gray, np.zeros((30, 40, 3), np.uint8), np.eye(3))


def test_fuse_masks_refuses_a_violation_map_of_another_shape():
    with pytest.raises(InputError, match=r"violation map has shape \(30, 41\)"):
        fuse_masks(np.zeros((30, 40), np.float32), np.zeros((30, 41), np.float32),
                   flow_boost=1.0)


def _blobs(*boxes, shape=(60, 80)):
    mask = np.zeros(shape, np.uint8)
    for y, x in boxes:
        mask[y:y + 10, x:x + 10] = 255
    return mask


def test_persistent_blobs_drops_only_a_blob_new_in_this_frame():
    previous = _blobs((10, 10))
    mask = _blobs((12, 13), (40, 60))  # the first blob moved 3 px; the second is new
    kept = persistent_blobs(mask, previous, np.eye(3), radius=4)
    assert np.array_equal(kept, _blobs((12, 13)))


def test_persistent_blobs_follows_the_camera():
    previous = _blobs((10, 10))
    pan = np.array([[1.0, 0, 30], [0, 1, 0], [0, 0, 1]])  # the camera moved 30 px
    mask = _blobs((10, 40))
    assert np.array_equal(persistent_blobs(mask, previous, pan, radius=2), mask)
    assert not persistent_blobs(mask, previous, np.eye(3), radius=2).any()


def test_exposure_gain_is_the_frames_brightness_over_the_models_despite_foreground():
    frame = _view(_scene(), 0)
    model = CompensatedBackground()
    assert model.exposure_gain(frame) == 1.0  # no model yet
    model.reset(frame)
    model.update(frame)
    brighter = cv2.convertScaleAbs(frame, alpha=1.2)
    brighter[:, :40] = 255 - brighter[:, :40]  # a quarter of the frame is something else
    assert model.exposure_gain(brighter) == pytest.approx(1.2, abs=0.01)


@pytest.mark.parametrize("follow", [True, False])
def test_a_gain_read_too_high_on_every_frame_does_not_drift_a_model_that_follows_exposure(follow):
    # The gain is read against the model, which learns the matched frames: read 2 % too high
    # on every frame, it darkens the model a little more on each, unless the model follows.
    frame = _view(_scene(), 0)
    model = CompensatedBackground()
    model.update(frame)
    for _ in range(200):
        gain = 1.02 * model.exposure_gain(frame)
        matched = cv2.convertScaleAbs(frame, alpha=1.0 / gain)
        model.update(matched, exposure=gain if follow else 1.0)
    drift = model.exposure_gain(frame)  # the unchanged frame's brightness over the model's
    if follow:
        assert drift == pytest.approx(1.0, abs=0.03)
    else:
        assert drift > 1.3


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize("skew", [0.0, 2e-4])
def test_a_colour_image_is_warped_as_each_channel_alone(dtype, skew):
    # Colour images take another path through OpenCV than gray ones (BGRA for uint8, three
    # channels for float32): the values must be those of each channel warped alone (to the
    # last float bit: OpenCV's multi-channel float kernels round a little differently).
    rng = np.random.default_rng(3)
    image = (rng.random((61, 83, 3)) * 255).astype(dtype)
    matrix = np.array([[1.01, 0.02, 2.3], [-0.015, 0.99, -1.7], [skew, -skew, 1.0]])
    for flags in (cv2.INTER_LINEAR, cv2.INTER_NEAREST):
        warped = warp_image(image, matrix, (83, 61), flags, cv2.BORDER_REPLICATE)
        assert warped.shape == image.shape and warped.dtype == image.dtype
        for k in range(3):
            alone = warp_image(np.ascontiguousarray(image[:, :, k]), matrix, (83, 61), flags,
                               cv2.BORDER_REPLICATE)
            np.testing.assert_allclose(warped[:, :, k], alone, rtol=1e-6, atol=0)

