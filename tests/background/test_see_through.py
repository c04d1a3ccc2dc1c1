"""A semi-transparent watermark word burnt into a moving camera's frames is seen through: found,
taken out of the frames, and the objects under it still watched (bgsub.background.see_through
through the moving-camera engine)."""

import cv2
import numpy as np
import pytest

from bgsub import create_engine
from bgsub.background.see_through import SeeThrough
from bgsub.samples import SceneSpec, render_frames

from helpers import write_pan_clip

WORD_AT = (40, 140)  # the word's baseline start, x y
OPACITY = 0.35


def word(shape) -> np.ndarray:
    """(h, w) uint8: the word's coverage, 255 inside, anti-aliased."""
    out = np.zeros(shape[:2], np.uint8)
    cv2.putText(out, "SAMPLE", WORD_AT, cv2.FONT_HERSHEY_DUPLEX, 2.0, 255, 5, cv2.LINE_AA)
    return out


def with_word(image: np.ndarray) -> np.ndarray:
    """``image`` with a white word blended in at OPACITY, fixed in the frame."""
    a = (word(image.shape).astype(np.float32) / 255 * OPACITY)[..., None]
    return (image * (1 - a) + 255 * a).astype(np.uint8)


def run(*, category: str = "pan", n_frames: int = 90, **params):
    """``(engine, false positives near the word, F)`` over frames 30 on of a sample scene with
    the word burnt in."""
    engine = create_engine("grbm", **params)
    near_word = cv2.dilate(word((240, 320)), np.ones((9, 9), np.uint8)) > 0
    fp_near = tp = fp = fn = 0
    for k, (image, gt, _) in enumerate(render_frames(SceneSpec(category, seed=1,
                                                               n_frames=n_frames))):
        mask = engine.apply(with_word(image)) > 0
        if k < 30:
            continue
        background = gt == 0
        fp_near += np.count_nonzero(mask & background & near_word)
        tp += np.count_nonzero(mask & (gt == 255))
        fp += np.count_nonzero(mask & background)
        fn += np.count_nonzero(~mask & (gt == 255))
    return engine, fp_near, 2 * tp / max(2 * tp + fp + fn, 1)


@pytest.fixture(scope="module")
def seen_through():
    return run()


@pytest.fixture(scope="module")
def left_in():
    return run(see_through=0)


def test_a_watermark_over_a_pan_is_found_where_it_is(seen_through):
    engine, _, _ = seen_through
    x, y, w, h = engine.see_through_box
    ys, xs = np.nonzero(word((240, 320)))
    # The box holds the word, give or take the grown rim, and little more.
    assert x <= xs.min() <= x + 8 and x + w - 8 <= xs.max() <= x + w
    assert y <= ys.min() <= y + 8 and y + h - 8 <= ys.max() <= y + h


def test_seen_through_the_word_is_less_often_foreground(seen_through, left_in):
    _, fp_through, f_through = seen_through
    _, fp_left, f_left = left_in
    assert fp_through < 0.8 * fp_left
    assert f_through > f_left + 0.05  # the objects, under the word too, are still found


def star_field(shape, seed=0) -> np.ndarray:
    """(h, w) uint8: a dark sky with a star every 150 pixels or so, slightly blurred."""
    rng = np.random.default_rng(seed)
    sky = np.full(shape, 12.0) + rng.normal(0, 2, shape)
    stars = rng.integers(0, shape[0] * shape[1], shape[0] * shape[1] // 150)
    sky.flat[stars] += rng.uniform(60, 240, len(stars))
    return np.clip(cv2.GaussianBlur(sky, (0, 0), 0.8) * 1.6, 0, 255).astype(np.uint8)


def test_a_word_over_a_star_field_is_mapped_back_to_the_scene():
    # A sparse, dark scene varies too little around most of the word's pixels for the ratio of
    # spreads to read their opacity; the means read it.
    n = 100
    sky = star_field((240 + 2 * n, 320 + 3 * n))
    coverage = word((240, 320))
    opacity = coverage.astype(np.float32) / 255 * OPACITY
    inside = coverage > 128
    engine = create_engine("grbm")
    errors, contrast = [], []
    for t in range(n):
        scene = sky[2 * t:2 * t + 240, 3 * t:3 * t + 320].astype(np.float32)
        gray = (scene * (1 - opacity) + 255 * opacity).astype(np.uint8)
        engine.apply(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
        if t >= 60 and t % 10 == 0:
            _, mapped = engine.overlays.unveil(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), gray)
            errors.append(np.abs(mapped - scene)[inside].mean())
            contrast.append(np.abs(gray - scene)[inside].mean())
    assert engine.see_through_box is not None
    assert np.mean(contrast) > 50  # (the word as it came)
    assert np.mean(errors) < 8  # gray levels, over the word's pixels


def test_a_word_over_a_star_field_is_background_once_found():
    # Over a dark sky the frames repeat the word as it came, whatever the map back to the scene
    # makes of its letters.
    n = 100
    sky = star_field((240 + 2 * n, 320 + 3 * n), seed=1)
    coverage = word((240, 320))
    opacity = coverage.astype(np.float32) / 255 * OPACITY
    near_word = cv2.dilate(coverage, np.ones((9, 9), np.uint8)) > 0
    engine = create_engine("grbm")
    false_positives = 0
    for t in range(n):
        scene = sky[2 * t:2 * t + 240, 3 * t:3 * t + 320].astype(np.float32)
        gray = (scene * (1 - opacity) + 255 * opacity).astype(np.uint8)
        mask = engine.apply(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
        if t >= 60:
            false_positives += np.count_nonzero(mask[near_word])
    assert engine.see_through_box is not None
    assert false_positives < 0.005 * np.count_nonzero(near_word) * (n - 60)


def test_a_word_over_a_noisy_star_field_is_background_from_early_on():
    # The sensor's noise shows through the word, so its strokes change from frame to frame as
    # the scene does; its letters' edges, fixed by construction, would outweigh them over a
    # dark sky were the word judged whole.
    n = 100
    sky = star_field((240 + 2 * n, 320 + 3 * n), seed=0)
    opacity = word((240, 320)).astype(np.float32) / 255 * OPACITY
    near_word = cv2.dilate(word((240, 320)), np.ones((9, 9), np.uint8)) > 0
    rng = np.random.default_rng(0)
    engine = create_engine("grbm")
    false_positives = 0
    for t in range(n):
        scene = sky[2 * t:2 * t + 240, 3 * t:3 * t + 320].astype(np.float32)
        noisy = scene * (1 - opacity) + 255 * opacity + rng.normal(0, 2.5, scene.shape)
        mask = engine.apply(cv2.cvtColor(np.clip(noisy, 0, 255).astype(np.uint8),
                                         cv2.COLOR_GRAY2BGR))
        if t >= 30:
            false_positives += np.count_nonzero(mask[near_word])
    assert false_positives < 0.005 * np.count_nonzero(near_word) * (n - 30)


def test_a_plain_subject_the_camera_follows_over_a_star_field_is_no_watermark():
    # A plain disc held near one place in the frame, over a sky that streams past: its edge
    # holds still as a letter's does, and only the sensor's noise changes inside it.
    n = 100
    sky = star_field((240 + 2 * n, 320 + 3 * n), seed=1)
    disc = np.zeros((240, 320), np.uint8)
    cv2.circle(disc, (170, 110), 28, 255, -1)
    alpha = cv2.GaussianBlur(disc, (0, 0), 1.0).astype(np.float32) / 255
    rng = np.random.default_rng(1)
    engine = create_engine("grbm")
    found = missed = 0
    for t in range(n):
        scene = sky[2 * t:2 * t + 240, 3 * t:3 * t + 320].astype(np.float32)
        at = np.roll(alpha, (round(1.5 * np.sin(t / 5)), round(1.5 * np.cos(t / 7))), (0, 1))
        frame = scene * (1 - at) + 150 * at + rng.normal(0, 2.5, scene.shape)
        mask = engine.apply(cv2.cvtColor(np.clip(frame, 0, 255).astype(np.uint8),
                                         cv2.COLOR_GRAY2BGR)) > 0
        if t >= 30:
            found += np.count_nonzero(mask & (at > 0.5))
            missed += np.count_nonzero(~mask & (at > 0.5))
    assert found / (found + missed) > 0.97


def test_a_word_over_a_star_field_under_a_shaking_camera_is_background():
    # Under a shake the scene barely moves under the word from one frame to the next, so the
    # see-through tests take it for opaque; its pixels repeat and do not move at all.
    n = 100
    sky = star_field((300, 380), seed=1)
    coverage = word((240, 320))
    opacity = coverage.astype(np.float32) / 255 * OPACITY
    near_word = cv2.dilate(coverage, np.ones((9, 9), np.uint8)) > 0
    rng = np.random.default_rng(2)
    xs = 30 + np.round(12 * np.sin(np.arange(n) / 7) + rng.normal(0, 2, n)).astype(int)
    ys = 30 + np.round(10 * np.cos(np.arange(n) / 9) + rng.normal(0, 2, n)).astype(int)
    engine = create_engine("grbm")
    false_positives = 0
    for t in range(n):
        scene = sky[ys[t]:ys[t] + 240, xs[t]:xs[t] + 320].astype(np.float32)
        gray = (scene * (1 - opacity) + 255 * opacity).astype(np.uint8)
        mask = engine.apply(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR))
        if t >= 60:
            false_positives += np.count_nonzero(mask[near_word])
    assert false_positives < 0.15 * np.count_nonzero(near_word) * (n - 60)


def test_only_the_overlay_pixels_that_look_as_always_are_discounted():
    rng = np.random.default_rng(0)
    frames = [rng.normal(40, 2, (40, 60)).clip(0, 255).astype(np.uint8) for _ in range(8)]
    see = SeeThrough(8)
    for frame in frames:
        see.remember(frame)
    see.region = np.zeros((40, 60), bool)
    see.region[10:30, 10:50] = True
    frame = frames[-1].copy()
    frame[10:30, 30:50] = 120  # an object under the right half of the overlay
    score = np.full((40, 60), 3.0, np.float32)
    see.discount(score, frame)
    assert (score[10:30, 10:30] <= 1).all()  # the overlay as it always looks: background
    assert (score[10:30, 30:50] == 3).all()  # the object under it: as it was
    assert (score[:10] == 3).all() and (score[30:] == 3).all()  # off the overlay: as it was


def test_left_in_no_watermark_is_reported(left_in):
    engine, _, _ = left_in
    assert engine.see_through_box is None


def test_a_still_camera_sees_through_nothing():
    # A still camera's scene does not stream past the word: nothing tells it from the scene.
    engine, _, _ = run(category="static", n_frames=60)
    assert engine.see_through_box is None


def test_without_an_overlay_the_frames_are_left_as_they_are():
    see = SeeThrough(8)
    frame = np.random.default_rng(0).integers(0, 255, (48, 64, 3), np.uint8)
    gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    work, g = see.unveil(frame, gray)
    assert work is frame and g is gray
    assert see.region is None


def test_bgsub_run_reports_the_watermark_once(tmp_path, capsys):
    from bgsub.cli import main

    clip = write_pan_clip(tmp_path / "watermark.avi", seed=1, n=60, fourcc="FFV1",
                          burn_in=with_word)
    assert main(["run", str(clip), "-o", str(tmp_path / "masks.mkv")]) == 0
    err = capsys.readouterr().err
    assert err.count("semi-transparent overlay") == 1
