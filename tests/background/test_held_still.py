"""bgsub.background.held_still: repeating pixels that do not move at all, told from a pattern
that repeats but shakes with the scene."""

import numpy as np
import cv2

from bgsub.background.held_still import HeldStill


def _texture(seed=0, shape=(64, 96)):
    rng = np.random.default_rng(seed)
    return cv2.GaussianBlur(rng.uniform(0, 255, shape), (0, 0), 1.5)


def _shifted(image, dx, dy):
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(image, m, image.shape[::-1], flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REFLECT).astype(np.uint8)


def _run(shake_px):
    """HeldStill over 30 frames of one texture, every pixel repeating, shaken by up to
    ``shake_px`` px a frame."""
    rng = np.random.default_rng(1)
    texture = _texture()
    held = HeldStill()
    repeating = np.ones(texture.shape, bool)
    last = _shifted(texture, 0, 0)
    for _ in range(30):
        cur = _shifted(texture, *rng.uniform(-shake_px, shake_px, 2))
        held.update(repeating, cur, last)
        last = cur
    return held.mask


def test_a_pattern_that_does_not_move_is_held_still():
    mask = _run(0.0)
    assert mask is not None and mask.mean() > 0.9


def test_a_pattern_that_shakes_by_half_a_pixel_is_not():
    assert _run(0.5) is None


def test_nothing_repeating_holds_nothing():
    held = HeldStill()
    frame = _texture().astype(np.uint8)
    held.update(np.zeros(frame.shape, bool), frame, frame)
    assert held.mask is None
