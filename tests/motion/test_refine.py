"""bgsub.motion.refine: sub-pixel refinement of patch vectors from a rough start."""

import numpy as np
import pytest
from helpers import random_texture, shifted

from bgsub.errors import InputError
from bgsub.engines.frontends.grbm import GrbmConfig
from bgsub.motion.refine import refine_vectors

# The grbm front end's refinement settings.
_GRBM = dict(window=GrbmConfig().refine_window, within=GrbmConfig().refine_within)

H, W = 96, 128
TRUE = (1.35, -0.6)  # a sub-pixel shift that a grid of whole pixels cannot read


def _pair():
    texture = random_texture(H, W, seed=3)
    return texture[:H, :W], shifted(texture, *TRUE, H, W)


def _grid():
    ys, xs = np.mgrid[20:H - 20:12, 20:W - 20:12]
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float32)


def test_a_whole_pixel_start_is_refined_to_the_true_sub_pixel_shift():
    prev, cur = _pair()
    points = _grid()
    start = np.tile(np.round(TRUE), (len(points), 1)).astype(np.float32)
    refined = refine_vectors(prev, cur, points, start, **_GRBM)
    assert refined.shape == start.shape and refined.dtype == np.float32
    assert np.median(np.hypot(*(refined - TRUE).T)) < 0.05
    assert np.median(np.hypot(*(start - TRUE).T)) > 0.4


def test_float_frames_in_0_1_refine_as_uint8_frames_do():
    prev, cur = _pair()
    points = _grid()
    start = np.tile(np.round(TRUE), (len(points), 1)).astype(np.float32)
    as_float = refine_vectors(prev / np.float32(255), cur / np.float32(255), points, start,
                              **_GRBM)
    np.testing.assert_allclose(as_float, refine_vectors(prev, cur, points, start, **_GRBM),
                               atol=1e-3)


def test_a_start_that_would_move_beyond_within_is_kept():
    prev, cur = _pair()
    points = _grid()
    start = np.tile(np.round(TRUE), (len(points), 1)).astype(np.float32)
    # The refinement moves every start by about 0.4 px: a bound below that keeps them all.
    np.testing.assert_array_equal(
        refine_vectors(prev, cur, points, start, window=13, within=0.2), start)


def test_a_flat_patch_keeps_its_start():
    flat = np.full((H, W), 128, np.uint8)
    points = _grid()[:3]
    start = np.array([[0.5, 0.0], [1.0, -1.0], [0.0, 0.25]], np.float32)
    np.testing.assert_array_equal(refine_vectors(flat, flat, points, start, **_GRBM), start)


def test_no_vectors_give_no_vectors():
    prev, cur = _pair()
    empty = np.zeros((0, 2), np.float32)
    assert refine_vectors(prev, cur, empty, empty, **_GRBM).shape == (0, 2)


@pytest.mark.parametrize("prev_shape, points_shape", [((H, W + 1), (4, 2)),
                                                      ((H, W), (4, 3))])
def test_mismatched_inputs_are_input_errors(prev_shape, points_shape):
    prev = np.zeros(prev_shape, np.uint8)
    cur = np.zeros((H, W), np.uint8)
    with pytest.raises(InputError, match="refine_vectors"):
        refine_vectors(prev, cur, np.zeros(points_shape), np.zeros(points_shape),
                       **_GRBM)


def test_a_window_below_three_pixels_is_an_input_error():
    prev, cur = _pair()
    points = _grid()[:2]
    with pytest.raises(InputError, match="at least 3"):
        refine_vectors(prev, cur, points, np.zeros_like(points), window=2, within=1.5)
