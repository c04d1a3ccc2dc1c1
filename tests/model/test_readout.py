"""Readouts: max-flow field, patch displacements, analogies, and `bgsub analogy`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.model.rbm import GatedRBM
from bgsub.model.readout import (
    analogy,
    analogy_images,
    displacement_offsets,
    displacement_scores,
    max_flow_field,
    patch_displacements,
)
from bgsub.model.training import TrainConfig, TranslatedDots, train

P = 9


@pytest.fixture(scope="module")
def shift_model() -> GatedRBM:
    """A small model trained on one-pixel shifts of 9x9 random dots (a few seconds)."""
    cfg = TrainConfig(patch_size=P, n_factors=100, n_hidden=50, n_pairs=10_000, epochs=20, lr=0.1, seed=1,
                      sparsity_cost=0.1)
    return train(TranslatedDots(patch_size=P, max_shift=1), cfg).model


def _random_model(p: int = 4, seed: int = 0) -> GatedRBM:
    return GatedRBM.create(patch_size=p, n_factors=6, n_hidden=5, init_scale=0.8, rng=np.random.default_rng(seed))


def _full_m(model: GatedRBM, h: np.ndarray) -> np.ndarray:
    """M[n, i, j] = sum_f wxf[i, f] wyf[j, f] (h whf)[n, f], directly."""
    return np.einsum("if,jf,nf->nij", model.wxf, model.wyf, h @ model.whf)


def _dots(n: int, seed: int, max_shift: int = 1):
    return TranslatedDots(patch_size=P, max_shift=max_shift).sample(np.random.default_rng(seed), n)


def test_full_max_flow_is_the_argmax_of_the_flow_matrix():
    model = _random_model()
    rng = np.random.default_rng(1)
    x = rng.random((7, 16)).astype(np.float32)
    y = rng.random((7, 16)).astype(np.float32)
    m = _full_m(model, model.hidden_probs(x, y))
    target = m.argmax(axis=2)  # (n, i) -> j
    expected = np.stack([target % 4 - np.arange(16) % 4, target // 4 - np.arange(16) // 4], axis=2)
    flow = max_flow_field(model, x, y)
    assert flow.shape == (7, 4, 4, 2) and flow.dtype == np.float32
    np.testing.assert_array_equal(flow.reshape(7, 16, 2), expected)


def test_displacement_scores_sum_the_flow_matrix_along_each_shift():
    model = _random_model(p=5)
    rng = np.random.default_rng(2)
    x = rng.random((4, 25)).astype(np.float32)
    y = rng.random((4, 25)).astype(np.float32)
    m = _full_m(model, model.hidden_probs(x, y))
    offsets = displacement_offsets(2)
    expected = np.zeros((4, len(offsets)))
    for d, (dx, dy) in enumerate(offsets):
        for r in range(5):
            for c in range(5):
                if 0 <= r + dy < 5 and 0 <= c + dx < 5:
                    expected[:, d] += m[:, r * 5 + c, (r + dy) * 5 + c + dx]
    np.testing.assert_allclose(displacement_scores(model, x, y, max_disp=2), expected, rtol=1e-4, atol=1e-5)


def test_windowed_max_flow_agrees_with_full_wherever_the_full_target_is_in_the_window():
    model = _random_model(p=6, seed=3)
    rng = np.random.default_rng(3)
    x = rng.random((20, 36)).astype(np.float32)
    y = rng.random((20, 36)).astype(np.float32)
    full = max_flow_field(model, x, y)
    window = max_flow_field(model, x, y, radius=2)
    inside = np.abs(full).max(axis=3) <= 2
    assert inside.any() and not inside.all()
    np.testing.assert_array_equal(window[inside], full[inside])
    assert np.abs(window).max() <= 2


def test_windowed_max_flow_equals_full_for_translations(shift_model):
    x_raw, y_raw, shifts = _dots(300, seed=4)
    x, y, _ = shift_model.prepare(x_raw, y_raw)
    full = max_flow_field(shift_model, x, y)
    window = max_flow_field(shift_model, x, y, radius=1)
    on = x.reshape(-1, P, P) > 0.5
    on[:, [0, -1], :] = False
    on[:, :, [0, -1]] = False
    assert np.mean(np.all(full[on] == window[on], axis=1)) > 0.99
    assert np.mean(np.all(window == shifts[:, None, None, :], axis=3)[on]) > 0.95


def test_patch_displacement_is_the_mode_of_the_max_flow_field(shift_model):
    x_raw, y_raw, shifts = _dots(300, seed=5)
    x, y, _ = shift_model.prepare(x_raw, y_raw)
    disp, _ = patch_displacements(shift_model, x, y, max_disp=1, subpixel=False)
    flow = max_flow_field(shift_model, x, y, radius=1)
    code = (flow[..., 1] + 1) * 3 + (flow[..., 0] + 1)  # offset index of each pixel's flow
    on = x.reshape(-1, P, P) > 0.5
    modes = np.array([np.bincount(c[o].astype(int), minlength=9).argmax() for c, o in zip(code, on)])
    mode_disp = displacement_offsets(1)[modes]
    assert np.mean(np.all(disp == mode_disp, axis=1)) > 0.97
    assert np.mean(np.all(disp == shifts, axis=1)) > 0.9


def test_subpixel_refinement_stays_within_half_a_pixel_of_the_peak(shift_model):
    x_raw, y_raw, _ = _dots(200, seed=6)
    x, y, _ = shift_model.prepare(x_raw, y_raw)
    whole, _ = patch_displacements(shift_model, x, y, max_disp=1, subpixel=False)
    fine, conf = patch_displacements(shift_model, x, y, max_disp=1)
    assert fine.dtype == np.float32 and fine.shape == (200, 2) and conf.shape == (200,)
    assert np.abs(fine - whole).max() <= 0.5
    assert np.any(fine != whole)


def test_confidence_is_lower_for_unrelated_patches(shift_model):
    x_raw, y_raw, _ = _dots(300, seed=7)
    other, _, _ = _dots(300, seed=8)
    x, y, _ = shift_model.prepare(x_raw, y_raw)
    _, conf_true = patch_displacements(shift_model, x, y, max_disp=1)
    _, conf_junk = patch_displacements(shift_model, x, other, max_disp=1)
    assert 0.0 <= conf_true.min() and conf_true.max() <= 1.0
    assert np.median(conf_true) > np.median(conf_junk) + 0.2


def test_analogy_moves_a_new_patch_the_same_way(shift_model):
    x_raw, y_raw, shifts = _dots(200, seed=9)
    # New dots x2 and the truth y2: x2 moved by the same shifts as (x, y).
    rng = np.random.default_rng(11)
    big = (rng.random((200, P + 2, P + 2)) < 0.1).astype(np.float32)
    x2 = big[:, 1:-1, 1:-1].reshape(200, -1)
    rows = (1 - shifts[:, 1])[:, None, None] + np.arange(P)[None, :, None]
    cols = (1 - shifts[:, 0])[:, None, None] + np.arange(P)[None, None, :]
    y2 = big[np.arange(200)[:, None, None], rows, cols].reshape(200, -1)
    pred = analogy(shift_model, x_raw, y_raw, x2)
    inner = np.zeros((P, P), bool)
    inner[1:-1, 1:-1] = True
    inner = np.broadcast_to(inner.ravel(), pred.shape)
    on, off = (y2 > 0.5) & inner, (y2 < 0.5) & inner
    assert pred[on].mean() > 3 * pred[off].mean()


def _shifted_images(seed: int, size: int = 27, shift=(1, 0)):
    rng = np.random.default_rng(seed)
    big = (rng.random((size + 2, size + 2)) < 0.1).astype(np.float32)
    dx, dy = shift
    x = big[1:-1, 1:-1]
    y = big[1 - dy : 1 - dy + size, 1 - dx : 1 - dx + size]
    return x, y


def test_analogy_images_transfers_a_shift_patch_by_patch(shift_model):
    x, y = _shifted_images(12)
    x2, y2 = _shifted_images(13)
    out = analogy_images(shift_model, x, y, x2)
    assert out.shape == x.shape and out.dtype == np.float32
    inner = (slice(2, -2), slice(2, -2))
    assert np.corrcoef(out[inner].ravel(), y2[inner].ravel())[0, 1] > np.corrcoef(out[inner].ravel(), x2[inner].ravel())[0, 1] + 0.2


def _png(path, image):
    cv2.imwrite(str(path), np.clip(image * 255, 0, 255).astype(np.uint8))
    return str(path)


def test_cli_analogy_end_to_end(shift_model, tmp_path, capsys):
    model_path = shift_model.save(tmp_path / "m.npz")
    x, y = _shifted_images(14)
    x2, y2 = _shifted_images(15)
    args = [_png(tmp_path / "x.png", x), _png(tmp_path / "y.png", y), _png(tmp_path / "x2.png", x2)]
    out = tmp_path / "y2.png"
    assert main(["analogy", *args, "-o", str(out), "--model", str(model_path), "-q"]) == 0
    result = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE).astype(np.float32)
    assert result.shape == x.shape
    inner = (slice(2, -2), slice(2, -2))
    assert np.corrcoef(result[inner].ravel(), y2[inner].ravel())[0, 1] > 0.5
    # Refuses to overwrite; refuses images of different sizes.
    assert main(["analogy", *args, "-o", str(out), "--model", str(model_path)]) == 2
    small = _png(tmp_path / "small.png", x[:12, :12])
    assert main(["analogy", args[0], args[1], small, "-o", str(tmp_path / "z.png"),
                 "--model", str(model_path)]) == 2
    assert "same size" in capsys.readouterr().err


def test_cli_analogy_missing_image_and_bad_model(tmp_path, capsys):
    assert main(["analogy", "a.png", "b.png", "c.png", "-o", str(tmp_path / "o.png"),
                 "--model", "no-such-model"]) == 2
    assert "shipped" in capsys.readouterr().err


# ---------------------------------------------------------------------- fused raw readout


def _contrast_model(seed: int = 3) -> GatedRBM:
    model = GatedRBM.create(patch_size=7, n_factors=24, n_hidden=12, init_scale=0.3,
                            rng=np.random.default_rng(seed), normalization="contrast")
    model.bh[:] = np.random.default_rng(seed + 1).normal(0, 0.5, model.bh.shape)
    return model


def _raw_pairs(n: int, p: int, seed: int):
    rng = np.random.default_rng(seed)
    x = rng.random((n, p * p)).astype(np.float32)
    y = np.roll(x.reshape(n, p, p), 1, axis=2).reshape(n, p * p) + rng.normal(0, 0.05, (n, p * p))
    y = y.astype(np.float32)
    x[:3] = 0.4  # constant patches: flat pairs
    y[:3] = 0.4
    return x, y


@pytest.mark.parametrize("normalization", ["contrast", "none"])
def test_raw_patch_motion_equals_prepare_then_patch_displacements(normalization):
    from bgsub.model.readout import raw_patch_motion

    model = _contrast_model()
    model.normalization = normalization
    x_raw, y_raw = _raw_pairs(200, 7, seed=5)
    x, y, flat = model.prepare(x_raw, y_raw)
    disp, conf = patch_displacements(model, x, y, max_disp=2)
    conf = np.where(flat, 0.0, conf)
    d2, c2, f2 = raw_patch_motion(model, x_raw, y_raw, max_disp=2)
    np.testing.assert_array_equal(f2, flat)
    assert flat[:3].all()
    np.testing.assert_allclose(d2, disp, atol=1e-3)
    np.testing.assert_allclose(c2, conf, atol=1e-3)


def test_projected_first_frame_patches_can_be_reused_across_reads():
    from bgsub.model.readout import patch_features, raw_patch_motion

    model = _contrast_model()
    x_raw, y_raw = _raw_pairs(64, 7, seed=6)
    feats = patch_features(model, x_raw, side="x")
    for y in (y_raw, y_raw[::-1].copy()):
        direct = raw_patch_motion(model, x_raw, y, max_disp=3)
        reused = raw_patch_motion(model, None, y, max_disp=3, x_features=feats)
        for a, b in zip(direct, reused):
            np.testing.assert_array_equal(a, b)


def test_peak_confidence_ignores_the_peaks_neighbours_and_subpixel_stays_in_half_pixel():
    from bgsub.model.readout import _peaks

    rng = np.random.default_rng(7)
    r, side = 3, 7
    scores = rng.random((300, side * side)).astype(np.float32)
    disp, conf = _peaks(scores, r)
    offsets = displacement_offsets(r)
    best = scores.argmax(axis=1)
    assert np.all(np.abs(disp - offsets[best]) <= 0.5)
    for n in range(0, 300, 37):  # brute-force rival outside the 3x3 neighbourhood
        far = np.max(np.abs(offsets - offsets[best[n]]), axis=1) > 1
        rival = scores[n, far].max()
        expected = (scores[n, best[n]] - rival) / (scores[n, best[n]] - scores[n].mean())
        assert conf[n] == pytest.approx(np.clip(expected, 0, 1), abs=1e-5)


# ---------------------------------------------------------------- bad input: InputError, one line

def test_analogy_images_reads_uint8_images_as_gray_levels(shift_model):
    x, y = _shifted_images(12)
    x2, _ = _shifted_images(13)
    expected = analogy_images(shift_model, x, y, x2)
    as_uint8 = [(im * 255).astype(np.uint8) for im in (x, y, x2)]
    out = analogy_images(shift_model, *as_uint8)
    assert out.min() < 0.5  # uint8 input is scaled to [0, 1]: not a blank (all 1.0) image
    np.testing.assert_allclose(out, expected, atol=1e-4)


@pytest.mark.parametrize("stride", [0, -1, 5, 2.5])
def test_analogy_images_refuses_a_stride_outside_one_to_the_patch_size(stride):
    from bgsub.errors import InputError

    model = _random_model(p=4)
    img = np.random.default_rng(0).random((12, 12)).astype(np.float32)
    with pytest.raises(InputError, match="stride must be from 1 to the model's patch size 4"):
        analogy_images(model, img, img, img, stride=stride)


@pytest.mark.parametrize("sizes", [((12, 12), (12, 12), (12, 13)), ((3, 12), (3, 12), (3, 12))])
def test_analogy_images_refuses_images_of_different_or_too_small_sizes(sizes):
    from bgsub.errors import InputError

    model = _random_model(p=4)
    images = [np.zeros(s, np.float32) for s in sizes]
    with pytest.raises(InputError, match="analogy images.*(same size|smaller than)"):
        analogy_images(model, *images)


def test_patch_displacements_refuses_x_and_y_of_different_counts():
    from bgsub.errors import InputError

    model = _random_model(p=4)
    rng = np.random.default_rng(3)
    x, y = rng.random((5, 16)).astype(np.float32), rng.random((1, 16)).astype(np.float32)
    with pytest.raises(InputError, match=r"\(5, 16\) and \(1, 16\)"):
        patch_displacements(model, x, y, max_disp=1)
