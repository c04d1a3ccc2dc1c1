"""The gated RBM: its probabilities against the paper's formulas, normalisation, model files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bgsub.errors import ModelError, OutputError
from bgsub.model.rbm import FORMAT_VERSION, SHIPPED_MODELS, GatedRBM, load_model


def _tiny(output_units: str = "binary", seed: int = 0) -> GatedRBM:
    model = GatedRBM.create(patch_size=3, n_factors=4, n_hidden=5, output_units=output_units,
                            init_scale=0.7, rng=np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    model.bh[:] = rng.normal(size=5)
    model.by[:] = rng.normal(size=9)
    return model


def _tensor(model: GatedRBM) -> np.ndarray:
    """The full three-way tensor W[i, j, k] = sum_f wxf[i, f] wyf[j, f] whf[k, f]."""
    return np.einsum("if,jf,kf->ijk", model.wxf.astype(np.float64), model.wyf.astype(np.float64),
                     model.whf.astype(np.float64))


def _sig(a):
    return 1.0 / (1.0 + np.exp(-a))


def test_hidden_probs_match_the_three_way_formula():
    model = _tiny()
    rng = np.random.default_rng(3)
    x = rng.random((6, 9)).astype(np.float32)
    y = rng.random((6, 9)).astype(np.float32)
    w = _tensor(model)
    expected = _sig(np.einsum("ijk,ni,nj->nk", w, x, y) + model.bh)
    got = model.hidden_probs(x, y)
    assert got.dtype == np.float32 and got.shape == (6, 5)
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("units", ["binary", "gaussian"])
def test_output_probs_match_the_three_way_formula(units):
    model = _tiny(units)
    rng = np.random.default_rng(4)
    x = rng.random((6, 9)).astype(np.float32)
    h = (rng.random((6, 5)) < 0.5).astype(np.float32)
    act = np.einsum("ijk,ni,nk->nj", _tensor(model), x, h) + model.by
    expected = _sig(act) if units == "binary" else act
    np.testing.assert_allclose(model.output_probs(x, h), expected, rtol=1e-4, atol=1e-5)


def test_prepare_contrast_removes_mean_and_shares_one_scale():
    model = GatedRBM.create(patch_size=3, n_factors=2, n_hidden=2, normalization="contrast",
                            contrast_floor=0.02)
    rng = np.random.default_rng(5)
    x_raw = (0.5 + 0.1 * rng.normal(size=(4, 9))).astype(np.float32)
    y_raw = 0.2 + 2.0 * x_raw  # brighter and twice the contrast
    x_raw[3] = 0.3  # a flat patch
    y_raw[3] = 0.3
    x, y, flat = model.prepare(x_raw, y_raw)
    np.testing.assert_allclose(x.mean(1), 0, atol=1e-5)
    np.testing.assert_allclose(y.mean(1), 0, atol=1e-5)
    # One scale for the pair: y stays exactly twice x.
    np.testing.assert_allclose(y[:3], 2 * x[:3], rtol=1e-4, atol=1e-5)
    assert flat.tolist() == [False, False, False, True]


def test_prepare_without_normalisation_flags_empty_dot_patches():
    model = GatedRBM.create(patch_size=3, n_factors=2, n_hidden=2)
    x_raw = np.zeros((2, 9), np.float32)
    x_raw[0, 4] = 1
    x, y, flat = model.prepare(x_raw, x_raw)
    np.testing.assert_array_equal(x, x_raw)
    assert flat.tolist() == [False, True]


def test_save_load_round_trip(tmp_path):
    model = _tiny("gaussian")
    model.normalization = "contrast"
    model.wyf_gen = model.wyf * 2
    model.meta = {"data": "test", "held_out": {"acc": 0.5}}
    path = model.save(tmp_path / "m.npz")
    back = GatedRBM.load(path)
    for name in ("wxf", "wyf", "whf", "bh", "by", "wyf_gen"):
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert (back.patch_size, back.output_units, back.normalization) == (3, "gaussian", "contrast")
    assert back.meta["held_out"] == {"acc": 0.5}
    x = np.random.default_rng(0).random((3, 9)).astype(np.float32)
    np.testing.assert_array_equal(back.hidden_probs(x, x), model.hidden_probs(x, x))


def test_save_refuses_existing_file_without_overwrite(tmp_path):
    path = _tiny().save(tmp_path / "m.npz")
    with pytest.raises(OutputError):
        _tiny().save(path, overwrite=False)


def _write(path, **changes):
    """A valid model file with some entries replaced (None removes one)."""
    model = _tiny()
    entries = {
        "format_version": np.array(FORMAT_VERSION),
        "header": np.array(json.dumps({"patch_size": 3, "output_units": "binary"})),
        "wxf": model.wxf, "wyf": model.wyf, "whf": model.whf, "bh": model.bh, "by": model.by,
    }
    entries.update(changes)
    np.savez(path, **{k: v for k, v in entries.items() if v is not None})
    return path


def test_valid_hand_written_file_loads(tmp_path):
    assert GatedRBM.load(_write(tmp_path / "ok.npz")).n_hidden == 5


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"wxf": np.zeros((10, 4), np.float32)}, "wxf has shape"),
        ({"bh": np.zeros(7, np.float32)}, "bh has shape"),
        ({"whf": np.full((5, 4), np.nan, np.float32)}, "non-finite"),
        ({"by": np.full(9, np.inf, np.float32)}, "non-finite"),
        ({"format_version": np.array(99)}, "version 99"),
        ({"whf": None}, "missing whf"),
        ({"header": np.array("{not json")}, "malformed"),
        ({"header": np.array(json.dumps({"patch_size": 3, "output_units": "poisson"}))}, "output units"),
        # (-3)^2 = 9 fits the arrays, but no patch has a negative side.
        ({"header": np.array(json.dumps({"patch_size": -3, "output_units": "binary"}))},
         "patch_size must be at least 3"),
        ({"header": np.array(json.dumps({"patch_size": 3.5, "output_units": "binary"}))},
         "patch_size 3.5 is not a whole number"),
        ({"header": np.array(json.dumps({"patch_size": 3, "output_units": "binary",
                                         "contrast_floor": float("nan")}))},
         "contrast_floor must be a number above 0, not nan"),
        ({"header": np.array(json.dumps({"patch_size": 3, "output_units": "binary",
                                         "contrast_floor": -1}))},
         "contrast_floor must be a number above 0, not -1.0"),
        ({"format_version": np.array("1")}, "format version '1' is not stored as a whole number"),
        ({"format_version": np.array(1.7)}, "format version 1.7 is not stored as a whole number"),
    ],
)
def test_bad_model_files_are_refused(tmp_path, changes, words):
    path = _write(tmp_path / "bad.npz", **changes)
    with pytest.raises(ModelError, match=words):
        GatedRBM.load(path)


def test_truncated_file_is_refused(tmp_path):
    good = _tiny().save(tmp_path / "m.npz")
    data = good.read_bytes()
    cut = tmp_path / "cut.npz"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelError, match="cut.npz"):
        GatedRBM.load(cut)


def test_garbage_file_is_refused(tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"this is not a zip archive at all" * 10)
    with pytest.raises(ModelError):
        GatedRBM.load(junk)


def test_pickled_object_array_is_refused(tmp_path):
    path = tmp_path / "pickle.npz"
    np.savez(path, format_version=np.array(1), header=np.array([{"a": 1}], dtype=object),
             wxf=np.zeros((9, 4)), wyf=np.zeros((9, 4)), whf=np.zeros((5, 4)), bh=np.zeros(5), by=np.zeros(9))
    # An .npz archive all the same: the problem is the pickle it would take to read the array.
    with pytest.raises(ModelError, match="array 'header' holds Python objects, which only pickle"):
        GatedRBM.load(path)


def test_plain_npy_array_is_refused_with_its_reason(tmp_path):
    path = tmp_path / "weights.npy"
    np.save(path, np.zeros((169, 200), np.float32))
    with pytest.raises(ModelError, match="single .npy array"):
        GatedRBM.load(path)


def test_load_model_by_path_and_unknown_name(tmp_path):
    path = _tiny().save(tmp_path / "m.npz")
    assert load_model(str(path)).n_factors == 4
    with pytest.raises(ModelError) as err:
        load_model("no-such-model")
    for name in SHIPPED_MODELS:
        assert name in str(err.value)


@pytest.mark.parametrize("name", ["dots-translation", "dots-translation-3px", "dots-rotation"])
def test_shipped_dots_models_load(name):
    model = load_model(name)
    assert model.patch_size == 13 and model.output_units == "binary"


def test_a_failed_save_keeps_the_old_model_and_leaves_no_partial_file(tmp_path, monkeypatch):
    import os

    path = _tiny().save(tmp_path / "m.npz")
    before = path.read_bytes()

    def disk_full(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", disk_full)
    with pytest.raises(OutputError, match="cannot write model .*No space left on device"):
        GatedRBM.create(patch_size=5, n_factors=4, n_hidden=3,
                        rng=np.random.default_rng(9)).save(path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.npz"]


@pytest.mark.parametrize("method", ["hidden_probs", "prepare"])
@pytest.mark.parametrize("shapes", [((4, 16), (4, 16)), ((4, 9), (4, 16)), ((4, 9), (3, 9)),
                                    ((4, 9), (1, 9)),
                                    ((9,), (9,))])
def test_inputs_of_another_shape_are_refused(method, shapes):
    from bgsub.errors import InputError

    model = _tiny()  # 3x3 patches: (N, 9)
    x, y = (np.zeros(s, np.float32) for s in shapes)
    with pytest.raises(InputError, match=r"must both be \(N, 9\): N patches of 3x3 pixels"):
        getattr(model, method)(x, y)
