"""Real-image training pairs: shifted photographs and consecutive video frames."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.errors import InputError
from bgsub.model.imagedata import (
    ShiftedImagePairs,
    TEST_IMAGES,
    TRAIN_IMAGES,
    VideoFramePairs,
    warped_frame_pair,
)
from bgsub.model.training import Curriculum


def _texture(h: int = 160, w: int = 180, seed: int = 0, sigma: float = 1.0) -> np.ndarray:
    """Smooth random texture in [0, 1] (bilinear interpolation stays faithful on it)."""
    import cv2

    rng = np.random.default_rng(seed)
    smooth = cv2.GaussianBlur(rng.random((h, w)).astype(np.float32), (0, 0), sigma)
    return (smooth - smooth.min()) / (smooth.max() - smooth.min())


def _best_integer_shift(x: np.ndarray, y: np.ndarray, r: int) -> np.ndarray:
    """Per pair, the integer (dx, dy) maximising NCC of the overlap of x and y moved back."""
    n, p = len(x), int(np.sqrt(x.shape[1]))
    xs, ys = x.reshape(n, p, p), y.reshape(n, p, p)
    best = np.full(n, -np.inf)
    out = np.zeros((n, 2))
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            a = xs[:, max(0, -dy):p - max(0, dy), max(0, -dx):p - max(0, dx)].reshape(n, -1)
            b = ys[:, max(0, dy):p + min(0, dy), max(0, dx):p + min(0, dx)].reshape(n, -1)
            a = a - a.mean(1, keepdims=True)
            b = b - b.mean(1, keepdims=True)
            ncc = (a * b).sum(1) / np.sqrt((a * a).sum(1) * (b * b).sum(1) + 1e-12)
            better = ncc > best
            best[better] = ncc[better]
            out[better] = (dx, dy)
    return out


def test_pairs_are_shifted_by_the_stated_integer_amount():
    src = ShiftedImagePairs(images=[_texture()], max_shift=3, integer_shifts=True, max_rotation=0,
                            max_zoom=0, noise=0)
    s = src.sample(np.random.default_rng(1), 300)
    assert s.x.shape == (300, 169) and s.x.dtype == np.float32
    assert np.all(s.disp == np.round(s.disp)) and np.abs(s.disp).max() <= 3
    np.testing.assert_array_equal(_best_integer_shift(s.x, s.y, 3), s.disp)


def test_subpixel_rotated_pairs_match_their_shift_by_ncc():
    src = ShiftedImagePairs(images=[_texture(seed=2)], max_shift=3, max_rotation=3, max_zoom=0.03,
                            noise=0.005)
    s = src.sample(np.random.default_rng(2), 300)
    assert np.any(s.disp != np.round(s.disp))
    found = _best_integer_shift(s.x, s.y, 4)
    assert np.mean(np.abs(found - s.disp).max(axis=1) <= 1.0) > 0.97


def test_call_is_the_trainer_pair_source_with_curriculum():
    src = ShiftedImagePairs(images=[_texture()], max_shift=3, curriculum=Curriculum.parse("10:1"))
    x, y = src(np.random.default_rng(0), 50, 0)
    assert x.shape == y.shape == (50, 169) and x.dtype == y.dtype == np.float32
    assert src.shift_range(0) == 1 and src.shift_range(10) == 3
    early = src.sample(np.random.default_rng(0), 200, max_shift=src.shift_range(0))
    assert np.abs(early.disp).max() <= 1


def test_no_wrap_around_and_flat_images_rejected():
    flat = np.full((100, 100), 0.5, np.float32)
    with pytest.raises(InputError, match="no patch with contrast"):
        ShiftedImagePairs(images=[flat])
    with pytest.raises(InputError, match="too small"):
        ShiftedImagePairs(images=[_texture(30, 30)], max_shift=4)


def test_warped_frame_pair_flow_is_exact_for_a_shift():
    image = _texture(120, 140, seed=3, sigma=2.0)
    f1, f2, flow = warped_frame_pair(image, np.random.default_rng(0), max_shift=3, max_rotation=0,
                                     max_zoom=0)
    d = flow[60, 70]
    assert np.allclose(flow[np.isfinite(flow[..., 0])], d)  # one global shift
    assert f1.dtype == f2.dtype == np.uint8 and f1.shape == (120, 140)
    # f2 at (x + dx, y + dy) shows what f1 shows at (x, y), up to interpolation.
    y0, x0 = np.mgrid[30:90, 30:110]
    import cv2

    back = cv2.remap(f2.astype(np.float32), (x0 + d[0]).astype(np.float32), (y0 + d[1]).astype(np.float32),
                     cv2.INTER_LINEAR)
    assert np.abs(back - f1[30:90, 30:110]).mean() < 3.0  # the opposite sign gives ~20


def test_held_out_photos_are_not_training_photos():
    assert not set(TEST_IMAGES) & set(TRAIN_IMAGES)


def test_bundled_photos_load_when_scikit_image_is_installed():
    pytest.importorskip("skimage")
    from bgsub.model.imagedata import shifted_image_pairs

    src = shifted_image_pairs(split="test", max_shift=2)
    x, y = src(np.random.default_rng(0), 100, 0)
    assert x.shape == (100, 169) and 0.0 <= x.min() and x.max() <= 1.05


def test_video_frame_pairs_sample_consecutive_frames(tmp_path):
    import cv2

    rng = np.random.default_rng(0)
    base = (rng.random((90, 120)) * 255).astype(np.uint8)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(4):  # the scene moves 2 px right per frame
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), np.roll(base, 2 * k, axis=1))
    pairs = pytest.importorskip("bgsub.model.imagedata").video_frame_pairs([folder], pool_size=200,
                                                                      patches_per_pair=40)
    assert isinstance(pairs, VideoFramePairs) and len(pairs) == 120
    x, y = pairs(np.random.default_rng(0), 30, 0)
    assert x.shape == (30, 169) and x.dtype == np.float32 and x.max() <= 1.0
    found = _best_integer_shift(x, y, 3)
    assert (found == (2, 0)).all()


def test_samples_never_leave_the_image():
    # A frame of -1000 around the photo: any sample touching it would come out negative.
    image = np.pad(_texture(90, 100), 1, constant_values=-1000.0)
    src = ShiftedImagePairs(images=[image], max_shift=4, max_rotation=10, max_zoom=0.05, noise=0)
    s = src.sample(np.random.default_rng(0), 2000)
    assert s.x.min() >= 0.0 and s.y.min() >= 0.0


def test_missing_scikit_image_is_a_clear_error(monkeypatch):
    import sys

    from bgsub.model.imagedata import load_photos

    monkeypatch.setitem(sys.modules, "skimage", None)  # makes `import skimage.data` fail
    monkeypatch.setitem(sys.modules, "skimage.data", None)
    with pytest.raises(InputError, match="pip install"):
        load_photos(["camera"])


def test_degraded_copies_follow_the_originals():
    from bgsub.model.imagedata import degraded_copies

    rng = np.random.default_rng(0)
    photos = [rng.random((40, 50)).astype(np.float32), rng.random((30, 60)).astype(np.float32)]
    out = degraded_copies(photos, blur=(1.0, 2.0), motion_blur=5)
    assert len(out) == 2 + 2 * 2 + 2 * 2
    assert out[0] is photos[0] and [im.shape for im in out[2:4]] == [(40, 50), (30, 60)]
    detail = [float(np.abs(np.diff(im, axis=1)).mean()) for im in out[0:1] + out[2:3] + out[4:5]]
    assert detail[0] > detail[1] > detail[2]  # sigma 1 blurs less than sigma 2
    horizontal, vertical = out[6], out[8]  # the first photo box-blurred along x, then along y
    assert np.abs(np.diff(horizontal, axis=1)).mean() < np.abs(np.diff(horizontal, axis=0)).mean()
    assert np.abs(np.diff(vertical, axis=0)).mean() < np.abs(np.diff(vertical, axis=1)).mean()
    with pytest.raises(InputError):
        degraded_copies(photos, blur=(0.0,))
