"""`bgsub train`: bad options and outputs are one clear line before any training; Ctrl-C keeps
what was trained."""

from __future__ import annotations

import errno
import os

import pytest

from bgsub.model import training
from bgsub.cli import main
from bgsub.model.rbm import GatedRBM


def _tiny(out, *extra):
    """A run of well under a second: 9x9 patches, a small model, few pairs."""
    return ["train", "--data", "dots-translation", "-o", str(out), "--epochs", "3", "--pairs", "200",
            "--factors", "20", "--hidden", "10", "--eval-pairs", "20", "--patch-size", "9", "-q",
            *extra]


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("bgsub: error: ") and "internal error" not in err, err
    return lines[0]


@pytest.fixture
def no_training(monkeypatch):
    """Fail the test if training starts: the checks must come first."""
    def refuse(*args, **kwargs):
        raise AssertionError("training started before the options were checked")

    monkeypatch.setattr(training, "train", refuse)


# ------------------------------------------------------------------------------- options


@pytest.mark.parametrize("data, extra, message", [
    ("dots-translation", ["--seed", "-1"], "--seed must be a whole number >= 0, not -1"),
    ("dots-translation", ["--max-shift", "-1"], "--max-shift must be a number of pixels >= 1, not -1"),
    ("dots-translation", ["--max-shift", "0"], "--max-shift must be a number of pixels >= 1, not 0"),
    ("dots-translation", ["--max-shift", "nan"], "--max-shift must be a number of pixels >= 1, not nan"),
    ("shifted-images", ["--max-shift", "nan"], "--max-shift must be a number of pixels >= 1, not nan"),
    ("dots-translation", ["--max-shift", "100"], "--max-shift 100 is too large for 9x9 patches: at most 4"),
    ("shifted-images", ["--max-shift", "4.5"], "--max-shift 4.5 is too large for 9x9 patches: at most 4"),
    ("dots-rotation", ["--max-angle", "-30"], "--max-angle must be in (0, 180] degrees"),
    ("dots-rotation", ["--max-angle", "nan"], "--max-angle must be in (0, 180] degrees"),
    ("shifted-images", ["--blur", "nan"], "--blur: blur sigmas must be positive numbers, not 'nan'"),
    ("shifted-images", ["--blur", "1,inf"], "--blur: blur sigmas must be positive numbers"),
    ("shifted-images", ["--motion-blur", "-3"], "--motion-blur must be a number of pixels >= 0"),
    ("dots-translation", ["--weight-decay", "-1"], "--weight-decay must be a number >= 0, not -1"),
    ("dots-translation", ["--weight-decay", "nan"], "--weight-decay must be a number >= 0, not nan"),
    ("dots-translation", ["--sparsity-cost", "-1"], "--sparsity-cost must be a number >= 0, not -1"),
    ("dots-translation", ["--sparsity-cost", "nan"], "--sparsity-cost must be a number >= 0, not nan"),
    ("dots-translation", ["--eval-pairs", "-5"], "--eval-pairs must be at least 0"),
    ("dots-translation", ["--lr", "nan"], "--lr must be a number > 0, not nan"),
    ("dots-translation", ["--momentum", "nan"], "--momentum must be in [0, 1), not nan"),
    ("dots-translation", ["--batch", "500"], "--batch 500 is larger than --pairs 200"),
    ("dots-translation", ["--video-scale", "nan"], "--video-scale must be a number > 0"),
    ("dots-translation", ["--curriculum", "2:nan"], "--curriculum limits must be numbers >= 0"),
])
def test_bad_option_is_one_line_before_training(tmp_path, capsys, no_training, data, extra, message):
    _refused_before_training(tmp_path, capsys, data, extra, message)


def _refused_before_training(tmp_path, capsys, data, extra, message):
    """``bgsub train`` with ``--data data`` and ``extra`` stops with status 2 and the one-line
    ``message`` before writing a model."""
    out = tmp_path / "m.npz"
    args = _tiny(out, *extra)
    args[args.index("--data") + 1] = data
    assert main(args) == 2
    assert message in _one_error_line(capsys)
    assert not out.exists()


def test_largest_max_shift_for_the_patch_still_trains(tmp_path):
    # 9x9 patches take shifts up to 4 (half the patch); the limit must not be off by one.
    out = tmp_path / "m.npz"
    assert main(_tiny(out, "--max-shift", "4")) == 0
    assert GatedRBM.load(out).meta["max_shift"] == 4


def test_builtin_kind_mixed_with_a_file_says_so(tmp_path, capsys, no_training):
    video = tmp_path / "video.mp4"
    video.write_bytes(b"")
    args = _tiny(tmp_path / "m.npz")
    args[args.index("--data") + 1: args.index("--data") + 2] = ["dots-translation", str(video)]
    assert main(args) == 2
    line = _one_error_line(capsys)
    assert "dots-translation is a built-in data kind and must be given alone" in line
    assert "no such file" not in line


# ------------------------------------------------------------------------------- output


def test_output_folder_is_called_a_folder(tmp_path, capsys, no_training):
    assert main(_tiny(tmp_path)) == 2
    assert "is a folder, not a model file" in _one_error_line(capsys)


def test_output_in_a_missing_folder_is_refused(tmp_path, capsys, no_training):
    assert main(_tiny(tmp_path / "missing" / "m.npz")) == 2
    assert "the folder" in _one_error_line(capsys)


def test_unwritable_output_folder_is_refused_before_training(tmp_path, capsys, monkeypatch, no_training):
    # chmod does not stop root, so the permission check itself answers "no".
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    assert main(_tiny(tmp_path / "m.npz")) == 2
    assert "is not writable" in _one_error_line(capsys)


def test_output_without_the_npz_extension_is_refused_before_training(tmp_path, capsys,
                                                                     no_training):
    assert main(_tiny(tmp_path / "model.txt")) == 2
    assert "ends in .npz" in _one_error_line(capsys)
    assert not (tmp_path / "model.txt").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs a FIFO")
def test_output_that_is_not_a_regular_file_is_never_replaced(tmp_path, capsys, no_training):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert main(_tiny(fifo, "--overwrite")) == 2
    assert "is not a regular file" in _one_error_line(capsys)


def test_write_error_at_save_time_is_one_output_line(tmp_path, capsys, monkeypatch):
    def disk_full(self, path, *, overwrite=True):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(GatedRBM, "save", disk_full)
    out = tmp_path / "m.npz"
    assert main(_tiny(out)) == 2
    assert _one_error_line(capsys) == f"bgsub: error: cannot write the model to {out}: No space left on device"


# ------------------------------------------------------------------------------- Ctrl-C


def _interrupt_at_epoch(monkeypatch, stop_epoch: int) -> None:
    """Ctrl-C when the translated-dots source is asked for the pairs of ``stop_epoch``."""
    draw = training.TranslatedDots.__call__

    def interrupted(self, rng, n, epoch=0):
        if epoch == stop_epoch:
            raise KeyboardInterrupt
        return draw(self, rng, n, epoch)

    monkeypatch.setattr(training.TranslatedDots, "__call__", interrupted)


def test_ctrl_c_keeps_the_model_trained_so_far(tmp_path, capsys, monkeypatch):
    _interrupt_at_epoch(monkeypatch, 2)
    out = tmp_path / "m.npz"
    assert main(_tiny(out)) == 130
    err = capsys.readouterr().err.strip()
    assert err == f"bgsub: interrupted after 2 of 3 epochs; saved the model so far to {out}"
    model = GatedRBM.load(out)
    assert model.meta["epochs"] == 2 and model.meta["interrupted"] is True
    assert model.meta["data_kind"] == "dots-translation"


def test_ctrl_c_in_the_first_epoch_says_nothing_was_written(tmp_path, capsys, monkeypatch):
    _interrupt_at_epoch(monkeypatch, 0)
    out = tmp_path / "m.npz"
    assert main(_tiny(out)) == 130
    assert capsys.readouterr().err.strip() == (
        f"bgsub: interrupted before the first epoch finished; no model was written to {out}")
    assert not out.exists()


def test_ctrl_c_during_the_evaluation_keeps_the_trained_model(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(training, "evaluate_translation", interrupted)
    out = tmp_path / "m.npz"
    assert main(_tiny(out)) == 130
    assert "interrupted during the held-out evaluation; saved the fully trained model" in capsys.readouterr().err
    model = GatedRBM.load(out)
    assert model.meta["epochs"] == 3 and "held_out" not in model.meta


# ------------------------------------------------------------------------------- curriculum


@pytest.fixture
def captured_training(monkeypatch):
    """Record the pair source and config `bgsub train` would train with, then stop (Ctrl-C in
    the first epoch: nothing is written)."""
    seen = {}

    def capture(source, config, **kwargs):
        seen["source"], seen["config"] = source, config
        raise KeyboardInterrupt

    monkeypatch.setattr(training, "train", capture)
    return seen


@pytest.mark.parametrize("extra", [[], ["--epochs", "400"]])
def test_documented_3px_recipe_keeps_its_curriculum(tmp_path, capsys, captured_training, extra):
    # models/dots-translation-3px.md: --max-shift 3 (--epochs 400): 100:1,200:2, unscaled.
    args = ["train", "--data", "dots-translation", "--max-shift", "3", "-o",
            str(tmp_path / "m.npz"), *extra]
    assert main(args) == 130
    assert captured_training["config"].epochs == 400
    assert captured_training["config"].lr_schedule == "linear"
    assert str(captured_training["source"].curriculum) == "100:1,200:2"
    assert "curriculum" not in capsys.readouterr().err


def test_default_curriculum_is_scaled_to_fewer_epochs(tmp_path, capsys):
    # 100:1,200:2 counted absolute epochs: --epochs 3 trained only +-1 shifts.
    out = tmp_path / "m.npz"
    args = _tiny(out, "--max-shift", "3")
    args.remove("-q")
    assert main(args) == 0
    assert GatedRBM.load(out).meta["curriculum"] == "1:1,2:2"
    err = capsys.readouterr().err
    assert ("bgsub: default curriculum 100:1,200:2 (for 400 epochs) scaled to --epochs 3: "
            "1:1,2:2") in err.splitlines()


def test_scaled_curriculum_note_is_silenced_by_quiet(tmp_path, capsys):
    assert main(_tiny(tmp_path / "m.npz", "--max-shift", "3")) == 0
    assert capsys.readouterr().err == ""


def test_curriculum_beyond_the_epochs_is_warned_even_when_quiet(tmp_path, capsys):
    out = tmp_path / "m.npz"
    assert main(_tiny(out, "--max-shift", "3", "--curriculum", "2:1,3:2,100:3")) == 0
    err = capsys.readouterr().err.strip()
    assert err == ("bgsub: warning: --curriculum 2:1,3:2,100:3 reaches beyond --epochs 3: the "
                   "range stays at 2 to the end and never reaches the full --max-shift 3; "
                   "stage 100:3 never runs")
    assert GatedRBM.load(out).meta["curriculum"] == "2:1,3:2,100:3"  # given: kept as it is


def test_curriculum_within_the_epochs_says_nothing(tmp_path, capsys):
    assert main(_tiny(tmp_path / "m.npz", "--max-shift", "3", "--curriculum", "1:1,2:2")) == 0
    assert capsys.readouterr().err == ""


# ------------------------------------------------------------------------------- data kinds


@pytest.mark.parametrize("data, extra, message", [
    ("dots-translation", ["--max-angle", "10"],
     "--max-angle applies to dots-rotation only, not to dots-translation"),
    ("shifted-images", ["--max-angle", "10"],
     "--max-angle applies to dots-rotation only, not to shifted-images"),
    ("dots-rotation", ["--max-shift", "2"],
     "--max-shift applies to dots-translation, shifted-images and video data, not to "
     "dots-rotation (dots-rotation takes --max-angle)"),
    ("dots-translation", ["--blur", "1"], "--blur applies to shifted-images only, not to "
                                          "dots-translation"),
    ("dots-rotation", ["--motion-blur", "3"], "--motion-blur applies to shifted-images only"),
    ("shifted-images", ["--video-step", "2"], "--video-step applies to video data only"),
    ("dots-translation", ["--video-scale", "0.5"], "--video-scale applies to video data only"),
    ("shifted-images", ["--output-units", "binary"],
     "--output-units binary applies to dots data (dots-translation and dots-rotation) only, "
     "not to shifted-images"),
])
def test_option_for_another_data_kind_is_refused(tmp_path, capsys, no_training, data, extra,
                                                 message):
    _refused_before_training(tmp_path, capsys, data, extra, message)


def _video_args(tmp_path, *extra):
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"")  # never read: the options are refused first
    return ["train", "--data", str(video), "-o", str(tmp_path / "m.npz"), "-q", *extra]


@pytest.mark.parametrize("extra, message", [
    (["--output-units", "binary"], "--output-units binary applies to dots data"),
    (["--curriculum", "10:1"], "--curriculum applies to dots-translation, dots-rotation and "
                               "shifted-images, not to video data"),
    (["--max-angle", "10"], "--max-angle applies to dots-rotation only, not to video data"),
    (["--blur", "1"], "--blur applies to shifted-images only, not to video data"),
    (["--eval-pairs", "500"], "--eval-pairs applies to generated data (dots-translation, "
                              "dots-rotation and shifted-images) only, not to video data"),
])
def test_option_that_video_data_does_not_use_is_refused(tmp_path, capsys, monkeypatch, extra,
                                                        message):
    from bgsub.model import imagedata

    def refuse(*args, **kwargs):
        raise AssertionError("the videos were read before the options were checked")

    monkeypatch.setattr(imagedata, "video_frame_pairs", refuse)
    assert main(_video_args(tmp_path, *extra)) == 2
    assert message in _one_error_line(capsys)


def test_video_data_takes_eval_pairs_0_and_its_own_options(tmp_path, monkeypatch):
    # Accepted up to the point where the videos are read.
    from bgsub.model import imagedata

    class Stop(BaseException):  # passes through main(), which turns Exception into a line
        pass

    def reached(*args, **kwargs):
        raise Stop

    monkeypatch.setattr(imagedata, "video_frame_pairs", reached)
    with pytest.raises(Stop):
        main(_video_args(tmp_path, "--eval-pairs", "0", "--video-step", "2", "--max-shift", "2",
                         "--output-units", "gaussian"))


def test_whiten_and_no_whiten_are_mutually_exclusive(tmp_path, capsys, no_training):
    with pytest.raises(SystemExit) as stop:
        main(_tiny(tmp_path / "m.npz", "--whiten", "--no-whiten"))
    assert stop.value.code == 2
    assert "--no-whiten: not allowed with argument --whiten" in capsys.readouterr().err


def test_eval_pairs_help_says_video_has_none(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "Not for video: its motion is unknown" in help_text
    assert "results such as a report table" not in help_text
