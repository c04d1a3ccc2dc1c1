"""The moving-camera engines' foreground cues end to end: colour, and motion the image can tell."""

import cv2
import numpy as np
import pytest

from bgsub.engines import create_engine

H, W = 120, 160


GRAY = 128
TINT = (220, 155, 40)  # BGR of gray level 128 (0.114 B + 0.587 G + 0.299 R): a dull violet


def _gray_world(seed=0, h=200, w=320):
    """A gray scene: textured above and below, a flat band of gray level ``GRAY`` across."""
    rng = np.random.default_rng(seed)
    small = rng.integers(60, 190, (h // 4, w // 4)).astype(np.uint8)
    world = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    world[70:140] = GRAY
    return world


def _chameleon_clip(n=24, pan=2.0):
    """A panning gray scene with a disc that differs from it in colour only: it crosses the
    band of its own gray level, so a gray-level engine cannot see it."""
    world = _gray_world()
    yy, xx = np.mgrid[:H, :W]
    for k in range(n):
        m = np.float32([[1, 0, -20 - pan * k], [0, 1, -30]])
        gray = cv2.warpAffine(world, m, (W, H), flags=cv2.INTER_LINEAR)
        frame = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
        disc = (xx - (6 * k - 20)) ** 2 + (yy - 75) ** 2 < 18 ** 2  # enters from the left
        frame[disc] = TINT
        yield frame, disc, gray


def _found(engine, *, colour=True):
    """Mean (recall, false-positive rate) of ``engine`` on the chameleon clip (colour frames or
    their gray levels), once the disc is well inside the frame."""
    hits = []
    for k, (frame, disc, gray) in enumerate(_chameleon_clip()):
        assert cv2.absdiff(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), gray).max() <= 1
        mask = engine.apply(frame if colour else gray) > 0
        if k >= 8:
            hits.append((np.count_nonzero(mask & disc) / disc.sum(),
                         np.count_nonzero(mask & ~disc) / (~disc).sum()))
    return np.mean(hits, axis=0)


@pytest.mark.parametrize("name", ["grbm", "compensated"])
def test_an_object_of_the_backgrounds_gray_level_is_found_by_its_colour(name):
    recall, false_rate = _found(create_engine(name))
    assert recall > 0.9 and false_rate < 0.01
    recall, _ = _found(create_engine(name), colour=False)
    assert recall < 0.1  # the clip is what it claims: in gray levels there is nothing to find


def test_the_debug_picture_carries_the_flow_colour_legend():
    from bgsub.io.flowio import add_colour_wheel

    engine = create_engine("grbm")
    for frame, _, _ in _chameleon_clip(n=3):
        engine.apply(frame)
    picture = engine.debug_image()
    scale = engine.frontend.colour_scale()
    # The legend is drawn last, over the picture: drawing it again changes nothing.
    assert np.array_equal(add_colour_wheel(picture, scale), picture)
    corner = picture[-30:, -30:].reshape(-1, 3).astype(int)
    assert len(np.unique(corner, axis=0)) > 20  # the wheel's many hues


def test_the_cli_finds_the_colour_only_object_in_a_folder_of_frames(tmp_path, capsys):
    from bgsub.cli import main

    frames = tmp_path / "frames"
    frames.mkdir()
    discs = []
    for k, (frame, disc, _) in enumerate(_chameleon_clip()):
        cv2.imwrite(str(frames / f"in{k + 1:06d}.png"), frame)
        discs.append(disc)
    assert main(["run", str(frames), "-o", str(tmp_path / "masks"), "-q"]) == 0
    masks = sorted((tmp_path / "masks").glob("*.png"))
    assert len(masks) == len(discs)
    found = [np.count_nonzero(cv2.imread(str(m), cv2.IMREAD_GRAYSCALE)[d] == 255) / d.sum()
             for m, d in zip(masks[8:], discs[8:])]
    assert np.mean(found) > 0.9
