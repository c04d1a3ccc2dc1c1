"""The objects' own colours (bgsub.background.object_colour.ObjectColours): a found object grows
over its parts that match the background."""

import cv2
import numpy as np
import pytest

from bgsub.background.fusion import FusionConfig
from bgsub.background.object_colour import LEVELS, ObjectColours, colour_index
from bgsub.engines import create_engine
from bgsub.errors import InputError

H, W = 96, 128
GROUND, FUR = (60, 110, 140), (40, 160, 220)  # BGR: a brown ground, a golden coat


def _scene(seed=0, *, second=False):
    """A noisy ground with a 30 x 40 object of another colour (rows 30-59, columns 40-79) and,
    with ``second``, a like-coloured object far from it (rows 10-19, columns 100-119):
    ``(frame (H, W, 3) uint8, object (H, W) bool)``."""
    rng = np.random.default_rng(seed)
    frame = np.empty((H, W, 3), np.float32)
    frame[:] = GROUND
    obj = np.zeros((H, W), bool)
    obj[30:60, 40:80] = True
    frame[obj] = FUR
    if second:
        frame[10:20, 100:120] = FUR
    frame += rng.normal(0, 3, frame.shape)
    return np.clip(frame, 0, 255).astype(np.uint8), obj


def _mask(where):
    return where.astype(np.uint8) * np.uint8(255)


def _learnt(**kw):
    colours = ObjectColours(radius=kw.get("radius", 24), above=kw.get("above", 0.8))
    frame, obj = _scene(0, second=kw.get("second", False))
    colours.learn(frame, _mask(obj))
    return colours


def test_colour_index_gives_one_bin_per_quantised_colour():
    frame = np.array([[[0, 0, 0], [15, 15, 15], [16, 0, 0], [0, 0, 16], [255, 255, 255]]],
                     np.uint8)
    assert colour_index(frame).tolist() == [[0, 0, LEVELS ** 2, 1, LEVELS ** 3 - 1]]
    assert colour_index(frame[..., 0]).tolist() == [[0, 0, 1, 0, LEVELS - 1]]


def test_a_half_found_object_grows_over_its_missed_half():
    colours = _learnt()
    frame, obj = _scene(1)
    half = obj.copy()
    half[:, 60:] = False  # the right half matched the background and was missed
    grown = colours.grow(_mask(half), frame)
    assert grown.dtype == np.uint8 and set(np.unique(grown)) <= {0, 255}
    assert (grown[obj] == 255).mean() > 0.95
    assert not grown[~obj].any()


def test_growth_stops_at_the_radius():
    colours = _learnt(radius=5)
    frame, obj = _scene(1)
    half = obj.copy()
    half[:, 60:] = False
    grown = colours.grow(_mask(half), frame) > 0
    assert grown[30:60, 60:65].all() and not grown[:, 66:].any()


def test_a_like_coloured_region_the_mask_does_not_touch_is_not_added():
    colours = _learnt(radius=40)
    frame, obj = _scene(1, second=True)
    grown = colours.grow(_mask(obj), frame)
    assert not grown[10:20, 100:120].any()


def test_an_object_of_the_backgrounds_colour_does_not_grow():
    colours = ObjectColours(radius=12, above=0.8)
    frame, obj = _scene(0)
    frame[obj] = frame[~obj][: obj.sum()]  # the object wears the ground's colours
    colours.learn(frame, _mask(obj))
    half = obj.copy()
    half[:, 60:] = False
    grown = colours.grow(_mask(half), frame)
    assert (grown[30:60, 60:80] == 0).mean() > 0.95


@pytest.mark.parametrize("learnt_mask", ["empty", "none yet", "reset"])
def test_without_a_colour_model_the_mask_is_returned_as_it_is(learnt_mask):
    colours = ObjectColours(radius=12, above=0.8)
    frame, obj = _scene(0)
    if learnt_mask == "empty":
        colours.learn(frame, np.zeros((H, W), np.uint8))
    elif learnt_mask == "reset":
        colours.learn(frame, _mask(obj))
        colours.reset()
    half = _mask(obj & (np.arange(W) < 60))
    assert colours.grow(half, frame) is half


def test_radius_zero_is_off():
    colours = _learnt(radius=0)
    frame, obj = _scene(1)
    half = _mask(obj & (np.arange(W) < 60))
    assert colours.grow(half, frame) is half


def test_a_gray_frame_has_a_gray_level_model():
    colours = ObjectColours(radius=24, above=0.8)
    frame, obj = _scene(0)
    gray = frame[..., 2].copy()  # ground 140, object 220
    colours.learn(gray, _mask(obj))
    half = obj & (np.arange(W) < 60)
    grown = colours.grow(_mask(half), _scene(1)[0][..., 2].copy())
    assert (grown[obj] == 255).mean() > 0.95 and not grown[~obj].any()


@pytest.mark.parametrize("bad", [{"grow_radius": -1}, {"grow_above": 0.4}, {"grow_above": 1.5}])
def test_the_growth_settings_are_checked(bad):
    with pytest.raises(InputError, match=next(iter(bad))):
        FusionConfig(**bad)


def test_the_engine_grows_its_mask_over_a_flat_object():
    """Through the engine: a flat object entering a pan is found from its edges first; with
    growth its inside is found frames earlier."""
    rng = np.random.default_rng(3)
    ground = cv2.GaussianBlur(rng.integers(0, 255, (140, 200, 3), np.uint8), (0, 0), 2)
    found = {}
    for radius in (0, 6):
        engine = create_engine("grbm", grow_radius=radius, grow_above=0.8, edge_radius=0,
                               work_width=160)
        for t in range(4):
            frame = ground[10 + t: 130 + t, 20 + 2 * t: 180 + 2 * t].copy()  # a pan
            obj = np.zeros(frame.shape[:2], bool)
            obj[40:80, 40 + 6 * t: 70 + 6 * t] = True  # a flat object moving against it
            frame[obj] = FUR
            mask = engine.apply(frame)
        found[radius] = (mask[obj] > 0).mean()
    assert found[6] > found[0] + 0.2
