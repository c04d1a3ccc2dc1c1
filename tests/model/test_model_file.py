"""The model file format module and the names the model module keeps for it."""

from __future__ import annotations

import numpy as np

from bgsub.model import model_file, rbm
from bgsub.model.rbm import GatedRBM


def _tiny() -> GatedRBM:
    model = GatedRBM.create(patch_size=3, n_factors=4, n_hidden=5, init_scale=0.7,
                            rng=np.random.default_rng(2))
    model.meta = {"max_shift": 1}
    return model


def test_write_model_and_read_model_round_trip(tmp_path):
    model = _tiny()
    path = model_file.write_model(model, tmp_path / "m.npz")
    back = model_file.read_model(path, model_class=GatedRBM)
    for name in model_file.ARRAY_NAMES:
        np.testing.assert_array_equal(getattr(back, name), getattr(model, name))
    assert back.meta["max_shift"] == 1 and back.meta["source"] == str(path)


def test_the_model_methods_write_and_read_the_same_files(tmp_path):
    model = _tiny()
    by_method = model.save(tmp_path / "a.npz")
    by_module = model_file.write_model(model, tmp_path / "b.npz")
    np.testing.assert_array_equal(GatedRBM.load(by_module).wxf,
                                  model_file.read_model(by_method, model_class=GatedRBM).wxf)


def test_the_model_module_keeps_the_file_format_names():
    assert rbm.FORMAT_VERSION == model_file.FORMAT_VERSION
    assert rbm.SHIPPED_MODELS == model_file.SHIPPED_MODELS
    assert rbm.load_model is model_file.load_model
