"""`bgsub flow` with the paper's random-dot models reproduces their model cards' figures
(models/dots-translation.md, models/dots-rotation.md) through the command line."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.io.flowio import read_flo
from bgsub.model.training import RotatedDots

SHIFTS = [(dx, dy) for dy in (-1, 0, 1) for dx in (-1, 0, 1)]  # the paper's 9 classes


def _dot_pair(tmp_path, size: int, dx: int, dy: int, seed: int):
    """Random dots (10 % on) and the same dots moved by ``(dx, dy)``, as two PNG files."""
    rng = np.random.default_rng(seed)
    big = ((rng.random((size + 2, size + 2)) < 0.1) * 255).astype(np.uint8)
    first = big[1:1 + size, 1:1 + size]
    second = big[1 - dy:1 - dy + size, 1 - dx:1 - dx + size]  # second[r + dy, c + dx] = first[r, c]
    paths = tmp_path / f"a{dx}{dy}.png", tmp_path / f"b{dx}{dy}.png"
    cv2.imwrite(str(paths[0]), first)
    cv2.imwrite(str(paths[1]), second)
    return first, paths


def _flow(paths, out, *extra) -> np.ndarray:
    assert main(["flow", str(paths[0]), str(paths[1]), "-o", str(out), "-q", *map(str, extra)]) == 0
    return read_flo(out)


@pytest.mark.parametrize("dx, dy", SHIFTS)
def test_nine_shifts_per_pixel_max_flow_as_in_the_model_card(tmp_path, dx, dy):
    # Model card: per-pixel max-flow right for 99.98 % of the 'on' pixels >= 1 px from the
    # border, global direction 100 %.
    first, paths = _dot_pair(tmp_path, 48, dx, dy, seed=10 + 3 * dx + dy)
    flow = _flow(paths, tmp_path / "d.flo", "--model", "dots-translation")
    inner = np.zeros(first.shape, bool)
    inner[1:-1, 1:-1] = True
    right = np.all(flow == (dx, dy), axis=2)
    assert right[(first > 0) & inner].mean() >= 0.995
    assert tuple(np.median(flow[inner], axis=0)) == (dx, dy)


@pytest.mark.parametrize("dx, dy", [(1, 0), (-1, 1), (0, 0)])
def test_shift_through_the_patch_readout(tmp_path, dx, dy):
    _, paths = _dot_pair(tmp_path, 64, dx, dy, seed=3)
    flow = _flow(paths, tmp_path / "d.flo", "--model", "dots-translation", "--readout", "patch")
    known = np.isfinite(flow).all(axis=2)
    assert known.mean() > 0.9
    assert np.all(np.abs(flow[known] - (dx, dy)) < 0.5)


def test_rotation_test_as_in_the_model_card(tmp_path):
    # The card's test: 1,000 fresh 13x13 pairs (seed 1000) rotated within +-30 degrees, a
    # RANSAC similarity fitted to the max-flow vectors of each pair's 'on' pixels. Each pair is
    # one image of the patch's size; laid side by side in one mosaic, a grid step of 13 reads
    # each tile as its own patch, in one command.
    n, p, cols = 1000, 13, 40
    x, y, angles = RotatedDots(patch_size=p, max_angle=30.0).sample(np.random.default_rng(1000), n)
    rows = n // cols

    def mosaic(tiles: np.ndarray) -> np.ndarray:
        grid = tiles.reshape(rows, cols, p, p).transpose(0, 2, 1, 3).reshape(rows * p, cols * p)
        return (grid * 255).astype(np.uint8)

    paths = tmp_path / "x.png", tmp_path / "y.png"
    cv2.imwrite(str(paths[0]), mosaic(x))
    cv2.imwrite(str(paths[1]), mosaic(y))
    flow = _flow(paths, tmp_path / "r.flo", "--model", "dots-rotation", "--stride", p)
    gy, gx = np.mgrid[0:p, 0:p].astype(np.float32)
    errors = []
    for k in range(n):
        r, c = divmod(k, cols)
        tile = flow[r * p:(r + 1) * p, c * p:(c + 1) * p]
        on = x[k].reshape(p, p) > 0.5
        src = np.stack([gx[on], gy[on]], axis=1)
        m, _ = cv2.estimateAffinePartial2D(src, src + tile[on], method=cv2.RANSAC,
                                           ransacReprojThreshold=1.0)
        angle = math.degrees(math.atan2(m[1, 0], m[0, 0])) if m is not None else math.inf
        errors.append(abs((angle - angles[k] + 180.0) % 360.0 - 180.0))
    errors = np.asarray(errors)
    # Card: median 1.59 deg, mean 1.85 deg, 98.1 % within 5 deg.
    assert np.median(errors) <= 1.6
    assert np.mean(errors <= 5.0) >= 0.98
