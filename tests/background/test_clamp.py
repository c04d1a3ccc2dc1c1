"""Frames bounded in place (bgsub.background.clamp): numpy's values, whatever the layout."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.background.clamp import at_least, at_most


@pytest.mark.parametrize("shape", [(0,), (7,), (24, 32), (24, 32, 3), (5, 4, 3, 2)])
@pytest.mark.parametrize("bound", [0.0, 0.3, 25.5])
def test_the_bounds_are_numpys_in_place(shape, bound):
    rng = np.random.default_rng(0)
    a = (rng.normal(0, 20, shape)).astype(np.float32)
    low, high = a.copy(), a.copy()
    assert at_least(low, bound) is low and at_most(high, bound) is high
    np.testing.assert_array_equal(low, np.maximum(a, np.float32(bound)))
    np.testing.assert_array_equal(high, np.minimum(a, np.float32(bound)))


@pytest.mark.parametrize("make", [lambda a: a[:, ::2], lambda a: a.astype(np.float64)])
def test_strided_and_float64_arrays_are_bounded_too(make):
    a = make(np.random.default_rng(1).normal(0, 1, (6, 8)).astype(np.float32))
    expected = np.maximum(a, 0.25)
    at_least(a, 0.25)
    np.testing.assert_array_equal(a, expected)
