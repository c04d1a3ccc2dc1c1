"""A near layer beyond the reduced read's reach (bgsub.camera.near_layer): found in a parallax
field or guessed from scattered vectors with exact answers, and read a second time by the
engine on two-layer scenes."""

import cv2
import numpy as np
import pytest
from helpers import random_texture

from bgsub import create_engine
from bgsub.camera.near_layer import leading_layer, probed_layer
from bgsub.motion.global_motion import GlobalMotion
from bgsub.motion.result import MotionResult
from bgsub.camera.parallax import ParallaxConfig, ParallaxField

SHAPE = (240, 320)  # (h, w)
PAN = np.array([[1.0, 0.0, -2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # the far layer's motion


def _band_field(departure, *, top=168, x0=0, x1=SHAPE[1]):
    """``(h, w, 2) float32``: a field that moves rows from ``top`` down, columns ``x0:x1``,
    by ``departure`` (dx, dy) beyond the plane, and leaves the rest on it."""
    field = np.zeros(SHAPE + (2,), np.float32)
    field[top:, x0:x1] = departure
    return field


def test_a_band_ahead_of_the_plane_is_a_near_layer_with_its_shift_and_region():
    layer = leading_layer(_band_field((-4.0, 0.0)), PAN, least=0.75)
    assert layer is not None
    assert np.allclose(layer.shift, (-4.0, 0.0))
    band, far = np.mgrid[172:240:4, 0:320:4], np.mgrid[0:164:4, 0:320:4]
    assert layer.covers(band[::-1].reshape(2, -1).T).all()
    assert not layer.covers(far[::-1].reshape(2, -1).T).any()
    assert not layer.covers(np.array([[-5.0, 200.0], [400.0, 200.0]])).any()  # outside
    assert np.allclose(layer.prior(PAN)[:2, 2], (-6.0, 0.0))  # the plane, then the shift


def test_a_band_whose_departure_grows_across_the_view_is_one_near_layer():
    # (its upper half of departures is the right half of the band: the band reaches across)
    field = _band_field((-1.0, 0.0))
    field[168:, :, 0] *= np.linspace(3.0, 6.0, SHAPE[1], dtype=np.float32)
    layer = leading_layer(field, PAN, least=0.75)
    assert layer is not None and layer.covers(np.array([[8.0, 200.0], [312.0, 200.0]])).all()


def test_a_band_lagging_behind_the_plane_is_no_near_layer():
    # (what a subject the camera follows looks like: it departs against the pan)
    assert leading_layer(_band_field((4.0, 0.0)), PAN, least=0.75) is None


def test_a_compact_region_ahead_of_the_plane_is_no_near_layer():
    # (an object overtaking the camera's motion, 96 px of the 320 px view)
    assert leading_layer(_band_field((-4.0, 0.0), top=100, x0=100, x1=196),
                         PAN, least=0.75) is None


def _band_vectors(seed, band_speed):
    """``(points, disp, weights)``: the far layer moving by ``PAN``, the frame's bottom 30 %
    ``band_speed`` times as fast; 0.1 px of noise."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[4:SHAPE[0]:8, 4:SHAPE[1]:8]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    disp = np.tile(PAN[:2, 2], (len(pts), 1))
    disp[pts[:, 1] >= 0.7 * SHAPE[0]] *= band_speed
    return pts, disp + rng.normal(0, 0.1, disp.shape), np.ones(len(pts))


def _scattered(seed, share=0.3, pan=PAN):
    """``(points, disp, weights)``: the far layer moving by ``pan``; the frame's bottom
    ``share`` read wrong, scattered by 3 px."""
    rng = np.random.default_rng(seed)
    pts, disp, weights = _band_vectors(seed, band_speed=1.0)
    disp[:] = pan[:2, 2]
    band = pts[:, 1] >= (1 - share) * SHAPE[0]
    disp[band] += rng.normal(0, 3.0, (np.count_nonzero(band), 2))
    return pts, disp, weights, band


def test_scattered_vectors_across_the_view_suggest_a_layer_twice_as_fast_as_the_plane():
    pts, disp, weights, band = _scattered(0)
    layer = probed_layer(pts, disp, weights, PAN, SHAPE, share=0.15, least=1.5)
    assert layer is not None
    assert np.allclose(layer.shift, PAN[:2, 2])  # the plane's motion again
    covered = layer.covers(pts)
    assert covered[~band].sum() == 0 and covered[band].mean() > 0.8  # (a few read it right)


def test_a_guessed_layer_spans_the_lines_along_the_shift_that_its_scattered_vectors_hold():
    # (every other column of the band reads the plane's motion, as a flat or repeating stretch
    # of ground does: those vectors do not scatter, yet they are the same layer)
    pts, disp, weights, band = _scattered(0, share=0.4)
    on_plane = band & (pts[:, 0] % 16 == 4)
    disp[on_plane] = PAN[:2, 2]
    layer = probed_layer(pts, disp, weights, PAN, SHAPE, share=0.15, least=1.5)
    covered = layer.covers(pts)
    assert covered[on_plane].all() and not covered[~band].any()


def test_a_guessed_layer_leaves_the_lines_of_a_compact_object_out():
    pts, disp, weights, band = _scattered(0, share=0.4)
    thing = (np.abs(pts[:, 0] - 100) < 30) & (np.abs(pts[:, 1] - 60) < 30)
    disp[thing] += (3.0, 0.0)  # an object, off the plane, in the far layer's rows
    layer = probed_layer(pts, disp, weights, PAN, SHAPE, share=0.15, least=1.5)
    far = ~band & ~thing
    assert layer.covers(pts)[band].all() and not layer.covers(pts)[far].any()


def test_few_scattered_vectors_or_a_slow_plane_suggest_no_layer():
    pts, disp, weights, _ = _scattered(0, share=0.1)
    assert probed_layer(pts, disp, weights, PAN, SHAPE, share=0.15, least=1.5) is None
    slow = PAN.copy()
    slow[0, 2] = -1.0
    pts, disp, weights, _ = _scattered(0, pan=slow)
    assert probed_layer(pts, disp, weights, slow, SHAPE, share=0.15, least=1.5) is None


def test_a_layer_is_probed_only_where_no_field_stands_and_the_probe_is_on():
    pts, disp, weights, _ = _scattered(0)
    result = MotionResult(pts, disp, weights, GlobalMotion(PAN, np.ones(len(pts), bool), True))
    young = ParallaxField(ParallaxConfig())
    assert young.layer_to_probe(result, SHAPE) is None  # before a field could stand
    assert _after(4, band_speed=1.0).layer_to_probe(result, SHAPE) is not None  # none stands
    off = _after(4, 1.0, ParallaxConfig(parallax_probe=0))
    assert off.layer_to_probe(result, SHAPE) is None
    assert _after(4, band_speed=3.0).layer_to_probe(result, SHAPE) is None  # a field stands


def test_a_field_that_stood_a_frame_ago_does_not_hold_the_guess_back():
    pts, disp, weights, _ = _scattered(0)
    result = MotionResult(pts, disp, weights, GlobalMotion(PAN, np.ones(len(pts), bool), True))
    parallax = _after(4, band_speed=3.0)
    parallax.estimate(*_band_vectors(5, band_speed=1.0), PAN, SHAPE)  # no field this frame
    assert parallax.standing() and parallax.layer_to_probe(result, SHAPE) is not None


def test_after_a_refused_guess_the_next_ones_wait_longer():
    pts, disp, weights, _ = _scattered(0)
    result = MotionResult(pts, disp, weights, GlobalMotion(PAN, np.ones(len(pts), bool), True))
    parallax = _after(4, band_speed=1.0)
    guessed = []
    for _ in range(7):
        layer = parallax.layer_to_probe(result, SHAPE)
        guessed.append(layer is not None)
        if layer is not None:
            parallax.probe_taken(False)
    assert guessed == [True, False, True, False, False, True, False]  # waits 1, then 2
    parallax.probe_taken(True)
    assert [parallax.layer_to_probe(result, SHAPE) is not None for _ in range(5)] == [
        False, False, False, True, True]  # (the wait running) then every frame again


def _after(frames, band_speed, config=ParallaxConfig()):
    parallax = ParallaxField(config)
    for k in range(frames):
        parallax.estimate(*_band_vectors(k, band_speed), PAN, SHAPE)
    return parallax


def test_only_a_layer_that_departs_by_parallax_layer_px_is_read_again():
    assert _after(4, band_speed=3.0).layer_to_read() is not None  # 4 px beyond the plane
    assert _after(4, band_speed=2.0).layer_to_read() is None  # 2 px: the read reaches it
    assert _after(4, 3.0, ParallaxConfig(parallax_layer=0)).layer_to_read() is None  # off


def test_the_layer_is_read_again_for_parallax_keep_frames_after_it_was_seen():
    parallax = _after(4, 3.0, ParallaxConfig(parallax_keep=2))
    flat = _band_vectors(9, band_speed=1.0)
    read = []
    for _ in range(3):
        parallax.estimate(*flat, PAN, SHAPE)
        read.append(parallax.layer_to_read() is not None)
    assert read == [True, True, False]
    parallax.restart()
    assert parallax.layer is None


def _printed_lines(h, w, seed):
    """``(h, w) uint8``: a page, rows of dark glyphs 2-5 px wide on a light ground, with gaps."""
    rng = np.random.default_rng(seed)
    page = np.full((h, w), 190, np.float32)
    for y in range(3, h - 8, 11):
        x = int(rng.integers(0, 20))
        while x < w - 8:
            if rng.random() < 0.15:
                x += int(rng.integers(20, 60))
                continue
            width = int(rng.integers(2, 6))
            page[y:y + 7, x:x + width] = 60
            x += width + int(rng.integers(1, 4))
    return cv2.GaussianBlur(page, (3, 3), 0.7).astype(np.uint8)


def _two_layer_clip(n, *, far=2.0, near=8.0, top=172, ground=random_texture):
    """``n`` BGR frames (240 x 320) of a camera translating past near ground: the view's rows
    from ``top`` down (textured by ``ground(h, w, seed)``) move ``near`` px a frame, the rest
    ``far`` (4x as fast: 6 px beyond the plane, out of the model's reach from it)."""
    h, w = SHAPE
    rng = np.random.default_rng(0)
    layers = [(texture(h, w + int(v * n) + 16, seed), v)
              for texture, seed, v in ((random_texture, 1, far), (ground, 2, near))]
    frames = []
    for k in range(n):
        views = [cv2.warpAffine(tex, np.float32([[1, 0, -v * k], [0, 1, 0]]), (w, h),
                                flags=cv2.INTER_LINEAR) for tex, v in layers]
        img = np.where(np.arange(h)[:, None] >= top, views[1], views[0]).astype(np.float64)
        img = np.clip(img + rng.normal(0, 1.5, img.shape), 0, 255).astype(np.uint8)
        frames.append(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
    return frames


@pytest.fixture(scope="module")
def two_layer_clip():
    return _two_layer_clip(60)


def _ground_foreground(frames, **params):
    """The share of the near ground's pixels (below row 176) called foreground over the
    second half of ``frames``."""
    engine = create_engine("grbm", lookback=0, **params)
    shares = [(engine.apply(f) > 0)[176:].mean() for f in frames]
    return float(np.mean(shares[len(frames) // 2:]))


def test_near_ground_beyond_the_reads_reach_stays_background(two_layer_clip):
    assert _ground_foreground(two_layer_clip) < 0.05


def test_without_the_second_read_the_near_ground_is_foreground(two_layer_clip):
    assert _ground_foreground(two_layer_clip, parallax_layer=0) > 0.5


@pytest.fixture(scope="module")
def near_ground_from_the_start():
    # (the ground moves 6 px beyond the plane from the first frame: no field ever shows it)
    return _two_layer_clip(60, far=3.0, near=9.0)


def test_near_ground_read_wrong_from_the_start_stays_background(near_ground_from_the_start):
    assert _ground_foreground(near_ground_from_the_start) < 0.05


def test_near_ground_of_printed_lines_read_wrong_from_the_start_stays_background():
    # (the page's flat ground and repeating glyphs read the plane's motion: only part of the
    # ground scatters off the fit, and those vectors lie across its rows)
    frames = _two_layer_clip(60, near=7.0, ground=_printed_lines)
    assert _ground_foreground(frames) < 0.1


def test_without_the_probe_that_ground_is_foreground(near_ground_from_the_start):
    assert _ground_foreground(near_ground_from_the_start, parallax_probe=0) > 0.5


def test_a_guess_whose_second_read_scatters_too_is_not_taken():
    # (the view's bottom third is new noise every frame, as water or snow: no layer)
    h, w = SHAPE
    rng = np.random.default_rng(3)
    far = random_texture(h, w + 200, seed=1)
    frames = []
    for k in range(24):
        img = cv2.warpAffine(far, np.float32([[1, 0, -3.0 * k], [0, 1, 0]]), (w, h))
        img[160:] = rng.integers(0, 256, (h - 160, w))
        frames.append(cv2.cvtColor(img.astype(np.uint8), cv2.COLOR_GRAY2BGR))
    probed, plain = create_engine("grbm", lookback=0), create_engine("grbm", lookback=0,
                                                                     parallax_probe=0)
    for frame in frames:
        assert np.array_equal(probed.apply(frame), plain.apply(frame))
