"""NCC block matching, the classical reference for patch motion."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.motion.blockmatch import ncc_block_match, ncc_block_match_at
from bgsub.errors import InputError


def _shifted_texture(dx: int, dy: int, *, h: int = 80, w: int = 96, seed: int = 0):
    """A random texture and the same texture moved by (dx, dy): f2[y + dy, x + dx] == f1[y, x]."""
    rng = np.random.default_rng(seed)
    big = rng.integers(0, 256, (h + 20, w + 20)).astype(np.uint8)
    f1 = big[10:10 + h, 10:10 + w]
    f2 = big[10 - dy:10 - dy + h, 10 - dx:10 - dx + w]
    return f1, f2


@pytest.mark.parametrize("dx, dy", [(2, -3), (0, 0), (-4, 1)])
def test_recovers_known_integer_shift_exactly(dx, dy):
    f1, f2 = _shifted_texture(dx, dy)
    result = ncc_block_match(f1, f2, max_disp=4)
    r, half = 4, 6
    # Every patch whose displaced copy lies inside frame 2 must be found exactly.
    inner = result.flow[half + r:-half - r, half + r:-half - r]
    assert np.isfinite(inner).all()
    assert (inner[..., 0] == dx).all() and (inner[..., 1] == dy).all()
    np.testing.assert_allclose(result.score[half + r:-half - r, half + r:-half - r], 1.0, atol=1e-6)


def test_border_without_full_patch_is_unknown():
    f1, f2 = _shifted_texture(1, 1)
    result = ncc_block_match(f1, f2, max_disp=2)
    assert np.isnan(result.flow[:6]).all() and np.isnan(result.flow[:, -6:]).all()
    assert result.flow.shape == (80, 96, 2) and result.flow.dtype == np.float32


def test_flat_patches_are_unknown():
    f1 = np.full((40, 40), 128, np.uint8)
    result = ncc_block_match(f1, f1, max_disp=2)
    assert np.isnan(result.flow).all()


def test_colour_input_and_sparse_centres():
    f1, f2 = _shifted_texture(-2, 3)
    bgr1, bgr2 = np.repeat(f1[..., None], 3, 2), np.repeat(f2[..., None], 3, 2)
    centres = np.array([[40, 40], [50, 30]])
    disp, score = ncc_block_match_at(bgr1, bgr2, centres, max_disp=3)
    np.testing.assert_array_equal(disp, [[-2, 3], [-2, 3]])
    assert disp.shape == (2, 2) and score.shape == (2,)


def test_size_mismatch_is_input_error():
    with pytest.raises(InputError, match="differ in size"):
        ncc_block_match(np.zeros((30, 30)), np.zeros((30, 31)))


def test_too_small_is_input_error():
    with pytest.raises(InputError, match="smaller than one 13x13 patch"):
        ncc_block_match(np.zeros((12, 30)), np.zeros((12, 30)))
