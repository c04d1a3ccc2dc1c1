"""Black bars along the frame's edges (letterbox, pillarbox) are frame-fixed overlays:
bgsub.background.bars on frames with exact answers, and through the moving-camera engine."""

import numpy as np
from helpers import random_texture

from bgsub import create_engine
from bgsub.background.bars import BlackBars
from bgsub.samples import SceneSpec, render_frames

SHAPE = (120, 160)


def _framed(seed, *, top=0, bottom=0, left=0, right=0):
    """A textured ``SHAPE`` gray frame with black bars of those depths (px)."""
    h, w = SHAPE
    frame = random_texture(h, w, seed=seed)[:h, :w] // 2 + 64  # (no black pixel in the scene)
    rows, cols = np.arange(h), np.arange(w)
    frame[(rows < top) | (rows >= h - bottom)] = 0
    frame[:, (cols < left) | (cols >= w - right)] = 0
    return frame


def _bars(frames, *, needed=4, grow=0):
    bars = BlackBars()
    for frame in frames:
        bars.observe(frame)
    return bars.mask(SHAPE, frames=needed, grow=grow)


def test_letterbox_bars_are_found_with_their_depth():
    mask = _bars([_framed(k, top=10, bottom=6) for k in range(4)], grow=2)
    rows = mask.all(axis=1)
    assert rows[:12].all() and rows[SHAPE[0] - 8:].all()  # the bars, 2 px deeper
    assert not mask[12:SHAPE[0] - 8].any()


def test_pillarbox_bars_are_found_with_their_depth():
    mask = _bars([_framed(k, left=8, right=12) for k in range(4)])
    cols = mask.all(axis=0)
    assert cols[:8].all() and cols[SHAPE[1] - 12:].all()
    assert not mask[:, 8:SHAPE[1] - 12].any()


def test_a_bar_is_only_as_deep_as_in_every_frame():
    frames = [_framed(k, top=20) for k in range(4)] + [_framed(9, top=5)]
    mask = _bars(frames)
    assert mask[:5].all() and not mask[5:].any()


def test_the_mask_is_made_again_only_when_the_bars_change():
    bars = BlackBars()
    for k in range(4):
        bars.observe(_framed(k, top=20))
    first = bars.mask(SHAPE, frames=4, grow=0)
    bars.observe(_framed(5, top=20))
    assert bars.mask(SHAPE, frames=4, grow=0) is first  # (the engine keeps its region)
    bars.observe(_framed(6, top=5))
    shallower = bars.mask(SHAPE, frames=4, grow=0)
    assert shallower is not first and shallower[:5].all() and not shallower[5:].any()


def test_a_frame_without_black_edges_has_no_bars():
    assert _bars([_framed(k) for k in range(6)]) is None


def test_bars_are_reported_only_after_enough_frames():
    frames = [_framed(k, top=10) for k in range(3)]
    assert _bars(frames, needed=4) is None
    assert _bars(frames, needed=3) is not None


def _bar_foreground(**params):
    """The share of the letterbox bars (12 px, top and bottom) called foreground by grbm over
    the second half of a shaking camera's sample scene drawn with them."""
    engine = create_engine("grbm", **params)
    shares = []
    spec = SceneSpec("jitter", seed=1, n_frames=60)
    for k, (image, _, _) in enumerate(render_frames(spec)):
        image = image.copy()
        image[:12] = image[-12:] = 0
        mask = engine.apply(image) > 0
        if k >= 30:
            shares.append(np.concatenate([mask[:12], mask[-12:]]).mean())
    return float(np.mean(shares))


def test_letterbox_bars_over_a_shaking_camera_stay_background():
    assert _bar_foreground() <= 0.01


def test_without_overlays_the_shaking_camera_drags_the_scene_over_the_bars():
    assert _bar_foreground(overlay=0) > 0.2


def test_a_still_camera_reports_no_bars():
    # (as for the textured overlays: a still camera's model drags nothing over them)
    engine = create_engine("grbm")
    for image, _, _ in render_frames(SceneSpec("static", seed=1, n_frames=30)):
        image = image.copy()
        image[:12] = image[-12:] = 0
        engine.apply(image)
    assert engine.overlay_box is None
