"""Models the readouts cannot run are refused when made or loaded; trainings that cannot fit
in memory are refused before any data is drawn."""

from __future__ import annotations

import pytest

from bgsub.errors import InputError, ModelError
from bgsub.model.rbm import GatedRBM
from bgsub.model.training import TrainConfig


@pytest.mark.parametrize("changes, words", [
    ({"patch_size": 2}, "patch_size must be at least 3"),
    ({"n_factors": 0}, "at least one factor"),
    ({"n_hidden": 0}, "one mapping unit"),
])
def test_models_that_cannot_read_motion_are_refused(changes, words):
    with pytest.raises(ModelError, match=words):
        GatedRBM.create(**{"patch_size": 5, "n_factors": 4, "n_hidden": 3, **changes})


@pytest.mark.parametrize("value", [7, -1, float("nan"), "4", True, None])
def test_a_saved_range_the_patches_cannot_show_is_refused_on_load(tmp_path, value):
    model = GatedRBM.create(patch_size=13, n_factors=4, n_hidden=3)
    model.meta["max_shift"] = value
    path = model.save(tmp_path / "m.npz")
    with pytest.raises(ModelError, match="meta max_shift .* from 0 to 6"):
        GatedRBM.load(path)


def test_a_range_within_half_the_patch_loads(tmp_path):
    model = GatedRBM.create(patch_size=13, n_factors=4, n_hidden=3)
    model.meta["max_shift"] = 6.0
    assert GatedRBM.load(model.save(tmp_path / "m.npz")).meta["max_shift"] == 6.0


def test_training_refuses_small_patches_and_what_cannot_fit_in_memory():
    with pytest.raises(InputError, match="patch-size must be at least 3"):
        TrainConfig(patch_size=2).check()
    with pytest.raises(InputError, match=r"patch-size 1000 .* about 153.5 GiB"):
        TrainConfig(patch_size=1000).check()
    TrainConfig(patch_size=64).check()  # 0.6 GiB
