"""`bgsub analogy`: refusals of bad options, inputs and outputs, each one line before any work."""

from __future__ import annotations

import errno
import os

import cv2
import numpy as np
import pytest

from bgsub.cli import main


def _dots(size: int, seed: int) -> np.ndarray:
    """Sparse bright dots on black: what the default (binary, random-dot) model expects."""
    rng = np.random.default_rng(seed)
    return np.where(rng.random((size, size)) < 0.1, 255, 0).astype(np.uint8)


@pytest.fixture
def images(tmp_path):
    """X, Y (X moved 1 px right) and X2, one 13x13 patch each."""
    x, x2 = _dots(13, 0), _dots(13, 1)
    paths = [tmp_path / "x.png", tmp_path / "y.png", tmp_path / "x2.png"]
    for path, image in zip(paths, (x, np.roll(x, 1, axis=1), x2)):
        cv2.imwrite(str(path), image)
    return [str(p) for p in paths]



def test_writes_the_analogy(images, tmp_path):
    out = tmp_path / "y2.png"
    assert main(["analogy", *images, "-o", str(out), "--zoom", "4", "-q"]) == 0
    assert cv2.imread(str(out), cv2.IMREAD_GRAYSCALE).shape == (52, 52)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp left


def test_output_may_not_replace_an_input(capsys, images, bgsub_error):
    before = open(images[2], "rb").read()
    err = bgsub_error(["analogy", *images, "-o", images[2], "--overwrite"])
    assert "-o would overwrite an input" in err
    assert open(images[2], "rb").read() == before


@pytest.mark.parametrize("stride", ["0", "-1"])
def test_stride_below_one(capsys, images, tmp_path, stride, bgsub_error):
    err = bgsub_error(["analogy", *images, "-o", str(tmp_path / "y2.png"), "--stride", stride])
    assert f"--stride must be at least 1, not {stride}" in err


def test_stride_larger_than_a_patch(capsys, images, tmp_path, bgsub_error):
    err = bgsub_error(["analogy", *images, "-o", str(tmp_path / "y2.png"), "--stride", "14"])
    assert "13x13" in err and "use 1 to 13" in err


@pytest.mark.parametrize("zoom", ["0", "65", "100000"])
def test_zoom_out_of_range(capsys, images, tmp_path, zoom, bgsub_error):
    err = bgsub_error(["analogy", *images, "-o", str(tmp_path / "y2.png"), "--zoom", zoom])
    assert f"--zoom must be from 1 to 64, not {zoom}" in err


def test_zoom_of_a_large_image_is_bounded(capsys, tmp_path, bgsub_error):
    paths = []
    for name, seed in (("x", 0), ("y", 1), ("x2", 2)):
        paths.append(str(tmp_path / f"{name}.png"))
        cv2.imwrite(paths[-1], _dots(300, seed))
    out = tmp_path / "y2.png"
    err = bgsub_error(["analogy", *paths, "-o", str(out), "--zoom", "60"])
    assert "16384 px" in err and "--zoom 54 or less" in err
    assert not out.exists()


def test_folder_given_as_an_image(capsys, images, tmp_path, bgsub_error):
    folder = tmp_path / "gray"
    folder.mkdir()
    err = bgsub_error(["analogy", str(folder), *images[1:], "-o", str(tmp_path / "y2.png")])
    assert "gray: is a folder, not an image file" in err


def test_output_folder_missing(capsys, images, tmp_path, bgsub_error):
    err = bgsub_error(["analogy", *images, "-o", str(tmp_path / "nodir" / "y2.png")])
    assert "does not exist" in err


def test_output_extension_without_an_encoder(capsys, images, tmp_path, bgsub_error):
    err = bgsub_error(["analogy", *images, "-o", str(tmp_path / "y2.xyz")])
    assert "-o: cannot write an image with this extension" in err


def test_output_folder_not_writable(capsys, images, tmp_path, monkeypatch, bgsub_error):
    # Checked before any work; os.access is faked because root may write anywhere.
    folder = tmp_path / "locked"
    folder.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw:
                        False if os.fspath(path) == str(folder) else real_access(path, mode, **kw))
    err = bgsub_error(["analogy", *images, "-o", str(folder / "y2.png")])
    assert "not writable" in err


def test_disk_full_while_writing(capsys, images, tmp_path, monkeypatch, bgsub_error):
    def full(*_args, **_kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "replace", full)
    out = tmp_path / "y2.png"
    err = bgsub_error(["analogy", *images, "-o", str(out)])
    assert f"cannot write image {out}: {os.strerror(errno.ENOSPC)}" in err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no partial file


def test_success_is_a_bgsub_note_on_stderr(images, tmp_path, capsys):
    # Like flow's "bgsub: flow of ... written to ...": a note, not a result on stdout.
    out = tmp_path / "y2.png"
    assert main(["analogy", *images, "-o", str(out), "--zoom", "4"]) == 0
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"bgsub: analogy of 13x13 written to {out} (52x52 with --zoom 4)\n"


def test_quiet_silences_the_note(images, tmp_path, capsys):
    assert main(["analogy", *images, "-o", str(tmp_path / "y2.png"), "-q"]) == 0
    assert capsys.readouterr() == ("", "")
