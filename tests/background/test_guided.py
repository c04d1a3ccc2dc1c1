"""The mask placed on the frame's own edges, at the input's size (guided_mask)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.background.guided import guided_mask
from bgsub.errors import InputError


def _scene(seed: int = 0, *, ground=70, inside=170) -> tuple:
    """A 480x640 frame: an ellipse of colour (or gray level) ``inside`` on a noisy ground of
    ``ground``; its true (480, 640) mask, and the frame and the mask as an engine has them at
    its 160x120 working size."""
    rng = np.random.default_rng(seed)
    truth = np.zeros((480, 640), np.uint8)
    cv2.ellipse(truth, (300, 230), (131, 77), 17.0, 0, 360, 255, -1)
    frame = np.empty((480, 640) + np.shape(ground), np.float64)
    frame[...] = ground
    frame[truth > 0] = inside
    frame = (frame + rng.normal(0, 6, frame.shape)).clip(0, 255).astype(np.uint8)
    small = cv2.resize(frame, (160, 120), interpolation=cv2.INTER_AREA)
    small_mask = np.where(cv2.resize(truth, (160, 120), interpolation=cv2.INTER_AREA) > 127,
                          255, 0).astype(np.uint8)
    return frame, truth, small, small_mask


def _wrong_pixels(mask: np.ndarray, truth: np.ndarray) -> int:
    return int(np.count_nonzero((mask > 0) != (truth > 0)))


def test_the_edges_follow_the_frame_closer_than_bilinear_upscaling():
    frame, truth, small, small_mask = _scene()
    bilinear = np.where(cv2.resize(small_mask, (640, 480), interpolation=cv2.INTER_LINEAR) > 127,
                        255, 0).astype(np.uint8)
    guided = guided_mask(small_mask, small, frame, radius=2, eps=1e-3)
    assert guided.shape == truth.shape and guided.dtype == np.uint8
    assert set(np.unique(guided)) <= {0, 255}
    # The blocky working-size outline is wrong along the whole boundary; the guided one snaps
    # to the ellipse's edge.
    assert _wrong_pixels(guided, truth) < 0.5 * _wrong_pixels(bilinear, truth)


def test_an_object_of_another_colour_but_the_same_gray_is_followed():
    # Gray levels equal inside and out (BGR to gray weighs G 0.587, R 0.299, B 0.114): only
    # the colour guide sees the edge.
    frame, truth, small, small_mask = _scene(ground=(60, 130, 40), inside=(200, 62, 120))
    gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    assert abs(float(gray[truth > 0].mean()) - float(gray[truth == 0].mean())) < 3
    colour = guided_mask(small_mask, small, frame, radius=2, eps=1e-3)
    by_gray = guided_mask(small_mask, cv2.cvtColor(small, cv2.COLOR_BGR2GRAY), gray,
                              radius=2, eps=1e-3)
    assert _wrong_pixels(colour, truth) < 0.5 * _wrong_pixels(by_gray, truth)


def test_an_empty_mask_stays_empty():
    frame, _, small, _ = _scene()
    out = guided_mask(np.zeros((120, 160), np.uint8), small, frame, radius=4, eps=0.01)
    assert out.shape == (480, 640) and not out.any()


def test_a_mask_over_a_flat_frame_keeps_its_place():
    # No edges to follow: the mask is its own smooth upscaling, neither grown nor shrunk much.
    _, truth, _, small_mask = _scene()
    flat_small = np.full((120, 160), 90, np.uint8)
    flat = np.full((480, 640), 90, np.uint8)
    out = guided_mask(small_mask, flat_small, flat, radius=2, eps=0.01)
    assert abs(int(np.count_nonzero(out)) - int(np.count_nonzero(truth))) < 0.05 * np.count_nonzero(
        truth)
    assert _wrong_pixels(out, truth) < 0.1 * np.count_nonzero(truth)


def test_a_fit_on_shrunk_images_follows_the_edges_too():
    # The fast guided filter: coefficients fitted every 2nd or 4th working pixel and scaled
    # back up still place the outline on the ellipse, at the input's size and at the working
    # size (from an outline 3 px off).
    frame, truth, small, small_mask = _scene()
    bilinear = cv2.resize(small_mask, (640, 480), interpolation=cv2.INTER_LINEAR) > 127
    small_truth = cv2.resize(truth, (160, 120), interpolation=cv2.INTER_AREA) > 127
    offset = np.roll(small_mask, 3, axis=1)
    for step in (2, 4):
        fast = guided_mask(small_mask, small, frame, radius=4, eps=1e-3, step=step)
        assert set(np.unique(fast)) <= {0, 255}
        assert _wrong_pixels(fast, truth) < 0.1 * _wrong_pixels(bilinear, truth)
        at_work = guided_mask(offset, small, small, radius=4, eps=1e-3, step=step)
        assert at_work.shape == (120, 160)
        assert _wrong_pixels(at_work, small_truth) < 0.5 * _wrong_pixels(offset, small_truth)


def test_a_step_below_one_is_refused():
    frame, _, small, small_mask = _scene()
    with pytest.raises(InputError, match="step"):
        guided_mask(small_mask, small, frame, radius=4, eps=1e-3, step=0)



@pytest.mark.parametrize("size", [(487, 353), (641, 470), (160, 119)])
def test_an_object_is_placed_as_if_the_whole_frame_were_filtered(size):
    # The scaled-up mask is computed only around the mask's bounding box. Two specks in
    # opposite corners stretch that box over the whole frame: away from the specks the
    # result must not change, at scales that are not whole numbers.
    rng = np.random.default_rng(size[0])
    frame = rng.integers(0, 256, size[::-1] + (3,), np.uint8)
    small = cv2.resize(frame, (150, 110), interpolation=cv2.INTER_AREA)
    reach = int(12 * size[0] / 150) + 4  # input px: the specks' windows, scaled up, and more
    for centre in [(40, 30), (75, 55), (120, 90)]:
        mask = np.zeros((110, 150), np.uint8)
        cv2.circle(mask, centre, 9, 255, -1)
        specks = mask.copy()
        specks[0, 0] = specks[-1, -1] = 255
        alone = guided_mask(mask, small, frame, radius=3, eps=1e-3)
        whole = guided_mask(specks, small, frame, radius=3, eps=1e-3)
        away = np.ones(alone.shape, bool)
        away[:reach, :reach] = away[-reach:, -reach:] = False
        assert alone.any()
        np.testing.assert_array_equal(alone[away], whole[away])
