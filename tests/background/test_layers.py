"""bgsub.background.layers: in a 3-D scene each block of the compensated model takes the warp
that explains the frame best, on a two-layer world with exact motions and through the engine
on a ``parallax`` sample scene."""

import numpy as np
import pytest

from helpers import random_texture, shifted

from bgsub import create_engine
from bgsub.background.compensated import CompensatedBackground
from bgsub.background.layers import choose_layers
from bgsub.samples import SceneSpec, render_frames

H, W = 96, 128
FAR, NEAR = 2.0, 6.0  # px a frame: the far layer (top half) and the near band (bottom half)


def _two_layers(k):
    """Frame ``k`` (H, W, 3) uint8: two textures panning left, the bottom half three times as
    fast as the top."""
    far = shifted(random_texture(H, W + 80, seed=1), -FAR * k, 0, H, W)
    near = shifted(random_texture(H, W + 80, seed=2), -NEAR * k, 0, H, W)
    frame = far.copy()
    frame[H // 2:] = near[H // 2:]
    return np.repeat(frame[:, :, None], 3, axis=2)


def _pan(dx):
    return np.array([[1.0, 0.0, -dx], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


@pytest.fixture
def warped():
    """``(model warped by the far layer's motion, a copy warped by the band's, frame 1)``."""
    bg = CompensatedBackground()
    bg.restart(_two_layers(0))
    band = bg.warped_copy(_pan(NEAR))
    bg.warp(_pan(FAR))
    return bg, band, _two_layers(1)


def test_a_warped_copy_leaves_the_model_as_it_was():
    bg = CompensatedBackground()
    bg.restart(_two_layers(0))
    before = bg.mean.copy()
    copy = bg.warped_copy(_pan(NEAR))
    assert np.array_equal(bg.mean, before)
    assert np.abs(copy.mean[:, :-8] - before[:, 6:-2]).max() < 1e-3


def test_each_layer_takes_the_warp_that_explains_it(warped):
    bg, band, frame = warped
    score = bg.score(frame)
    assert np.median(score[H // 2 + 8:]) > 1  # the band, warped by the far layer's motion
    chosen = choose_layers(bg, [band], frame, score, block=9)
    assert np.median(chosen[:H // 2 - 8, 8:-8]) < 0.5 and np.median(chosen[H // 2 + 8:, :-8]) < 0.5
    # The model itself now holds the band where the band is: the next frame's warp moves it.
    assert np.array_equal(bg.mean[H // 2 + 8:, :-8], band.mean[H // 2 + 8:, :-8])
    assert np.median(bg.score(frame)[H // 2 + 8:, :-8]) < 0.5


def test_pixels_under_the_last_mask_keep_the_fields_warp(warped):
    bg, band, frame = warped
    keep = np.zeros((H, W), np.uint8)
    keep[H // 2:, :W // 2] = 255  # an object seen there last frame
    chosen = choose_layers(bg, [band], frame, bg.score(frame), block=9, keep=keep)
    assert np.median(chosen[H // 2 + 8:, 8:W // 2]) > 1
    assert np.median(chosen[H // 2 + 8:, W // 2 + 8:-8]) < 0.5


def _false_and_missed(**params):
    """``(false-positive, missed)`` pixel counts of grbm on a ``parallax`` sample scene whose
    near band's edge the field alone smears."""
    engine = create_engine("grbm", **params)
    spec = SceneSpec("parallax", seed=7, n_frames=60)
    fp = fn = 0
    for k, (image, gt, _) in enumerate(render_frames(spec)):
        mask = engine.apply(image) > 0
        if k >= spec.warmup_frames:
            fp += np.count_nonzero(mask & (gt == 0))
            fn += np.count_nonzero(~mask & (gt == 255))
    return fp, fn


def test_the_layers_clear_the_false_foreground_along_a_near_bands_edge():
    fp, fn = _false_and_missed()
    fp_field, fn_field = _false_and_missed(parallax_layers=0)
    assert fp_field > 1000 and fp < 0.2 * fp_field
    assert fn <= 1.2 * fn_field + 20
