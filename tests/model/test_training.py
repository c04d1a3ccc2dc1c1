"""Training data, the CD-k update, the trainer and `bgsub train`."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.cli import main
from bgsub.errors import InputError, ProcessingError
from bgsub.model.rbm import GatedRBM
from bgsub.model.training import (
    Curriculum,
    FixedPairs,
    RotatedDots,
    TrainConfig,
    TrainingInterrupted,
    TranslatedDots,
    _cd_step,
    _fit_whitening,
    _Params,
    _to_model,
    evaluate_translation,
    train,
)


# ------------------------------------------------------------------------------------- data


def test_translated_dots_are_shifted_copies_without_wrap_around():
    x, y, shifts = TranslatedDots(patch_size=9, max_shift=2).sample(np.random.default_rng(0), 200)
    assert x.shape == y.shape == (200, 81) and x.dtype == np.float32
    assert set(np.unique(x)) <= {0.0, 1.0}
    assert shifts.min() == -2 and shifts.max() == 2
    for (dx, dy), a, b in zip(shifts, x.reshape(-1, 9, 9), y.reshape(-1, 9, 9)):
        # y[r + dy, c + dx] == x[r, c] wherever both are inside the patch.
        src = a[max(0, -dy): 9 - max(0, dy), max(0, -dx): 9 - max(0, dx)]
        dst = b[max(0, dy): 9 - max(0, -dy), max(0, dx): 9 - max(0, -dx)]
        np.testing.assert_array_equal(src, dst)
    # Content entering at the border is new, not wrapped around: y is not a roll of x.
    moved = np.any(shifts != 0, axis=1)
    rolled = [np.array_equal(np.roll(a, (dy, dx), (0, 1)), b)
              for (dx, dy), a, b in zip(shifts[moved], x[moved].reshape(-1, 9, 9), y[moved].reshape(-1, 9, 9))]
    assert np.mean(rolled) < 0.05


def test_dot_density_is_about_ten_percent():
    x, _, _ = TranslatedDots().sample(np.random.default_rng(1), 1000)
    assert 0.09 < x.mean() < 0.11


def test_curriculum_limits_the_shift_range():
    src = TranslatedDots(max_shift=3, curriculum=Curriculum.parse("10:1,20:2"))
    rng = np.random.default_rng(2)
    assert np.abs(src.sample(rng, 500, epoch=5)[2]).max() == 1
    assert np.abs(src.sample(rng, 500, epoch=15)[2]).max() == 2
    assert np.abs(src.sample(rng, 500, epoch=25)[2]).max() == 3


@pytest.mark.parametrize("text", ["10", "a:1", "20:1,10:2", "10:nan", "10:-1", "10:inf"])
def test_bad_curriculum_text_is_an_input_error(text):
    with pytest.raises(InputError):
        Curriculum.parse(text)


def test_curriculum_scaled_to_fewer_epochs_keeps_every_range():
    default = Curriculum.parse("100:1,200:2")
    assert default.scaled(1.0, epochs=400) == default  # the default epoch count: unchanged
    assert str(default.scaled(3 / 400, epochs=3)) == "1:1,2:2"
    assert str(default.scaled(150 / 400, epochs=150)) == "38:1,75:2"
    assert str(default.scaled(2.0)) == "200:1,400:2"
    # Too few epochs for every stage: stages that would get no epoch of their own go, and
    # the full range always keeps the last epochs.
    assert str(default.scaled(2 / 400, epochs=2)) == "1:1"
    assert default.scaled(1 / 400, epochs=1).stages == ()
    with pytest.raises(InputError):
        default.scaled(0.0)


def test_curriculum_says_what_a_short_run_never_reaches():
    curriculum = Curriculum.parse("100:1,200:2,300:3")
    assert curriculum.unreached(400, 4) == ((), None)  # everything runs
    assert curriculum.unreached(300, 4) == ((), 3.0)  # 3 up to the end, never 4
    assert curriculum.unreached(150, 4) == (((300, 3.0),), 2.0)
    assert curriculum.unreached(100, 4) == (((200, 2.0), (300, 3.0)), 1.0)
    # A last limit at (or above) the full range is the full range.
    assert Curriculum.parse("10:1,20:5").unreached(15, 3) == ((), None)


def test_rotated_dots_by_zero_and_ninety_degrees():
    src = RotatedDots(patch_size=9, max_angle=0.0)
    x, y, angles = src.sample(np.random.default_rng(3), 20)
    np.testing.assert_array_equal(x, y)
    x, y = RotatedDots(patch_size=9).rotate(np.random.default_rng(4), np.full(20, 90.0))
    assert x.any()
    for a, b in zip(x.reshape(-1, 9, 9), y.reshape(-1, 9, 9)):
        # Positive angles turn clockwise on screen (y axis down).
        np.testing.assert_array_equal(b, np.rot90(a, -1))


# ------------------------------------------------------------------------------------- CD-1


def _sig(a):
    return 1.0 / (1.0 + np.exp(-a))


def test_one_cd1_step_follows_the_formulas():
    rng = np.random.default_rng(5)
    n, d, f, k = 8, 9, 4, 5
    params = _Params(
        wxf=rng.normal(0, 0.5, (d, f)).astype(np.float32),
        wyf=rng.normal(0, 0.5, (d, f)).astype(np.float32),
        whf=rng.normal(0, 0.5, (k, f)).astype(np.float32),
        bh=rng.normal(0, 0.5, k).astype(np.float32),
        by=rng.normal(0, 0.5, d).astype(np.float32),
    )
    before = _Params(*(a.astype(np.float64) for a in params.arrays()))
    inc = _Params(*(np.zeros_like(a) for a in params.arrays()))
    x = (rng.random((n, d)) < 0.4).astype(np.float32)
    y = (rng.random((n, d)) < 0.4).astype(np.float32)
    cfg = TrainConfig(patch_size=3, n_factors=f, n_hidden=k, momentum=0.0, weight_decay=0.01,
                      sparsity_target=0.1, sparsity_cost=0.5)
    lr = 0.3
    _cd_step(params, inc, x, y, cfg=cfg, lr=lr, rng=np.random.default_rng(6))

    # Direct evaluation with the full three-way tensor, in float64.
    b = before
    w = np.einsum("if,jf,kf->ijk", b.wxf, b.wyf, b.whf)
    h_pos = _sig(np.einsum("ijk,ni,nj->nk", w, x, y) + b.bh)
    u = np.random.default_rng(6).random((n, k), dtype=np.float32)
    h_sample = (u < h_pos).astype(np.float64)
    y_neg = _sig(np.einsum("ijk,ni,nk->nj", w, x, h_sample) + b.by)
    h_neg = _sig(np.einsum("ijk,ni,nj->nk", w, x, y_neg) + b.bh)

    def stats(yy, hh):
        # -dE/dw for E = -sum_ijk x_i y_j h_k W_ijk, by the chain rule through the factors.
        return (np.einsum("ni,nj,nk,jf,kf->if", x, yy, hh, b.wyf, b.whf),
                np.einsum("ni,nj,nk,if,kf->jf", x, yy, hh, b.wxf, b.whf),
                np.einsum("ni,nj,nk,if,jf->kf", x, yy, hh, b.wxf, b.wyf))

    pos, neg = stats(y, h_pos), stats(y_neg, h_neg)
    for name, gp, gn in zip(("wxf", "wyf", "whf"), pos, neg):
        expected = getattr(b, name) + lr * ((gp - gn) / n - cfg.weight_decay * getattr(b, name))
        np.testing.assert_allclose(getattr(params, name), expected, rtol=1e-4, atol=1e-5)
    expected_bh = b.bh + lr * (h_pos - h_neg).sum(0) / n + lr * 0.5 * (0.1 - h_pos.mean(0))
    np.testing.assert_allclose(params.bh, expected_bh, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(params.by, b.by + lr * (y - y_neg).sum(0) / n, rtol=1e-4, atol=1e-5)


def test_whitening_folded_into_the_filters_gives_the_same_model():
    rng = np.random.default_rng(7)
    d, f, k = 9, 6, 4
    raw = rng.normal(size=(500, d)) @ rng.normal(size=(d, d))
    raw -= raw.mean(1, keepdims=True)
    white = _fit_whitening(raw[:250].astype(np.float32), raw[250:].astype(np.float32), 0.999)
    c = white.forward.shape[1]
    params = _Params(
        wxf=rng.normal(0, 0.3, (c, f)).astype(np.float32), wyf=rng.normal(0, 0.3, (c, f)).astype(np.float32),
        whf=rng.normal(0, 0.3, (k, f)).astype(np.float32), bh=rng.normal(size=k).astype(np.float32),
        by=rng.normal(size=c).astype(np.float32),
    )
    cfg = TrainConfig(patch_size=3, n_factors=f, n_hidden=k, output_units="gaussian",
                      normalization="contrast", whiten=True)
    model = _to_model(params, cfg, white, {})
    x = raw[:5].astype(np.float32)
    y = raw[5:10].astype(np.float32)
    xw, yw = x @ white.forward, y @ white.forward
    h_direct = _sig(((xw @ params.wxf) * (yw @ params.wyf)) @ params.whf.T + params.bh)
    np.testing.assert_allclose(model.hidden_probs(x, y), h_direct, rtol=1e-4, atol=1e-5)
    y_white = ((xw @ params.wxf) * (h_direct @ params.whf)) @ params.wyf.T + params.by
    np.testing.assert_allclose(model.output_probs(x, h_direct), y_white @ white.backward, rtol=1e-3, atol=1e-4)


# ------------------------------------------------------------------------------------- trainer


def _small_config(**changes) -> TrainConfig:
    base = dict(patch_size=9, n_factors=100, n_hidden=50, n_pairs=10_000, epochs=20, lr=0.1, seed=1,
                sparsity_cost=0.1)
    base.update(changes)
    return TrainConfig(**base)


def test_a_small_model_learns_one_pixel_shifts():
    result = train(TranslatedDots(patch_size=9, max_shift=1), _small_config())
    scores = evaluate_translation(result.model, max_shift=1, n=500)
    assert scores["patch_accuracy"] > 0.9
    assert result.errors[-1] < result.errors[0]


def test_training_is_reproducible_with_a_seed():
    cfg = _small_config(epochs=2, n_pairs=300)
    a = train(TranslatedDots(patch_size=9), cfg).model
    b = train(TranslatedDots(patch_size=9), cfg).model
    np.testing.assert_array_equal(a.wxf, b.wxf)
    c = train(TranslatedDots(patch_size=9), _small_config(epochs=2, n_pairs=300, seed=2)).model
    assert not np.array_equal(a.wxf, c.wxf)


def test_absurd_learning_rate_stops_with_a_clear_error():
    with pytest.raises(ProcessingError, match="diverged.*learning rate"):
        train(TranslatedDots(patch_size=9), _small_config(lr=1e4, init_scale=0.1, epochs=20))


@pytest.mark.parametrize("change", [dict(weight_decay=float("nan")), dict(weight_decay=-1.0),
                                    dict(sparsity_cost=float("nan")), dict(sparsity_cost=-1.0),
                                    dict(seed=-1)])
def test_settings_that_cannot_work_are_refused_before_training(change):
    # NaN weight decay would train and then report a misleading "diverged".
    with pytest.raises(InputError):
        _small_config(**change).check()


def test_ctrl_c_keeps_the_model_of_the_last_finished_epoch():
    # 300 pairs = 3 minibatches per epoch; Ctrl-C right after the second update of epoch 3,
    # when the weights are already part-way into that epoch.
    def interrupt(epoch, batch):
        if (epoch, batch) == (2, 1):
            raise KeyboardInterrupt

    after = {}

    def keep(epoch, error, get_model):
        after[epoch + 1] = get_model()

    # Caught as a KeyboardInterrupt: callers that do not know TrainingInterrupted still stop
    # (and a regression fails this test rather than interrupting the whole test run).
    with pytest.raises(KeyboardInterrupt) as stop:
        train(TranslatedDots(patch_size=9), _small_config(epochs=5, n_pairs=300), on_epoch=keep,
              on_batch=interrupt)
    assert isinstance(stop.value, TrainingInterrupted)
    result = stop.value.result
    assert result.epochs_run == 2 and len(result.errors) == 2 and result.stopped_early
    assert result.model.meta["epochs"] == 2 and result.model.meta["interrupted"] is True
    np.testing.assert_array_equal(result.model.wxf, after[2].wxf)


def test_ctrl_c_in_the_first_epoch_is_a_plain_keyboard_interrupt():
    def interrupt(epoch, batch):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as stop:
        train(TranslatedDots(patch_size=9), _small_config(epochs=5, n_pairs=300), on_batch=interrupt)
    assert not isinstance(stop.value, TrainingInterrupted)


def test_on_batch_is_called_after_every_minibatch_update():
    calls = []
    train(TranslatedDots(patch_size=9), _small_config(epochs=2, n_pairs=300),
          on_batch=lambda epoch, batch: calls.append((epoch, batch)))
    assert calls == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]


def test_flat_training_data_is_refused():
    flat = np.zeros((500, 81), np.float32)
    with pytest.raises(ProcessingError, match="enough contrast"):
        train(FixedPairs(flat, flat), _small_config(epochs=1, n_pairs=500))


def test_wrongly_shaped_training_data_is_refused():
    bad = np.zeros((500, 50), np.float32)
    with pytest.raises(ProcessingError, match="9x9"):
        train(FixedPairs(bad, bad), _small_config(epochs=1, n_pairs=500))


def test_on_epoch_can_stop_training_early():
    seen = []

    def stop_after_two(epoch, error, get_model):
        seen.append(error)
        assert isinstance(get_model(), GatedRBM)
        return epoch == 1

    result = train(TranslatedDots(patch_size=9), _small_config(epochs=10, n_pairs=300), on_epoch=stop_after_two)
    assert result.epochs_run == 2 and result.stopped_early and len(seen) == 2


# ------------------------------------------------------------------------------------- CLI


def _tiny_train_args(out):
    return ["train", "--data", "dots-translation", "-o", str(out), "--epochs", "3", "--pairs", "500",
            "--factors", "20", "--hidden", "10", "--eval-pairs", "50", "--patch-size", "9"]


def test_cli_train_writes_a_loadable_model_and_a_summary(tmp_path, capsys):
    out = tmp_path / "m.npz"
    assert main(_tiny_train_args(out)) == 0
    model = GatedRBM.load(out)
    assert model.patch_size == 9 and model.n_factors == 20 and model.n_hidden == 10
    assert "patch_accuracy" in model.meta["held_out"]
    captured = capsys.readouterr()
    # The summary is notes on stderr ("bgsub: " like every command's), silenced by --quiet.
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert lines[0].startswith("bgsub: trained 3 epochs")
    assert "bgsub: held-out patch accuracy: " in captured.err
    assert lines[-1] == f"bgsub: model written to {out}"


def test_cli_train_quiet_prints_nothing(tmp_path, capsys):
    assert main(_tiny_train_args(tmp_path / "m.npz") + ["-q"]) == 0
    assert capsys.readouterr() == ("", "")


def test_cli_train_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "m.npz"
    out.write_bytes(b"keep me")
    assert main(_tiny_train_args(out)) == 2
    assert "exists" in capsys.readouterr().err
    assert out.read_bytes() == b"keep me"


def test_cli_train_unknown_data_is_an_input_error(tmp_path, capsys):
    assert main(["train", "--data", str(tmp_path / "nothing.mp4"), "-o", str(tmp_path / "m.npz")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_cli_train_divergence_exits_1(tmp_path, capsys):
    args = _tiny_train_args(tmp_path / "m.npz") + ["--lr", "10000"]
    args[args.index("--epochs") + 1] = "20"
    assert main(args) == 1
    assert "diverged" in capsys.readouterr().err
    assert not (tmp_path / "m.npz").exists()


def test_cli_train_bad_blur_is_a_usage_error(tmp_path, capsys):
    args = ["train", "--data", "shifted-images", "--blur", "0,-1", "-o", str(tmp_path / "m.npz")]
    assert main(args) == 2
    assert "blur sigmas must be positive" in capsys.readouterr().err
    assert not (tmp_path / "m.npz").exists()
