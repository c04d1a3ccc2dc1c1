"""bgsub.model.tiling: patch grids, patch extraction and the texture score."""

import numpy as np
import pytest

from bgsub.errors import InputError
from bgsub.model.tiling import extract_patch_pairs, patch_grid, texture_score, to_gray


def test_grid_shape_and_centres():
    centres, (rows, cols) = patch_grid((40, 50), patch_size=13, stride=6)
    assert (rows, cols) == (5, 7)  # (40-13)//6+1, (50-13)//6+1
    assert centres.shape == (35, 2) and centres.dtype == np.float32
    assert tuple(centres[0]) == (6.0, 6.0)
    assert tuple(centres[-1]) == (6.0 + 6 * 6, 6.0 + 4 * 6)


def test_patches_are_cut_at_their_centres():
    rng = np.random.default_rng(0)
    img = rng.random((37, 41)).astype(np.float32)
    pairs = extract_patch_pairs(img, img[::-1].copy(), patch_size=13, stride=6)
    assert pairs.x.shape == (len(pairs.centres), 169) and pairs.x.dtype == np.float32
    for k in (0, 5, len(pairs.centres) - 1):
        cx, cy = pairs.centres[k].astype(int)
        np.testing.assert_array_equal(pairs.x[k], img[cy - 6:cy + 7, cx - 6:cx + 7].ravel())


def test_to_gray_scales_uint8_to_unit_range():
    frame = np.full((4, 5, 3), 255, np.uint8)
    g = to_gray(frame)
    assert g.shape == (4, 5) and g.dtype == np.float32
    np.testing.assert_allclose(g, 1.0, atol=1e-6)


def test_mismatched_frames_are_refused():
    with pytest.raises(InputError):
        extract_patch_pairs(np.zeros((20, 20), np.uint8), np.zeros((20, 21), np.uint8))


def test_texture_low_for_flat_and_single_edge_high_for_checkerboard():
    h, w = 60, 90
    img = np.zeros((h, w), np.float32)
    yy, xx = np.indices((h, 30))
    img[:, 30:60] = ((yy // 4 + xx // 4) % 2).astype(np.float32)  # checkerboard
    img[:, 60:] = 0.0
    img[:, 75:] = 1.0  # one vertical edge: the aperture problem
    centres = np.array([[15, 30], [45, 30], [75, 30]], np.float32)
    flat, checker, edge = texture_score(img, centres)
    assert flat < 0.01
    assert edge < 0.05
    assert checker > 0.5


def test_texture_at_centres_equals_the_full_texture_map_there():
    from bgsub.model.tiling import texture_at, texture_map

    rng = np.random.default_rng(4)
    gray = rng.random((50, 70)).astype(np.float32)
    gray[:, :30] = 0.5  # flat region: zero texture
    centres, _ = patch_grid(gray.shape, patch_size=13, stride=5)
    tmap = texture_map(gray, window=13)
    expected = tmap[centres[:, 1].astype(int), centres[:, 0].astype(int)]
    got = texture_at(gray, centres, window=13)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-9)
    assert got.min() == 0.0 and got.max() > 0.0


@pytest.mark.parametrize("kwargs", [dict(stride=0), dict(stride=-2), dict(patch_size=0)])
def test_extract_patches_refuses_a_step_or_size_below_one(kwargs):
    from bgsub.model.tiling import extract_patches

    with pytest.raises(InputError, match="patch_size and stride must be positive"):
        extract_patches(np.zeros((20, 20), np.float32), **kwargs)


def test_extract_patches_refuses_a_colour_image():
    from bgsub.model.tiling import extract_patches

    with pytest.raises(InputError, match=r"\(H, W\) gray image.*\(20, 20, 3\)"):
        extract_patches(np.zeros((20, 20, 3), np.float32))
