"""The moving-camera engines' foreground cues end to end: colour, and motion the image can tell."""

import cv2
import numpy as np
import pytest

from bgsub.engines import create_engine

H, W = 120, 160


def _gray_world(seed=0, h=200, w=320):
    rng = np.random.default_rng(seed)
    small = rng.integers(60, 190, (h // 4, w // 4)).astype(np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def _same_gray_tint(gray):
    """Colours of exactly the gray levels ``gray`` but another hue: +60 blue, -23 red."""
    g = gray.astype(np.float32)
    b, r = g + 60.0, g - 60.0 * 0.114 / 0.299
    return np.dstack([b, g, r]).round().clip(0, 255).astype(np.uint8)


def _chameleon_clip(n=16, pan=2.0):
    """A panning gray scene with a disc that differs from it in colour only (its gray level is
    the scene's under it): a gray-level engine cannot see it."""
    world = _gray_world()
    yy, xx = np.mgrid[:H, :W]
    for k in range(n):
        m = np.float32([[1, 0, -20 - pan * k], [0, 1, -30]])
        gray = cv2.warpAffine(world, m, (W, H), flags=cv2.INTER_LINEAR)
        frame = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
        disc = (xx - (40 + 4 * k)) ** 2 + (yy - 60) ** 2 < 18 ** 2
        frame[disc] = _same_gray_tint(gray)[disc]
        yield frame, disc, gray


@pytest.mark.parametrize("name", ["grbm", "compensated"])
def test_an_object_of_the_backgrounds_gray_level_is_found_by_its_colour(name):
    engine = create_engine(name)
    hits = []
    for k, (frame, disc, gray) in enumerate(_chameleon_clip()):
        seen_in_gray = cv2.absdiff(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), gray)
        assert seen_in_gray.max() <= 1  # the disc is invisible in gray levels
        mask = engine.apply(frame) > 0
        if k >= 4:
            hits.append((np.count_nonzero(mask & disc) / disc.sum(),
                         np.count_nonzero(mask & ~disc) / (~disc).sum()))
    recall, false_rate = np.mean(hits, axis=0)
    assert recall > 0.7
    assert false_rate < 0.02


def test_the_debug_picture_carries_the_flow_colour_legend():
    from bgsub.io.flowio import add_colour_wheel

    engine = create_engine("grbm")
    for frame, _, _ in _chameleon_clip(n=3):
        engine.apply(frame)
    picture = engine.debug_image()
    scale = engine.frontend.colour_scale()
    # The legend is drawn last, over the picture: drawing it again changes nothing.
    assert np.array_equal(add_colour_wheel(picture, scale), picture)
    corner = picture[-30:, -30:].reshape(-1, 3).astype(int)
    assert len(np.unique(corner, axis=0)) > 20  # the wheel's many hues
