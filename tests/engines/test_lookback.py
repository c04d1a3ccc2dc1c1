"""Look-back start (bgsub.engines.lookback.primed and the engines' prime): the first masks of a
stream come from a twin that ran the first frames backwards."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.engines import create_engine
from bgsub.engines.lookback import primed
from bgsub.samples import SceneSpec, render_frames
from helpers import random_texture


def _scene(n=24, category="pan", seed=0):
    """``(frames, truths)`` of a generated scene (``bgsub.samples``)."""
    rendered = list(render_frames(SceneSpec(category, seed=seed, n_frames=n)))
    return [f.image for f in rendered], [f.groundtruth for f in rendered]


def _object_from_the_start(n=24, h=180, w=240):
    """``(frames, truths)``: a textured world panning 3 px a frame and a flat red square that
    moves 3 px a frame the other way, there from the first frame."""
    world = cv2.cvtColor(random_texture(h + 2 * n * 3, w + 2 * n * 3, seed=4), cv2.COLOR_GRAY2BGR)
    frames, truths = [], []
    for k in range(n):
        frame = np.ascontiguousarray(world[20:20 + h, 3 * k:3 * k + w])
        truth = np.zeros((h, w), np.uint8)
        x0 = 40 + 3 * k
        frame[60:100, x0:x0 + 40] = (30, 30, 220)
        truth[60:100, x0:x0 + 40] = 255
        frames.append(frame)
        truths.append(truth)
    return frames, truths


def _f(mask, truth):
    m, t = mask > 0, truth == 255
    tp = np.count_nonzero(m & t)
    return 2 * tp / max(np.count_nonzero(m) + np.count_nonzero(t), 1)


def _masks(engine, frames, *, prime):
    pairs = list(enumerate(frames))
    stream = primed([engine], pairs) if prime else pairs
    return [engine.apply(image) for _, image in stream]


def test_the_stream_goes_on_unchanged_after_priming():
    frames, _ = _scene(n=8)
    engine = create_engine("grbm", lookback=6)
    pairs = list(primed([engine], enumerate(frames)))
    assert [k for k, _ in pairs] == list(range(8))
    assert all(np.array_equal(a, b) for (_, a), b in zip(pairs, frames))


def test_the_first_masks_find_the_objects_a_young_model_misses():
    frames, truths = _object_from_the_start()
    cold = _masks(create_engine("grbm", lookback=20), frames, prime=False)
    warm = _masks(create_engine("grbm", lookback=20), frames, prime=True)
    assert not cold[0].any()  # no previous frame: nothing to compare with
    first = range(0, 9)  # the frames the twin saw more of the scene for
    assert np.mean([_f(warm[k], truths[k]) for k in first]) > 0.8
    assert np.mean([_f(warm[k], truths[k]) for k in first]) > \
        np.mean([_f(cold[k], truths[k]) for k in first]) + 0.1
    # After them the engine's own masks, which priming did not change.
    assert all(np.array_equal(warm[k], cold[k]) for k in range(10, len(frames)))


def test_lookback_zero_and_engines_without_prime_start_as_before():
    frames, _ = _scene(n=10)
    off = create_engine("grbm", lookback=0)
    mog2 = create_engine("mog2")
    stream = primed([off, mog2], enumerate(frames))
    masks = [(off.apply(image), mog2.apply(image)) for _, image in stream]
    assert not masks[0][0].any()
    again = create_engine("mog2")
    assert all(np.array_equal(m, again.apply(f)) for (_, m), f in zip(masks, frames))


def test_prime_after_the_first_frame_or_with_known_motion_does_nothing():
    frames, _ = _scene(n=10)
    started = create_engine("grbm", lookback=8)
    started.apply(frames[0])
    started.prime(frames[1:])
    assert not started._early
    known = create_engine("grbm", known_motion=np.tile(np.eye(3), (10, 1, 1)))
    assert known.lookback == 0


@pytest.mark.parametrize("n", [1, 2])
def test_a_stream_shorter_than_three_frames_is_not_primed(n):
    frames = _scene(n=4)[0][:n]
    engine = create_engine("grbm", lookback=20)
    assert len(list(primed([engine], enumerate(frames)))) == n
    assert not engine._early


def test_bgsub_run_gives_a_mask_from_the_first_frame(tmp_path, capsys):
    from bgsub.cli import main

    frames, truths = _object_from_the_start(n=16)
    folder = tmp_path / "seq"
    folder.mkdir()
    for k, frame in enumerate(frames):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), frame)
    runs = {}
    for lookback in (0, 16):
        out = tmp_path / f"masks{lookback}"
        assert main(["run", str(folder), "-o", str(out), "-p", f"lookback={lookback}"]) == 0
        runs[lookback] = [cv2.imread(str(out / f"bin{k + 1:06d}.png"), cv2.IMREAD_GRAYSCALE)
                          for k in range(len(frames))]
    capsys.readouterr()
    assert not runs[0][0].any() and _f(runs[16][0], truths[0]) > 0.8
    assert all(np.array_equal(a, b) for a, b in zip(runs[0][8:], runs[16][8:]))


def test_a_stream_that_starts_on_the_bare_scene_is_foreground_where_both_agree():
    # The sample scenes' objects enter after an object-free warm-up: the twin meets them in its
    # first frame and could leave their ghosts in the first frames' masks.
    frames, truths = _scene(n=30, category="static", seed=2)
    assert not truths[0].any() and any(t.any() for t in truths)
    cold = _masks(create_engine("grbm", lookback=30), frames, prime=False)
    warm = _masks(create_engine("grbm", lookback=30), frames, prime=True)
    # (the engine's own first masks are empty there, and the twin's ghosts are not theirs)
    assert all(np.array_equal(w, c) for w, c in zip(warm, cold))


def test_the_near_ground_a_young_model_calls_foreground_is_not_in_the_first_masks():
    # A camera on a track past a near band: until the parallax field stands, the engine's own
    # first masks hold the band; the twin, which reaches frame 1 with the field, does not.
    frames, truths = _scene(n=30, category="parallax", seed=0)
    cold = _masks(create_engine("grbm", lookback=30), frames, prime=False)
    warm = _masks(create_engine("grbm", lookback=30), frames, prime=True)

    def false_positives(masks):
        return sum(int(np.count_nonzero((masks[k] > 0) & (truths[k] == 0))) for k in range(1, 6))

    assert false_positives(cold) > 10_000
    assert false_positives(warm) < 0.01 * false_positives(cold)
