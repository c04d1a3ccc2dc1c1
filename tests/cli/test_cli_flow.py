"""`bgsub flow`: image pair -> .flo (+ picture), video -> flow video, and its error messages."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.io.flowio import read_flo

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


def test_pair_flow_is_estimate_flows_dense_field_with_flow_config_defaults(pair, tmp_path):
    """The command is a thin layer: its field is the Python API's, read with FlowConfig's
    defaults (the grbm engine's) and the options given."""
    from bgsub.io.flowio import read_image
    from bgsub.model.rbm import load_model
    from bgsub.motion import FlowConfig, estimate_flow

    out = tmp_path / "f.flo"
    assert main(["flow", str(pair[0]), str(pair[1]), "-o", str(out), "--levels", "2", "-q"]) == 0
    config = FlowConfig(levels=2, dense=True, warn_range=False)
    expected = estimate_flow(read_image(pair[0]), read_image(pair[1]), config,
                             model=load_model("natural")).dense
    np.testing.assert_array_equal(read_flo(out), expected)


def test_colour_picture_has_its_legend_unless_no_legend(pair, tmp_path):
    pictures = {}
    for name, extra in (("legend", []), ("plain", ["--no-legend"])):
        vis = tmp_path / f"{name}.png"
        assert main(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / f"{name}.flo"),
                     "--vis", str(vis), "--max-magnitude", "3", "-q", *extra]) == 0
        pictures[name] = cv2.imread(str(vis))
    changed = np.any(pictures["legend"] != pictures["plain"], axis=2)
    ys, xs = np.nonzero(changed)
    assert len(ys) > 200 and ys.min() >= 120 // 2 and xs.min() >= 160 // 2  # bottom right


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



def test_missing_image(capsys, pair, tmp_path, bgsub_error):
    err = bgsub_error(["flow", str(tmp_path / "nope.png"), str(pair[1]), "-o", str(tmp_path / "f.flo")])
    assert "nope.png" in err


def test_unreadable_image(capsys, pair, tmp_path, bgsub_error):
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"not a png")
    err = bgsub_error(["flow", str(junk), str(pair[1]), "-o", str(tmp_path / "f.flo")])
    assert "junk.png" in err


def test_different_sizes(capsys, pair, tmp_path, bgsub_error):
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), _texture(60, 70))
    err = bgsub_error(["flow", str(pair[0]), str(small), "-o", str(tmp_path / "f.flo")])
    assert "differ in size" in err


def test_smaller_than_a_patch(capsys, tmp_path, bgsub_error):
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), _texture(10, 40))
    err = bgsub_error(["flow", str(tiny), str(tiny), "-o", str(tmp_path / "f.flo")])
    assert "13x13" in err


def test_unknown_model(capsys, pair, tmp_path, bgsub_error):
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--model", "no-such-model"])
    assert "no-such-model" in err


def test_existing_output_needs_overwrite(capsys, pair, tmp_path, bgsub_error):
    out = tmp_path / "f.flo"
    out.write_bytes(b"old")
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(out)])
    assert "--overwrite" in err and out.read_bytes() == b"old"


def test_output_must_be_flo_for_a_pair(capsys, pair, tmp_path, bgsub_error):
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.png")])
    assert ".flo" in err


def test_video_options_refused_for_a_pair(capsys, pair, tmp_path, bgsub_error):
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--scale", "0.5"])
    assert "--scale" in err


# --- refusals before any work: outputs that replace inputs, nonsense numbers, ignored options ---


def _video_file(tmp_path, name: str = "clip.avi", size=(80, 120)):
    """A tiny 3-frame MJPG video of a texture moving right by 2 px per frame."""
    h, w = size
    big = _texture(h + 20, w + 20, seed=2)
    path = tmp_path / name
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (w, h))
    for k in range(3):
        writer.write(cv2.cvtColor(big[10:10 + h, 2 * k:2 * k + w], cv2.COLOR_GRAY2BGR))
    writer.release()
    return path


def test_video_output_may_not_replace_the_input_video(capsys, tmp_path, bgsub_error):
    video = _video_file(tmp_path)
    before = video.read_bytes()
    err = bgsub_error(["flow", str(video), "-o", str(video), "--overwrite"])
    assert "-o would overwrite an input" in err
    assert video.read_bytes() == before


def test_vis_may_not_replace_an_input_image(capsys, pair, tmp_path, bgsub_error):
    before = pair[0].read_bytes()
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--vis", str(pair[0]), "--overwrite"])
    assert "--vis would overwrite an input" in err
    assert pair[0].read_bytes() == before
    assert not (tmp_path / "f.flo").exists()


@pytest.mark.parametrize("option, value", [
    ("--max-magnitude", "nan"), ("--max-magnitude", "inf"), ("--max-magnitude", "0"),
    ("--max-magnitude", "-1"), ("--max-motion", "-5"), ("--max-motion", "nan"),
    ("--max-motion", "0"), ("--levels", "-1"), ("--levels", "0"),
])
def test_pair_refuses_nonsense_numbers(capsys, pair, tmp_path, option, value, bgsub_error):
    out = tmp_path / "f.flo"
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(out),
                          "--vis", str(tmp_path / "f.png"), option, value])
    assert option in err and value in err
    assert not out.exists()


def test_video_refuses_nan_max_magnitude(capsys, tmp_path, bgsub_error):
    video, out = _video_file(tmp_path), tmp_path / "flow.avi"
    err = bgsub_error(["flow", str(video), "-o", str(out), "--max-magnitude", "nan"])
    assert "--max-magnitude must be a number above 0" in err
    assert not out.exists()


@pytest.mark.parametrize("options", [["--arrows"], ["--arrow-step", "8"], ["--max-magnitude", "5"]])
def test_pair_picture_options_need_vis(capsys, pair, tmp_path, options, bgsub_error):
    out = tmp_path / "f.flo"
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(out)] + options)
    assert options[0] in err and "--vis" in err
    assert not out.exists()


@pytest.mark.parametrize("mode", ["pair", "video"])
def test_arrow_step_needs_arrows(capsys, pair, tmp_path, mode, bgsub_error):
    if mode == "pair":
        out = tmp_path / "f.flo"
        argv = ["flow", str(pair[0]), str(pair[1]), "-o", str(out), "--vis", str(tmp_path / "f.png")]
    else:
        out = tmp_path / "flow.avi"
        argv = ["flow", str(_video_file(tmp_path)), "-o", str(out)]
    err = bgsub_error(argv + ["--arrow-step", "8"])
    assert "--arrow-step needs --arrows" in err
    assert not out.exists()


@pytest.fixture
def big_patch_model(tmp_path):
    """A (random, untrained) model whose 41x41 patches are larger than 32x48 frames."""
    from bgsub.model.rbm import GatedRBM

    path = tmp_path / "big.npz"
    GatedRBM.create(patch_size=41, n_factors=4, n_hidden=2).save(path)
    return path


@pytest.mark.parametrize("mode", ["pair", "video"])
def test_model_patch_larger_than_the_frames(capsys, tmp_path, big_patch_model, mode, bgsub_error):
    if mode == "pair":
        frame = tmp_path / "small.png"
        cv2.imwrite(str(frame), _texture(32, 48))
        out = tmp_path / "f.flo"
        argv = ["flow", str(frame), str(frame), "-o", str(out)]
    else:
        video, out = _video_file(tmp_path, size=(32, 48)), tmp_path / "flow.avi"
        argv = ["flow", str(video), "-o", str(out)]
    err = bgsub_error(argv + ["--model", str(big_patch_model)])
    assert "48x32, smaller than one 41x41 patch" in err
    assert not out.exists()


def test_folder_given_as_an_image(capsys, pair, tmp_path, bgsub_error):
    folder = tmp_path / "frames"
    folder.mkdir()
    err = bgsub_error(["flow", str(folder), str(pair[1]), "-o", str(tmp_path / "f.flo")])
    assert "is a folder, not an image file" in err


def test_npy_file_as_model(capsys, pair, tmp_path, bgsub_error):
    model = tmp_path / "plain.npy"
    np.save(model, np.zeros(3))
    err = bgsub_error(["flow", str(pair[0]), str(pair[1]), "-o", str(tmp_path / "f.flo"),
                          "--model", str(model)])
    assert "npz" in err


def test_a_random_dot_model_on_a_photograph_is_warned_about(pair, tmp_path, capsys):
    out = tmp_path / "f.flo"
    assert main(["flow", str(pair[0]), str(pair[1]), "-o", str(out), "-q",
                 "--model", "dots-translation"]) == 0
    assert capsys.readouterr().err == (
        f"bgsub: warning: {pair[0]}: a binary (random-dot) model expects dark images with "
        "sparse bright dots; for photographs and natural video use a Gaussian model such as "
        "natural\n")
    assert main(["flow", str(pair[0]), str(pair[1]), "-o", str(out), "-q", "--overwrite"]) == 0
    assert capsys.readouterr().err == ""  # the default model, natural, is for photographs


def test_a_truncated_video_gives_its_flow_with_a_warning(tmp_path, capsys):
    whole, cut = tmp_path / "whole.mkv", tmp_path / "cut.mkv"
    big = _texture(60, 80, seed=3)
    writer = cv2.VideoWriter(str(whole), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 10,
                             (40, 40), True)
    for k in range(12):
        writer.write(cv2.cvtColor(big[10:50, 2 * k:2 * k + 40], cv2.COLOR_GRAY2BGR))
    writer.release()
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert main(["flow", str(cut), "-o", str(tmp_path / "f.avi"), "-q",
                 "--max-motion", "3"]) == 0  # (all that 40x40 frames allow)
    err = capsys.readouterr().err
    assert err.startswith(f"bgsub: warning: {cut} ended after ")
    assert err.endswith(" of the 12 frames its header declares (truncated or damaged?)\n")


def _shifted_pair(tmp_path, shift, size=(240, 320)):
    h, w = size
    dx, dy = shift
    big = _texture(h + 60, w + 60, seed=3)
    f1 = big[30:30 + h, 30:30 + w]
    f2 = big[30 - dy:30 - dy + h, 30 - dx:30 - dx + w]
    p1, p2 = tmp_path / "s1.png", tmp_path / "s2.png"
    cv2.imwrite(str(p1), f1)
    cv2.imwrite(str(p2), f2)
    return p1, p2


def test_max_motion_is_read_on_frames_too_small_for_its_pyramid(tmp_path, capsys):
    # 320x240 allows 3 pyramid levels, which read about 12 px alone: --max-motion widens the
    # coarsest level's search instead (without it, 20 px would be misread).
    p1, p2 = _shifted_pair(tmp_path, (20, 0))
    out = tmp_path / "f.flo"
    assert main(["flow", str(p1), str(p2), "-o", str(out), "--max-motion", "24", "-q"]) == 0
    flow = read_flo(out)
    known = np.isfinite(flow).all(axis=2)
    assert np.median(flow[known, 0]) == pytest.approx(20, abs=1.0)
    assert np.median(flow[known, 1]) == pytest.approx(0, abs=1.0)
    assert "warning" not in capsys.readouterr().err


def test_a_max_motion_no_search_reaches_is_warned_about_once(tmp_path, capsys):
    p1, p2 = _shifted_pair(tmp_path, (2, 0), size=(120, 160))
    out = tmp_path / "f.flo"
    assert main(["flow", str(p1), str(p2), "-o", str(out), "--max-motion", "400", "-q"]) == 0
    err = capsys.readouterr().err
    assert err.count("bgsub: warning: --max-motion 400 is beyond what 160x120 frames allow") == 1
    assert "Warning" not in err  # no Python warning lines


def test_one_image_with_a_flo_output_asks_for_the_pair(pair, tmp_path, bgsub_error):
    err = bgsub_error(["flow", pair[0], "-o", tmp_path / "f.flo"])
    assert f"{pair[0]} is one image: a .flo file needs the pair" in err


def test_two_videos_as_a_pair_are_named_videos_not_corrupt_images(tmp_path, bgsub_error):
    clip = _video_file(tmp_path)
    err = bgsub_error(["flow", clip, clip, "-o", tmp_path / "f.flo"])
    assert f"{clip} is a video, not an image: give a video alone" in err
