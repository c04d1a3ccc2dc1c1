"""`bgsub flow`: image pair -> .flo (+ picture), video -> flow video, and its error messages."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.flowio import read_flo

SHIFT = (2, -1)  # (dx, dy): frame2[y + dy, x + dx] == frame1[y, x]


def _texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    smooth = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), 1.5)
    smooth = (smooth - smooth.min()) / (smooth.max() - smooth.min())
    return (smooth * 255).astype(np.uint8)


@pytest.fixture
def pair(tmp_path):
    dx, dy = SHIFT
    big = _texture(140, 180)
    f1 = big[10:130, 10:170]
    f2 = big[10 - dy:130 - dy, 10 - dx:170 - dx]
    p1, p2 = tmp_path / "a.png", tmp_path / "b.png"
    cv2.imwrite(str(p1), cv2.cvtColor(f1, cv2.COLOR_GRAY2BGR))  # colour file
    cv2.imwrite(str(p2), f2)  # gray file: mixing is fine
    return p1, p2


def test_pair_gives_full_size_flo_close_to_the_true_shift(pair, tmp_path):
    out, vis = tmp_path / "f.flo", tmp_path / "f.png"
    assert main(["flow", str(pair[0]), str(pair[1]), "-o", str(out), "--vis", str(vis), "-q"]) == 0
    flow = read_flo(out)
    assert flow.shape == (120, 160, 2)
    known = np.isfinite(flow).all(axis=2)
    assert known.mean() > 0.5
    err = np.hypot(flow[known, 0] - SHIFT[0], flow[known, 1] - SHIFT[1])
    assert np.mean(err <= 1.0) > 0.8
    picture = cv2.imread(str(vis))
    assert picture.shape == (120, 160, 3)


def test_arrows_picture(pair, tmp_path):
    vis = tmp_path / "arrows.png"
    rc = main(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"), "--vis", str(vis),
               "--arrows", "-q"])
    assert rc == 0
    picture = cv2.imread(str(vis))
    green = (picture[..., 1] > 200) & (picture[..., 0] < 100) & (picture[..., 2] < 100)
    assert green.sum() > 50


def test_video_gives_a_flow_video(tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    big = _texture(120, 200, seed=1)
    for k in range(3):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), big[20:100, 10 + 2 * k:130 + 2 * k])
    out = tmp_path / "flow.avi"
    assert main(["flow", str(folder), "-o", str(out), "-q"]) == 0
    cap = cv2.VideoCapture(str(out))
    frames = 0
    while cap.read()[0]:
        frames += 1
    assert frames == 2


def _error(capsys, argv) -> str:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.startswith("bgsub: error:") and err.count("\n") == 1
    return err


def test_missing_image(capsys, pair, tmp_path):
    err = _error(capsys, ["flow", str(tmp_path / "nope.png"), str(pair[1]), "-o", str(tmp_path / "f.flo")])
    assert "nope.png" in err


def test_unreadable_image(capsys, pair, tmp_path):
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not a png")
    err = _error(capsys, ["flow", str(junk), str(pair[1]), "-o", str(tmp_path / "f.flo")])
    assert "junk.png" in err


def test_different_sizes(capsys, pair, tmp_path):
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), _texture(60, 70))
    err = _error(capsys, ["flow", str(pair[0]), str(small), "-o", str(tmp_path / "f.flo")])
    assert "differ in size" in err


def test_smaller_than_a_patch(capsys, tmp_path):
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), _texture(10, 40))
    err = _error(capsys, ["flow", str(tiny), str(tiny), "-o", str(tmp_path / "f.flo")])
    assert "13x13" in err


def test_unknown_model(capsys, pair, tmp_path):
    err = _error(capsys, ["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--model", "no-such-model"])
    assert "no-such-model" in err


def test_existing_output_needs_overwrite(capsys, pair, tmp_path):
    out = tmp_path / "f.flo"
    out.write_bytes(b"old")
    err = _error(capsys, ["flow", str(pair[0]), str(pair[1]), "-o", str(out)])
    assert "--overwrite" in err and out.read_bytes() == b"old"


def test_output_must_be_flo_for_a_pair(capsys, pair, tmp_path):
    err = _error(capsys, ["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.png")])
    assert ".flo" in err


def test_video_options_refused_for_a_pair(capsys, pair, tmp_path):
    err = _error(capsys, ["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--scale", "0.5"])
    assert "--scale" in err
