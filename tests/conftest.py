"""Shared fixtures. Real data in ../shared/data is optional: tests using it skip when absent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.fixture
def shared_data() -> Path:
    """Path to ../shared/data; skips the test when it is not there (as on a user's machine)."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not available at {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture
def bgsub_error(capsys):
    """``bgsub_error(argv)``: run the ``bgsub`` command line, check that it failed with exit
    status 2 and exactly one ``bgsub: error:`` line on stderr, and return that line."""
    from bgsub.cli import main

    def run(argv) -> str:
        code = main([str(a) for a in argv])
        err = capsys.readouterr().err
        assert code == 2, err
        assert err.startswith("bgsub: error:") and err.count("\n") == 1
        return err

    return run


class OracleMatcher:
    """Exhaustive SSD block matching over integer shifts within +-max_disp (test double)."""

    patch_size = 13
    meta = {"max_disp": 3}

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        p = self.patch_size
        x = x_raw.reshape(-1, p, p)
        y = y_raw.reshape(-1, p, p)
        best = np.full(len(x), np.inf)
        disp = np.zeros((len(x), 2), np.float32)
        for dy in range(-max_disp, max_disp + 1):
            for dx in range(-max_disp, max_disp + 1):
                xs = x[:, max(0, -dy):p - max(0, dy), max(0, -dx):p - max(0, dx)]
                ys = y[:, max(0, dy):p - max(0, -dy), max(0, dx):p - max(0, -dx)]
                err = ((xs - ys) ** 2).mean(axis=(1, 2))
                better = err < best
                best[better] = err[better]
                disp[better] = (dx, dy)
        return disp, np.ones(len(x), np.float32), np.zeros(len(x), bool)


_NATURAL = {}


def model_path():
    """grbm needs a model file: the shipped natural model when installed, else skip."""
    from bgsub.errors import ModelError
    from bgsub.model.rbm import load_model

    if "m" not in _NATURAL:
        try:
            load_model("natural")
            _NATURAL["m"] = "natural"
        except ModelError as err:
            pytest.skip(f"shipped natural model not installed: {err}")
    return _NATURAL["m"]


def random_texture(h, w, seed=0):
    """A smooth random texture: ``(h + 8, w + 8) uint8`` (crop it to ``[:h, :w]``)."""
    import cv2

    rng = np.random.default_rng(seed)
    img = rng.random((h // 4 + 1, w // 4 + 1)).astype(np.float32)
    img = cv2.resize(img, (w + 8, h + 8), interpolation=cv2.INTER_CUBIC)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def shifted(img, dx, dy, h, w):
    """``img`` moved by ``(dx, dy)`` px (bilinear, edges reflected), cropped to ``(h, w)``."""
    import cv2

    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
