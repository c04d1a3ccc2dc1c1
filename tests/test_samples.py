"""Tests of the synthetic scene generator (bgsub.samples) and `bgsub samples`."""

from __future__ import annotations

from pathlib import Path
from typing import List

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.errors import InputError, OutputError
from bgsub.samples import (
    CATEGORIES,
    GT_BACKGROUND,
    GT_FOREGROUND,
    GT_UNKNOWN,
    SceneFrame,
    SceneSpec,
    generate_scene,
    render_frames,
)

SMALL = dict(width=128, height=96)


def _render(spec: SceneSpec) -> List[SceneFrame]:
    return list(render_frames(spec))


# ----------------------------------------------------------------------------- determinism


def test_same_seed_gives_identical_frames_and_groundtruth():
    spec = SceneSpec("pan-zoom-rotate", seed=3, n_frames=20, **SMALL)
    first, second = _render(spec), _render(spec)
    for a, b in zip(first, second):
        assert np.array_equal(a.image, b.image)
        assert np.array_equal(a.groundtruth, b.groundtruth)
        assert np.array_equal(a.motion, b.motion)


def test_different_seeds_give_different_scenes():
    a = _render(SceneSpec("pan", seed=0, n_frames=20, **SMALL))
    b = _render(SceneSpec("pan", seed=1, n_frames=20, **SMALL))
    assert not np.array_equal(a[-1].image, b[-1].image)
    assert not np.array_equal(a[-1].motion, b[-1].motion)


# ----------------------------------------------------------------------------- short scenes


@pytest.mark.parametrize("category", list(CATEGORIES))
@pytest.mark.parametrize("n_frames", [2, 5, 12, 21, 30])
def test_short_scenes_render_for_every_seed(category, n_frames):
    # Clips shorter than an object's crossing time leave almost no frames for an object to
    # enter at; every object must still get a path.
    for seed in range(4):
        frames = _render(SceneSpec(category, seed=seed, n_frames=n_frames, **SMALL))
        assert len(frames) == n_frames


@pytest.mark.parametrize("size,n_frames,seed", [((320, 240), 12, 0), ((320, 240), 30, 1),
                                                ((320, 240), 30, 3), ((640, 480), 6, 0)])
def test_pan_scenes_render_frames_of_the_requested_size(size, n_frames, seed):
    spec = SceneSpec("pan", seed=seed, width=size[0], height=size[1], n_frames=n_frames)
    frames = _render(spec)
    assert frames[-1].image.shape == (size[1], size[0], 3)


def test_objects_of_a_short_scene_appear_after_the_warmup():
    for seed in range(4):
        spec = SceneSpec("pan", seed=seed, n_frames=12, **SMALL)
        frames = _render(spec)
        assert spec.warmup_frames == 2
        assert all((f.groundtruth == 0).all() for f in frames[:spec.warmup_frames])
        assert any((f.groundtruth == GT_FOREGROUND).any() for f in frames[spec.warmup_frames:])


# ----------------------------------------------------------------------------- ground truth


def test_groundtruth_values_are_cdnet_labels():
    for frame in _render(SceneSpec("jitter", seed=2, n_frames=40, **SMALL)):
        assert frame.groundtruth.dtype == np.uint8
        assert set(np.unique(frame.groundtruth)) <= {GT_BACKGROUND, GT_UNKNOWN, GT_FOREGROUND}


@pytest.mark.parametrize("category", list(CATEGORIES))
def test_warmup_frames_have_no_foreground(category):
    spec = SceneSpec(category, seed=1, n_frames=60, **SMALL)
    frames = _render(spec)
    w = spec.warmup_frames
    assert w == 12 and spec.roi_start == 13
    assert all((f.groundtruth == GT_BACKGROUND).all() for f in frames[:w])
    assert any((f.groundtruth == GT_FOREGROUND).any() for f in frames[w:])


def test_default_scene_has_a_cdnet_warmup():
    spec = SceneSpec("static")
    assert spec.n_frames == 120 and spec.warmup_frames == 24 and spec.roi_start == 25
    assert SceneSpec("static", warmup=5, n_frames=30).roi_start == 6
    assert SceneSpec("static", roi_first=2).roi_start == 2
    with pytest.raises(InputError):
        SceneSpec("static", warmup=120)


def test_absurd_scene_lengths_are_refused():
    with pytest.raises(InputError, match="at most"):
        SceneSpec("pan", n_frames=10**11)


def test_odd_scene_sizes_render_in_memory_but_are_not_written(tmp_path):
    # Nothing about rendering needs even sizes (bgsub bench renders in memory); only the
    # written scene's .mp4 would be padded to even and no longer match its frames and truth.
    spec = SceneSpec("pan", width=101, height=77, n_frames=3)
    frames = _render(spec)
    assert frames[0].image.shape == (77, 101, 3) and frames[-1].groundtruth.shape == (77, 101)
    with pytest.raises(InputError, match=r"101x77 must be even .* the scene's \.mp4 .*100x76"):
        generate_scene(spec, tmp_path / "out")
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_cli_odd_size_says_why_it_must_be_even(tmp_path, capsys):
    assert main(["samples", str(tmp_path / "x"), "--size", "161x121", "-c", "pan"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and ".mp4 video" in err and "(e.g. 160x120)" in err
    assert "video codecs need it" not in err
    assert not (tmp_path / "x").exists()


def test_objects_move_enter_and_leave():
    # Small view, long clip: the objects cross it completely.
    spec = SceneSpec("pan", seed=0, n_frames=150, n_objects=3, width=96, height=72)
    areas = np.array([(f.groundtruth == GT_FOREGROUND).sum() for f in _render(spec)])
    visible = np.flatnonzero(areas > 0)
    assert visible.size > 0
    assert visible[0] >= spec.warmup_frames                  # entered after the warm-up
    assert areas[visible[0]] < areas.max()                   # came in through a border
    assert (areas[visible[0]:] == 0).any()                   # and the view empties again

    frames = _render(SceneSpec("static", seed=0, n_frames=60, **SMALL))
    masks = [f.groundtruth == GT_FOREGROUND for f in frames if (f.groundtruth == 255).any()]
    assert len(masks) > 5
    # On a still camera a moving object changes the mask from frame to frame.
    assert all(not np.array_equal(a, b) for a, b in zip(masks, masks[1:]))


def test_background_only_rendering_matches_scene_where_groundtruth_is_zero():
    spec = SceneSpec("pan", seed=4, n_frames=40, **SMALL)
    for full, bare in zip(render_frames(spec), render_frames(spec, include_objects=False)):
        background = full.groundtruth == GT_BACKGROUND
        assert np.array_equal(full.image[background], bare.image[background])


# ----------------------------------------------------------------------------- camera motion


def _background_residual(previous: np.ndarray, current: np.ndarray, motion: np.ndarray,
                         keep: np.ndarray) -> float:
    """Mean |warp(previous, motion) - current| over ``keep`` pixels, in grey levels."""
    h, w = current.shape[:2]
    warped = cv2.warpPerspective(previous.astype(np.float32), motion, (w, h),
                                 flags=cv2.INTER_LINEAR)
    return float(np.abs(warped - current.astype(np.float32))[keep].mean())


@pytest.mark.parametrize("category", ["pan", "jitter", "pan-zoom-rotate", "fast-pan"])
def test_camera_motion_maps_previous_frame_onto_current(category):
    spec = SceneSpec(category, seed=0, n_frames=30, width=160, height=120, noise_sigma=0.0)
    frames = _render(spec)
    border = np.zeros((120, 160), bool)
    border[20:-20, 20:-20] = True  # away from the border, where content enters the view
    for k in range(1, len(frames)):
        prev, cur = frames[k - 1], frames[k]
        objects = cv2.dilate(((prev.groundtruth > 0) | (cur.groundtruth > 0)).astype(np.uint8),
                             np.ones((9, 9), np.uint8)) > 0
        keep = border & ~objects
        good = _background_residual(prev.image, cur.image, cur.motion, keep)
        assert good < 2.0, (k, good)  # bilinear resampling error only
        if category != "jitter" or not np.allclose(cur.motion, np.eye(3), atol=0.3):
            # The inverse (or no) motion explains the frames much worse: the test can fail.
            wrong = _background_residual(prev.image, cur.image, np.linalg.inv(cur.motion), keep)
            assert wrong > 2 * good + 1.0, (k, good, wrong)


def test_static_camera_has_identity_motion():
    for frame in render_frames(SceneSpec("static", seed=5, n_frames=10, **SMALL)):
        assert np.array_equal(frame.motion, np.eye(3))


def test_fast_pan_moves_at_least_8_px_per_frame():
    for seed in range(3):
        frames = _render(SceneSpec("fast-pan", seed=seed, n_frames=6, **SMALL))
        centre = np.array([64.0, 48.0, 1.0])
        for frame in frames[1:]:
            moved = frame.motion @ centre
            assert np.hypot(*(moved[:2] / moved[2] - centre[:2])) >= 8.0


# ----------------------------------------------------------------------------- files on disk


def test_generate_scene_writes_the_cdnet_layout(tmp_path):
    spec = SceneSpec("pan", seed=2, n_frames=15, **SMALL)
    folder = generate_scene(spec, tmp_path)
    assert folder == tmp_path / "pan_s2"
    inputs = sorted((folder / "input").iterdir())
    gts = sorted((folder / "groundtruth").iterdir())
    assert [p.name for p in inputs] == [f"in{k:06d}.jpg" for k in range(1, 16)]
    assert [p.name for p in gts] == [f"gt{k:06d}.png" for k in range(1, 16)]
    assert (folder / "temporalROI.txt").read_text().split() == ["4", "15"]
    motion = np.load(folder / "camera_motion.npy", allow_pickle=False)
    assert motion.shape == (15, 3, 3) and motion.dtype == np.float64
    expected = _render(spec)
    assert np.allclose(motion, np.stack([f.motion for f in expected]))
    gt = cv2.imread(str(gts[7]), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(gt, expected[7].groundtruth)
    image = cv2.imread(str(inputs[7]))
    assert np.abs(image.astype(int) - expected[7].image).mean() < 3  # JPEG q95

    video = cv2.VideoCapture(str(folder / "pan_s2.mp4"))
    count = 0
    while True:
        ok, frame = video.read()
        if not ok:
            break
        assert frame.shape == (96, 128, 3)
        count += 1
    video.release()
    assert count == 15
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp left


def test_generate_scene_refuses_existing_output(tmp_path):
    spec = SceneSpec("static", seed=0, n_frames=3, **SMALL)
    generate_scene(spec, tmp_path)
    # Said for API callers and command-line users alike.
    with pytest.raises(OutputError, match=r"static_s0: already exists \(overwrite=True, or "
                                          r"--overwrite on the command line, replaces it\)"):
        generate_scene(spec, tmp_path)
    generate_scene(spec, tmp_path, overwrite=True)


# ----------------------------------------------------------------------------- CLI


def test_cli_writes_scenes_and_summary(tmp_path, capsys):
    out = tmp_path / "scenes"
    status = main(["samples", str(out), "--category", "static", "fast-pan", "--seed", "0", "1",
                   "--max-frames", "6", "--size", "96x72"])
    assert status == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["fast-pan_s0", "fast-pan_s1", "static_s0", "static_s1"]
    assert len(list((out / "static_s1" / "input").glob("in*.jpg"))) == 6
    image = cv2.imread(str(out / "fast-pan_s0" / "input" / "in000001.jpg"))
    assert image.shape == (72, 96, 3)
    captured = capsys.readouterr()
    assert str(out / "static_s0") in captured.out
    assert "4 scenes" in captured.err


def test_cli_output_is_what_the_library_writes(tmp_path):
    assert main(["samples", str(tmp_path / "a"), "-c", "jitter", "-s", "7", "--max-frames", "4",
                 "--size", "96x72", "-q"]) == 0
    generate_scene(SceneSpec("jitter", seed=7, n_frames=4, width=96, height=72), tmp_path / "b")
    for name in ["input/in000004.jpg", "groundtruth/gt000004.png", "camera_motion.npy"]:
        assert (tmp_path / "a/jitter_s7" / name).read_bytes() == \
            (tmp_path / "b/jitter_s7" / name).read_bytes()


def test_cli_refuses_existing_output(tmp_path, capsys):
    args = ["samples", str(tmp_path), "-c", "pan", "--max-frames", "3", "--size", "96x72", "-q"]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already exists" in err
    assert main(args + ["--overwrite"]) == 0


@pytest.mark.parametrize("bad", [["--size", "320by240"], ["--size", "10x10"],
                                 ["--category", "moving"], ["--max-frames", "1"],
                                 ["--category", ","], ["--size", "101x77"]])
def test_cli_bad_options_exit_2_with_one_line(tmp_path, capsys, bad):
    assert main(["samples", str(tmp_path / "x")] + bad) == 2
    err = capsys.readouterr().err
    assert err.startswith("bgsub: error:") and err.count("\n") == 1
    assert not (tmp_path / "x").exists()


def test_cli_list_names_every_category(capsys):
    assert main(["samples", "--list"]) == 0
    out = capsys.readouterr().out
    assert [line.split()[0] for line in out.splitlines()] == list(CATEGORIES)


def test_shipped_sample_is_the_pan_scene():
    shipped = Path(__file__).resolve().parents[1] / "samples" / "pan.mp4"
    if not shipped.exists():
        pytest.skip("samples/pan.mp4 not present")
    video = cv2.VideoCapture(str(shipped))
    count = int(video.get(cv2.CAP_PROP_FRAME_COUNT))
    ok, first = video.read()
    video.release()
    spec = SceneSpec("pan", seed=0)
    assert ok and count == spec.n_frames
    expected = next(iter(render_frames(spec))).image
    # The mp4 is lossy (mp4v), but its first frame is the scene's.
    assert np.abs(first.astype(int) - expected).mean() < 6


@pytest.mark.parametrize("args, hinted", [
    (["--category", "pan", "sc1/"], True),       # looks like a path
    (["--category", "pan", "sc1"], True),        # no DIR given: it may be meant as DIR
    (["--seed", "1", "scenes/"], True),
    (["out", "--category", "pan", "pann"], False),  # DIR given: a plain typo
])
def test_cli_a_dir_after_a_list_option_says_where_dir_goes(tmp_path, monkeypatch, bgsub_error,
                                                          args, hinted):
    monkeypatch.chdir(tmp_path)  # the default DIR, were anything written
    err = bgsub_error(["samples", *args])
    assert ("put DIR before" in err) == hinted
    assert list(tmp_path.iterdir()) == []


def test_cli_help_examples_keep_a_gap_before_their_comment(capsys):
    with pytest.raises(SystemExit):
        main(["samples", "--help"])
    examples = capsys.readouterr().out.split("examples:\n")[1].splitlines()
    commented = [line for line in examples if "   " in line.strip()]
    assert len(commented) == 4
    # Every comment starts in the same column, after at least two spaces.
    starts = {len(line) - len(line.split("   ")[-1].lstrip()) for line in commented}
    assert len(starts) == 1
    assert "--seed 0   the scene shipped as samples/pan.mp4" in "\n".join(examples)
