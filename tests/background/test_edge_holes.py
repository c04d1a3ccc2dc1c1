"""Holes closed by the frame's edges (bgsub.background.edge_holes.fill_edge_holes): the flat
inside of an object, bounded by its outline and the found parts of it, joins the mask."""

import numpy as np
import pytest

from bgsub.background.edge_holes import fill_edge_holes
from bgsub.background.fusion import FusionConfig
from bgsub.engines import create_engine
from bgsub.errors import InputError

H, W = 96, 128
TOP, BOTTOM, LEFT, RIGHT = 30, 60, 40, 80  # the object's outline (rows, columns)


def _outlined(gap=0, seed=0):
    """A flat gray frame with a dark 2 px rectangle outline whose inside is the ground's own
    gray; ``gap`` opens its top side that many columns: ``(frame (H, W) uint8, inside bool)``."""
    rng = np.random.default_rng(seed)
    frame = np.full((H, W), 120.0)
    frame[TOP:BOTTOM, LEFT:RIGHT] = 30
    frame[TOP + 2:BOTTOM - 2, LEFT + 2:RIGHT - 2] = 120
    if gap:
        mid = (LEFT + RIGHT) // 2
        frame[TOP:TOP + 2, mid - gap // 2: mid + gap - gap // 2] = 120
    frame += rng.normal(0, 2, frame.shape)
    inside = np.zeros((H, W), bool)
    inside[TOP + 2:BOTTOM - 2, LEFT + 2:RIGHT - 2] = True
    return np.clip(frame, 0, 255).astype(np.uint8), inside


def _sides(columns=8):
    """The mask of the object's left and right sides, ``columns`` wide each: what a background
    model finds of a flat box moving sideways (its top and bottom move along themselves)."""
    mask = np.zeros((H, W), np.uint8)
    mask[TOP:BOTTOM, LEFT:LEFT + columns] = 255
    mask[TOP:BOTTOM, RIGHT - columns:RIGHT] = 255
    return mask


def test_the_inside_the_outline_closes_is_filled():
    frame, inside = _outlined()
    filled = fill_edge_holes(_sides(), frame, share=0.3, max_area=5000)
    assert filled.dtype == np.uint8 and set(np.unique(filled)) <= {0, 255}
    assert (filled[inside] == 255).mean() > 0.9
    assert not filled[:TOP - 1].any() and not filled[BOTTOM + 1:].any()


def test_a_region_open_to_the_background_is_not_filled():
    frame, inside = _outlined(gap=8)
    filled = fill_edge_holes(_sides(), frame, share=0.3, max_area=5000)
    assert not filled[inside & (np.arange(W) >= LEFT + 10) & (np.arange(W) < RIGHT - 10)].any()


def test_a_region_mostly_bounded_by_edges_needs_a_larger_share_of_mask():
    frame, inside = _outlined()
    mask = _sides()
    # The inside's boundary is about half the mask's (its sides), half the outline's.
    assert (fill_edge_holes(mask, frame, share=0.3, max_area=5000)[inside] > 0).mean() > 0.9
    assert fill_edge_holes(mask, frame, share=0.7, max_area=5000) is mask


def test_a_region_larger_than_max_area_is_not_filled():
    frame, inside = _outlined()
    mask = _sides()
    assert fill_edge_holes(mask, frame, share=0.3, max_area=300) is mask


@pytest.mark.parametrize("share, empty", [(0.0, False), (0.3, True)])
def test_off_or_an_empty_mask_returns_the_mask_itself(share, empty):
    frame, _ = _outlined()
    mask = np.zeros((H, W), np.uint8) if empty else _sides()
    assert fill_edge_holes(mask, frame, share=share, max_area=5000) is mask


@pytest.mark.parametrize("bad", [-0.1, 1.5])
def test_the_share_is_checked(bad):
    with pytest.raises(InputError, match="hole_share"):
        FusionConfig(hole_share=bad)


def _pan_with_cup(t):
    """Frame ``t`` of a pan over a flat gray field framed by texture, with a textured cup moving
    right against it: its inside is the field's own gray, closed at the top by a dark line.
    ``(frame (120, 160, 3) uint8, inside bool)``."""
    rng = np.random.default_rng(5)
    ground = rng.integers(0, 255, (140, 200), np.uint8)
    ground[30:110, 30:170] = 120
    frame = ground[10 + t: 130 + t, 20 + 2 * t: 180 + 2 * t].astype(np.float64)
    left = 30 + 5 * t
    frame[45:85, left:left + 50] = rng.integers(0, 255, (40, 50))
    frame[45:48, left + 12:left + 38] = 30  # the line across the cup's mouth
    frame[48:73, left + 12:left + 38] = 120  # its inside
    frame += np.random.default_rng(t).normal(0, 1.5, frame.shape)
    inside = np.zeros(frame.shape, bool)
    inside[50:71, left + 14:left + 36] = True
    gray = np.clip(frame, 0, 255).astype(np.uint8)
    return np.repeat(gray[:, :, None], 3, axis=2), inside


def test_the_engine_finds_the_flat_inside_of_a_cup_its_line_closes():
    """Through the engine: the cup's texture is found, its flat inside (the field's own gray)
    is not, and the mask and the dark line across its mouth enclose it."""
    found = {}
    # The mask holds between 0.4 and 0.5 of the inside's boundary (edges line the cup's walls).
    for share in (0.0, 0.4):
        engine = create_engine("grbm", hole_share=share, grow_radius=0, edge_radius=0,
                               work_width=160)
        inside_found = []
        for t in range(4):
            frame, inside = _pan_with_cup(t)
            inside_found.append((engine.apply(frame)[inside] > 0).mean())
        found[share] = np.mean(inside_found[1:])
    assert found[0.4] > found[0.0] + 0.5
