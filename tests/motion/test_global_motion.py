"""bgsub.motion.global_motion: RANSAC camera motion with outliers and refusals."""

import numpy as np
import pytest

from bgsub.motion.global_motion import (apply_homography, corner_error, fast_median,
                                        fit_global_motion, simplest_model)


def _true_h():
    a = np.deg2rad(1.5)
    return np.array([[1.01 * np.cos(a), -np.sin(a), 6.0],
                     [np.sin(a), 1.01 * np.cos(a), -3.0],
                     [2e-5, -1e-5, 1.0]])


@pytest.mark.parametrize("model", ["homography", "affine", "similarity"])
def test_recovers_motion_with_half_outliers(model):
    rng = np.random.default_rng(1)
    h = _true_h() if model == "homography" else np.vstack([_true_h()[:2], [0, 0, 1]])
    if model == "similarity":
        h = np.array([[0.99, -0.02, 4.0], [0.02, 0.99, 2.0], [0, 0, 1.0]])
    src = rng.uniform([0, 0], [320, 240], (400, 2))
    dst = apply_homography(h, src) + rng.normal(0, 0.2, (400, 2))
    bad = rng.random(400) < 0.5
    dst[bad] = rng.uniform([0, 0], [320, 240], (bad.sum(), 2))
    gm = fit_global_motion(src, dst, model=model, frame_size=(320, 240), threshold=1.5)
    assert gm.ok, gm.reason
    assert corner_error(gm.matrix, h, width=320, height=240) < 0.5
    # Inliers are (mostly) the true correspondences.
    assert np.mean(gm.inliers[~bad]) > 0.9 and np.mean(gm.inliers[bad]) < 0.05


_TRUTHS = {
    "translation": [[1, 0, 0.3], [0, 1, -0.2], [0, 0, 1]],
    "similarity": [[0.995, -0.017, 2.0], [0.017, 0.995, 1.0], [0, 0, 1]],
    "affine": [[1.02, 0.03, 2.0], [-0.01, 0.97, 1.0], [0, 0, 1]],
    "homography": [[1.0, 0.0, 2.0], [0.0, 1.0, 1.0], [3e-4, -2e-4, 1]],
}


@pytest.mark.parametrize("model", list(_TRUTHS))
def test_auto_chooses_the_model_that_moved_the_points(model):
    rng = np.random.default_rng(5)
    truth = np.array(_TRUTHS[model], float)
    src = rng.uniform([0, 0], [320, 240], (300, 2))
    dst = apply_homography(truth, src) + rng.normal(0, 0.1, (300, 2))
    dst[:60] += rng.uniform(-10, 10, (60, 2))
    gm = fit_global_motion(src, dst, model="auto", frame_size=(320, 240), threshold=1.5)
    assert gm.ok, gm.reason
    name, matrix = simplest_model(src, dst, gm.matrix, gm.inliers)
    assert name == model
    np.testing.assert_allclose(matrix, gm.matrix, atol=1e-4)
    assert corner_error(gm.matrix, truth, width=320, height=240) < 0.15


def test_auto_does_not_invent_zoom_from_vectors_in_two_strips():
    """Vectors on two narrow vertical structures (a tower, a rocket) of a slowly panning
    camera: a homography fits their reading noise with a zoom and a tilt; auto keeps the
    translation they agree on."""
    rng = np.random.default_rng(7)
    n = 80
    xs = np.where(np.arange(n) < n // 2, rng.uniform(60, 66, n), rng.uniform(250, 258, n))
    src = np.column_stack([xs, rng.uniform(0, 240, n)])
    dst = src + [0.25, 0.0] + rng.normal(0, 0.25, (n, 2))
    truth = np.array([[1, 0, 0.25], [0, 1, 0], [0, 0, 1.0]])
    homography = fit_global_motion(src, dst, model="homography", frame_size=(320, 240),
                                   threshold=1.5)
    auto = fit_global_motion(src, dst, model="auto", frame_size=(320, 240), threshold=1.5)
    np.testing.assert_array_equal(auto.matrix[:2, :2], np.eye(2))
    error = corner_error(auto.matrix, truth, width=320, height=240)
    assert error < 0.05
    assert corner_error(homography.matrix, truth, width=320, height=240) > 2 * error


def test_weights_drop_unreliable_points():
    rng = np.random.default_rng(2)
    src = rng.uniform([0, 0], [320, 240], (200, 2))
    dst = src + [3.0, -1.0]
    # 70% wrong, all with weight 0: only the reliable 30% are used.
    bad = np.arange(200) < 140
    dst[bad] = src[bad] + rng.uniform(-8, 8, (140, 2))
    w = np.where(bad, 0.0, 1.0)
    gm = fit_global_motion(src, dst, weights=w, model="affine", threshold=1.5)
    assert gm.ok
    np.testing.assert_allclose(gm.matrix[:2, 2], [3.0, -1.0], atol=0.05)
    assert not gm.inliers[bad].any()


def test_too_few_points_is_refused_not_garbage():
    src = np.array([[0, 0], [10, 0], [0, 10]], float)
    gm = fit_global_motion(src, src + 1.0, threshold=1.5)
    assert not gm.ok and "too few" in gm.reason
    np.testing.assert_array_equal(gm.matrix, np.eye(3))


def test_implausible_motion_is_refused():
    rng = np.random.default_rng(3)
    src = rng.uniform([0, 0], [320, 240], (100, 2))
    gm = fit_global_motion(src, src * 3.0, model="affine", frame_size=(320, 240), threshold=1.5)
    assert not gm.ok and "degenerate" in gm.reason


def test_translation_model():
    rng = np.random.default_rng(4)
    src = rng.uniform([0, 0], [320, 240], (100, 2))
    dst = src + [-7.5, 2.25]
    dst[:40] += rng.uniform(-20, 20, (40, 2))
    gm = fit_global_motion(src, dst, model="translation", threshold=1.5)
    assert gm.ok
    np.testing.assert_allclose(gm.matrix[:2, 2], [-7.5, 2.25], atol=1e-6)


def test_identity_and_affine_tests():
    from bgsub.motion.global_motion import is_affine, is_identity

    eye = np.eye(3)
    assert is_identity(eye) and is_identity(eye + 1e-9)
    assert not is_identity(np.array([[1, 0, 0.01], [0, 1, 0], [0, 0, 1.0]]))
    assert is_affine(np.array([[1.1, 0.1, 3], [0, 0.9, 2], [0, 0, 2.0]]))
    assert not is_affine(_true_h())


# ---------------------------------------------------------------- bad input: InputError, one line

def _pan_points(n=60, seed=5):
    src = np.random.default_rng(seed).uniform([0, 0], [320, 240], (n, 2))
    return src, src + [3.0, -2.0]


@pytest.mark.parametrize("bad", ["xyz", "transposed"])
def test_fit_refuses_points_that_are_not_n_by_2(bad):
    from bgsub.errors import InputError

    src, dst = _pan_points()
    if bad == "xyz":  # (N, 3): reshaping it to (N * 3 / 2, 2) would mix the axes
        src, dst = np.hstack([src, np.ones((60, 1))]), np.hstack([dst, np.ones((60, 1))])
    else:
        src, dst = src.T, dst.T
    with pytest.raises(InputError, match=r"src must be \(N, 2\) points"):
        fit_global_motion(src, dst, model="translation", threshold=1.5)


def test_fit_accepts_opencv_point_layout():
    src, dst = _pan_points()
    gm = fit_global_motion(src.reshape(-1, 1, 2), dst.reshape(-1, 1, 2), model="translation",
                           threshold=1.5)
    assert gm.ok and gm.inliers.shape == (60,)
    np.testing.assert_allclose(gm.matrix[:2, 2], [3.0, -2.0], atol=1e-4)


def test_fit_refuses_weights_of_another_length():
    from bgsub.errors import InputError

    src, dst = _pan_points()
    with pytest.raises(InputError, match=r"weights must be \(60,\).*\(59,\)"):
        fit_global_motion(src, dst, weights=np.ones(59), threshold=1.5)


@pytest.mark.parametrize("threshold", [0.0, -1.0, float("nan")])
def test_fit_refuses_a_threshold_that_is_not_positive(threshold):
    from bgsub.errors import InputError

    src, dst = _pan_points()
    with pytest.raises(InputError, match="threshold must be a distance > 0"):
        fit_global_motion(src, dst, threshold=threshold, model="translation")


def test_apply_homography_refuses_a_2x3_matrix_and_3d_points():
    from bgsub.errors import InputError

    pts = np.array([[1.0, 2.0], [3.0, 4.0]])
    with pytest.raises(InputError, match=r"\(3, 3\) matrix, not shape \(2, 3\).*\[0, 0, 1\]"):
        apply_homography(np.eye(3)[:2], pts)
    with pytest.raises(InputError, match=r"points must be \(N, 2\).*\(2, 3\)"):
        apply_homography(np.eye(3), np.ones((2, 3)))
    # OpenCV's (N, 1, 2) still maps to (N, 2).
    np.testing.assert_allclose(apply_homography(np.eye(3), pts.reshape(-1, 1, 2)), pts)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("n", [1, 2, 7, 8, 1001, 1002])
def test_fast_median_is_numpys_median_to_the_bit(dtype, n):
    rng = np.random.default_rng(n)
    values = (rng.normal(size=(n, 2)) * 50).astype(dtype)
    values[: n // 3] = np.round(values[: n // 3])  # ties
    column = fast_median(values[:, 0])
    assert column == np.median(values[:, 0]) and column.dtype == dtype
    assert np.array_equal(fast_median(values), np.median(values, axis=0))
