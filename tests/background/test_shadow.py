"""Cast shadows are background (bgsub.background.shadow.ShadowVeto, the foreground's last step on
a moving camera)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.background.compensated import CompensatedBackground
from bgsub.background.shadow import ShadowVeto
from bgsub.engines import create_engine
from helpers import random_texture

H, W = 60, 80


def _colour_texture(h, w, seed):
    """``(h, w, 3) uint8``: a smooth random colour texture."""
    planes = [random_texture(h, w, seed=seed + c)[:h, :w] for c in range(3)]
    return np.dstack(planes)


def _model_of(background, *, age=10.0):
    """A compensated model that has learnt ``background`` for ``age`` frames."""
    bg = CompensatedBackground()
    bg.reset(background)
    bg.age[...] = age
    return bg


def _veto(frame, background, mask=None, *, age=10.0, **settings):
    veto = ShadowVeto(**{"low": 0.5, "chroma": 0.03, "texture": 0.7, **settings})
    mask = np.full((H, W), 255, np.uint8) if mask is None else mask
    return veto.veto(mask, frame, _model_of(background, age=age))


@pytest.fixture
def background():
    return _colour_texture(H, W, seed=1)


def _darker(image, factor):
    return np.clip(image.astype(np.float32) * factor, 0, 255).astype(np.uint8)


def test_the_background_in_shade_is_cleared(background):
    out = _veto(_darker(background, 0.7), background)
    assert np.count_nonzero(out) < 0.05 * out.size


@pytest.mark.parametrize("factor", [0.3, 0.98])
def test_too_dark_or_hardly_darker_is_not_shade(background, factor):
    out = _veto(_darker(background, factor), background)
    assert np.count_nonzero(out) > 0.95 * out.size


def test_an_object_of_its_own_texture_is_kept(background):
    obj = _darker(_colour_texture(H, W, seed=7), 0.8)
    out = _veto(obj, background)
    assert np.count_nonzero(out) > 0.8 * out.size


def test_a_darker_object_of_another_colour_is_kept(background):
    tinted = np.clip(background * np.float32([0.6, 0.6, 0.9]), 0, 255).astype(np.uint8)  # redder
    out = _veto(tinted, background)
    assert np.count_nonzero(out) > 0.8 * out.size


def test_only_mask_pixels_of_a_learnt_model_are_cleared(background):
    shade = _darker(background, 0.7)
    mask = np.zeros((H, W), np.uint8)
    mask[:, : W // 2] = 255
    out = _veto(shade, background, mask.copy())
    assert not out[:, W // 2:].any()
    young = _veto(shade, background, age=0.0)
    assert np.all(young == 255)


def test_off_or_gray_leaves_the_mask_as_it_is(background):
    shade = _darker(background, 0.7)
    assert np.all(_veto(shade, background, low=0.0) == 255)
    gray, gray_bg = (cv2.cvtColor(i, cv2.COLOR_BGR2GRAY) for i in (shade, background))
    assert np.all(_veto(gray, gray_bg) == 255)


def _shadow_clip(n=30, h=180, w=240):
    """``(frames, objects, shadows)``: a colour world panning 3 px a frame, a flat red square
    crossing it the other way, and the square's shadow (the world at 60 % of its brightness)
    beside it, moving with it; the last two as (h, w) bool per frame."""
    world = _colour_texture(h + 8, w + 3 * n + 8, seed=3)
    frames, objects, shadows = [], [], []
    for k in range(n):
        frame = np.ascontiguousarray(world[4:4 + h, 3 * k:3 * k + w])
        x0 = 30 + 3 * k
        obj, shade = np.zeros((h, w), bool), np.zeros((h, w), bool)
        obj[60:100, x0:x0 + 40] = True
        shade[100:130, x0 + 10:x0 + 60] = True
        frame[shade] = _darker(frame[shade], 0.6)
        frame[obj] = (40, 40, 200)
        frames.append(frame)
        objects.append(obj)
        shadows.append(shade)
    return frames, objects, shadows


def _found(mask, where):
    return np.count_nonzero((mask > 0) & where) / np.count_nonzero(where)


def test_a_moving_camera_finds_the_object_and_not_its_shadow():
    frames, objects, shadows = _shadow_clip()
    with_veto = create_engine("grbm", lookback=0)
    without = create_engine("grbm", lookback=0, shadow=0.0)
    found = {"veto": [], "none": []}
    for k, frame in enumerate(frames):
        a, b = with_veto.apply(frame), without.apply(frame)
        if k >= 15:
            found["veto"].append((_found(a, objects[k]), _found(a, shadows[k])))
            found["none"].append((_found(b, objects[k]), _found(b, shadows[k])))
    veto, none = np.mean(found["veto"], axis=0), np.mean(found["none"], axis=0)
    assert veto[0] > 0.8 and none[0] > 0.8  # the object, either way
    assert none[1] > 0.3  # the shadow moves with it: without the veto much of it is foreground
    assert veto[1] < 0.05
