"""`bgsub run` end to end, with small test engines so the tests do not depend on real engines."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import List, Optional

import cv2
import numpy as np
import pytest

from bgsub import engines
from bgsub.cli import main
from bgsub.engines import Engine, Param, register_engine
from bgsub.engines.moving import SCENE_CUT
from bgsub.io.sources import open_source

W, H, N = 80, 60, 20


class _FrameDiff(Engine):
    """Foreground where the gray level changed by more than ``threshold`` since the last frame."""

    calls = 0  # frames processed by any instance, to see whether processing started

    def __init__(self, threshold: int) -> None:
        self.threshold = threshold
        self.previous: Optional[np.ndarray] = None

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        _FrameDiff.calls += 1
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY).astype(np.int16)
        previous = gray if self.previous is None else self.previous
        self.previous = gray
        return np.where(np.abs(gray - previous) > self.threshold, 255, 0).astype(np.uint8)


class _Interrupting(_FrameDiff):
    """Acts as if the user pressed Ctrl-C while frame number ``at`` (0-based) was processed."""

    def __init__(self, at: int) -> None:
        super().__init__(30)
        self.at, self.seen = at, 0

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        if self.seen == self.at:
            self._stop()
        self.seen += 1
        return super().apply(image)

    def _stop(self) -> None:
        raise KeyboardInterrupt


class _Drawing(_FrameDiff):
    """Has a debug picture (none for the first frame) and a status ("fallback" every 3rd frame)."""

    def __init__(self) -> None:
        super().__init__(30)
        self.seen = 0
        self.last_status = "ok"

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        self.seen += 1
        self.last_status = "fallback: test" if self.seen % 3 == 0 else "ok"
        return super().apply(image)

    def debug_image(self):
        if self.seen < 2:
            return None
        return np.full((H // 2, W // 2, 3), 200, np.uint8)


register_engine("_test_diff", "test: frame difference",
                params={"threshold": Param(30, "gray level change")})(_FrameDiff)
register_engine("_test_interrupt", "test: Ctrl-C at a frame",
                params={"at": Param(5, "frame")})(_Interrupting)
class _Killed(_Interrupting):
    """Sends the process SIGTERM (as `kill` does) while frame number ``at`` is processed."""

    def _stop(self) -> None:
        os.kill(os.getpid(), signal.SIGTERM)


register_engine("_test_killed", "test: SIGTERM at a frame",
                params={"at": Param(5, "frame")})(_Killed)
register_engine("_test_draw", "test: debug_image and last_status")(_Drawing)


class _Cutting(_FrameDiff):
    """Takes every frame for a scene cut unless ``smooth`` > 0 (as grainy footage does)."""

    def __init__(self, smooth: float) -> None:
        super().__init__(30)
        self.last_status = "ok" if smooth > 0 else SCENE_CUT


register_engine("_test_cuts", "test: every frame a scene cut",
                params={"smooth": Param(0.0, "blur")})(_Cutting)


class _InterruptedDrawing(_Drawing):
    """Ctrl-C while the debug picture of frame number ``at`` (0-based) is drawn, after its mask
    was made."""

    def __init__(self, at: int) -> None:
        super().__init__()
        self.at = at

    def debug_image(self):
        if self.seen == self.at + 1:
            raise KeyboardInterrupt
        return super().debug_image()


register_engine("_test_draw_interrupt", "test: Ctrl-C while drawing a frame",
                params={"at": Param(5, "frame")})(_InterruptedDrawing)


def _clip_frames(n: int = N) -> List[np.ndarray]:
    rng = np.random.default_rng(0)
    frames = []
    for k in range(n):
        frame = rng.integers(0, 40, (H, W, 3), dtype=np.uint8)
        frame[20:35, 2 * k:2 * k + 15] = 230  # a bright box moving right
        frames.append(frame)
    return frames


@pytest.fixture
def clip(tmp_path) -> Path:
    path = tmp_path / "clip.mkv"
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 25.0,
                             (W, H), True)
    for frame in _clip_frames():
        writer.write(frame)
    writer.release()
    return path


def _video_frames(path: Path) -> List[np.ndarray]:
    with open_source(path) as source:
        return [frame for _, frame in source]


def _run(capsys, *args) -> tuple:
    code = main(["run", *map(str, args)])
    return code, capsys.readouterr().err


def test_masks_video_matches_the_engine(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--method", "_test_diff",
                     "--param", "threshold=50")
    assert code == 0
    engine = _FrameDiff(50)
    want = [engine.apply(frame) for frame in _clip_frames()]
    got = _video_frames(tmp_path / "m.mkv")
    assert len(got) == N
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g[:, :, 0], w)
    assert any(w.any() for w in want)  # the engine found the box: the check above means something
    assert f"{N} frames" in err and "m.mkv" in err and len(err.strip().splitlines()) == 1


def test_folder_input_gives_matching_png_names(tmp_path, capsys):
    folder = tmp_path / "seq" / "input"
    folder.mkdir(parents=True)
    for k, frame in enumerate(_clip_frames(8)):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), frame)
    code, err = _run(capsys, tmp_path / "seq", "-o", tmp_path / "out", "-m", "_test_diff",
                     "--start", "2", "--step", "2")
    assert code == 0
    assert sorted(os.listdir(tmp_path / "out")) == [f"bin00000{k}.png" for k in (3, 5, 7)]


def test_fps_notice_for_image_folder_written_as_video(tmp_path, capsys):
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, frame in enumerate(_clip_frames(3)):
        cv2.imwrite(str(folder / f"f{k}.png"), frame)
    code, err = _run(capsys, folder, "-o", tmp_path / "m.mkv", "-m", "_test_diff")
    assert code == 0 and "25 fps" in err


def test_mask_video_from_a_later_start_notes_the_eval_flags(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "-m", "_test_diff",
                     "--start", "4", "--step", "3", "--stop", "16")
    assert code == 0
    lines = err.strip().splitlines()
    assert len(lines) == 2 and len(_video_frames(tmp_path / "m.mkv")) == 4
    assert f"`bgsub eval {tmp_path / 'm.mkv'} GROUNDTRUTH --start 4 --step 3 --stop 16`" \
        in lines[1]  # after the summary: once the masks are written


@pytest.mark.parametrize("output, args", [
    ("m.mkv", ["--stop", "6"]),             # frame k is still frame k: nothing to say
    ("m", ["--start", "4", "--step", "3"]),  # bin pngs carry the frame numbers
    ("m.mkv", ["--start", "4", "--quiet"]),
])
def test_no_eval_note_when_not_needed_or_quiet(tmp_path, clip, capsys, output, args):
    code, err = _run(capsys, clip, "-o", tmp_path / output, "-m", "_test_diff", *args)
    assert code == 0 and "bgsub eval" not in err


def test_vis_video_is_side_by_side(tmp_path, clip, capsys):
    code, _ = _run(capsys, clip, "-o", tmp_path / "m", "--vis", tmp_path / "vis.mp4",
                   "-m", "_test_diff", "--stop", "6")
    assert code == 0
    frames = _video_frames(tmp_path / "vis.mp4")
    assert len(frames) == 6 and frames[0].shape == (H, 2 * W, 3)


def test_flow_vis_and_status_summary(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--flow-vis", tmp_path / "f.mkv",
                     "-m", "_test_draw", "--stop", "9")
    assert code == 0
    frames = _video_frames(tmp_path / "f.mkv")
    assert len(frames) == 9  # the first frame had no picture: black, to stay in step
    assert frames[0].mean() < 10 and frames[1].mean() > 150
    assert "3 frames not ok" in err and "fallback: test" in err


def test_flow_vis_needs_an_engine_that_draws(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--flow-vis", tmp_path / "f.mp4",
                     "-m", "_test_diff")
    assert code == 2 and "debug_image" in err
    assert not (tmp_path / "m.mkv").exists() and not (tmp_path / "f.mp4").exists()


def test_existing_output_is_refused_before_processing(tmp_path, clip, capsys):
    (tmp_path / "vis.mp4").write_bytes(b"old")
    before = _FrameDiff.calls
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--vis", tmp_path / "vis.mp4",
                     "-m", "_test_diff")
    assert code == 2 and "already exists" in err and len(err.strip().splitlines()) == 1
    assert _FrameDiff.calls == before and not (tmp_path / "m.mkv").exists()
    code, _ = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--vis", tmp_path / "vis.mp4",
                   "-m", "_test_diff", "--overwrite")
    assert code == 0 and len(_video_frames(tmp_path / "vis.mp4")) == N


def test_output_with_an_unknown_extension_is_refused_not_made_a_folder(tmp_path, clip,
                                                                       bgsub_error):
    before = _FrameDiff.calls
    err = bgsub_error(["run", clip, "-o", tmp_path / "masks.txt", "-m", "_test_diff"])
    assert ".mkv" in err and "a folder for binNNNNNN.png masks" in err
    assert _FrameDiff.calls == before and not (tmp_path / "masks.txt").exists()


def test_output_equal_to_input_is_refused(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", clip, "-m", "_test_diff", "--overwrite")
    assert code == 2 and "input" in err
    assert len(_video_frames(clip)) == N


@pytest.mark.parametrize("args, words", [
    (["--method", "no-such-method"], "unknown method"),
    (["-m", "_test_diff", "--param", "nope=1"], "no parameter"),
    (["-m", "_test_diff", "--param", "threshold=high"], "takes an integer"),
    (["-m", "_test_diff", "--param", "threshold"], "KEY=VALUE"),
    (["-m", "grbm", "--param", "stride=0"], "must be at least 1"),
    (["-m", "_test_diff", "--step", "0"], "step"),
])
def test_bad_options_exit_2(tmp_path, clip, capsys, args, words):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", *args)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.mkv").exists()


def test_ctrl_c_keeps_valid_partial_outputs_and_exits_130(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--vis", tmp_path / "v.mp4",
                     "-m", "_test_interrupt", "--param", "at=7")
    assert code == 130
    assert len(_video_frames(tmp_path / "m.mkv")) == 7
    assert len(_video_frames(tmp_path / "v.mp4")) == 7
    assert "interrupted" in err and "valid" in err and "7 frames" in err
    assert not list(tmp_path.glob(".*partial*"))


def test_ctrl_c_mid_frame_leaves_all_outputs_the_same_length(tmp_path, clip, capsys):
    outputs = [tmp_path / "m.mkv", tmp_path / "v.mp4", tmp_path / "f.mkv"]
    code, err = _run(capsys, clip, "-o", outputs[0], "--vis", outputs[1], "--flow-vis",
                     outputs[2], "-m", "_test_draw_interrupt", "--param", "at=5")
    assert code == 130
    assert [len(_video_frames(path)) for path in outputs] == [5, 5, 5]
    assert err.count("holds 5 frames") == 3


def test_sigterm_keeps_valid_partial_outputs_like_ctrl_c(tmp_path, clip, capsys):
    before = signal.getsignal(signal.SIGTERM)
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--vis", tmp_path / "v.mp4",
                     "-m", "_test_killed", "--param", "at=7")
    assert code == 128 + signal.SIGTERM
    assert len(_video_frames(tmp_path / "m.mkv")) == 7
    assert len(_video_frames(tmp_path / "v.mp4")) == 7
    assert "SIGTERM" in err and "valid" in err
    assert not list(tmp_path.glob(".*partial*"))
    assert signal.getsignal(signal.SIGTERM) == before  # restored after the command


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_a_full_stdout_is_one_error_line():
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-m", "bgsub", "methods"], stdout=full,
                              stderr=subprocess.PIPE, text=True, timeout=60)
    assert done.returncode == 1
    assert done.stderr.strip() == "bgsub: error: No space left on device"


def test_quiet_prints_nothing(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "-m", "_test_diff", "--quiet")
    assert code == 0 and err == ""


@pytest.mark.parametrize("argv, words", [
    (["run", "x.mp4"], "the following arguments are required: -o/--output (see `bgsub run "
                       "--help`)"),
    (["run", "x.mp4", "-o", "y.mkv", "--fps", "abc"], "argument --fps: invalid float value: "
                                                      "'abc' (see `bgsub run --help`)"),
    (["run", "x.mp4", "-o", "y.mkv", "--bogus"], "unrecognized arguments: --bogus (see `bgsub "
                                                 "run --help`)"),
    (["nosuch"], "argument COMMAND: invalid choice: 'nosuch'"),
])
def test_a_usage_error_is_one_line_pointing_at_the_help(argv, words, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    err = capsys.readouterr().err
    assert stop.value.code == 2
    assert err.startswith(f"bgsub: error: {words}") and err.count("\n") == 1, err


def test_help_teaches_with_examples(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "examples:" in out and "bgsub run clip.mp4 -o masks.mkv" in out


def _python_m_bgsub(*args) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "bgsub", "run", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=120)


def test_subprocess_bad_input_is_one_line_exit_2(tmp_path):
    result = _python_m_bgsub(tmp_path / "missing.mp4", "-o", tmp_path / "m.mkv")
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert "missing.mp4" in result.stderr


@pytest.mark.skipif("mog2" not in [s.name for s in engines.available_engines()],
                    reason="the mog2 engine (bgsub.engines.baselines) is not available")
def test_subprocess_run_with_mog2(tmp_path, clip):
    result = _python_m_bgsub(clip, "-o", tmp_path / "masks", "--method", "mog2")
    assert result.returncode == 0, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    names = sorted(os.listdir(tmp_path / "masks"))
    assert len(names) == N and names[0] == "bin000001.png"
    last = cv2.imread(str(tmp_path / "masks" / names[-1]), cv2.IMREAD_UNCHANGED)
    assert last.shape == (H, W) and set(np.unique(last)) <= {0, 255}


_SLOW_RUN = """
import os, sys, time
import numpy as np
from bgsub.cli import main
from bgsub.engines import Engine, register_engine

@register_engine("_test_slow", "test: 0.1 s per frame")
class Slow(Engine):
    calls = 0

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        Slow.calls += 1
        if Slow.calls == 3:  # two masks are written: tell the test it may interrupt
            open(os.environ["BGSUB_TEST_MARKER"], "w").close()
        go = os.environ.get("BGSUB_TEST_GO")  # then wait for this file, when given
        deadline = time.monotonic() + 60
        while Slow.calls >= 3 and go and not os.path.exists(go) and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.1)
        return np.zeros(image.shape[:2], np.uint8)

raise SystemExit(main(["run", *sys.argv[1:], "-m", "_test_slow"]))
"""


def test_real_sigint_leaves_valid_partial_output(tmp_path, clip):
    out = tmp_path / "m.mkv"
    marker = tmp_path / "two-written"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               BGSUB_TEST_MARKER=str(marker))
    child = subprocess.Popen([sys.executable, "-c", _SLOW_RUN, str(clip), "-o", str(out)],
                             stderr=subprocess.PIPE, text=True, env=env)
    partial = tmp_path / ".m.partial.mkv"
    deadline = time.monotonic() + 60
    # Interrupt mid-run, however slow the machine: once two masks are written (the whole run
    # would take N * 0.1 s = 2 s).
    while not marker.exists() and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert partial.exists()
    child.send_signal(signal.SIGINT)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    held = int(re.search(r"holds (\d+) frame", err).group(1))
    assert 0 < held < N and len(_video_frames(out)) == held
    assert not partial.exists()


def test_methods_lists_the_default_engine_first(capsys):
    assert main(["methods"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("grbm (default):")


# --- outputs that would clash with the input, empty names, summaries, truncated videos -------


def _image_folder(folder: Path, n: int = 4) -> Path:
    folder.mkdir(parents=True)
    for k, frame in enumerate(_clip_frames(n)):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), frame)
    return folder


@pytest.mark.parametrize("given, output", [
    ("seq", "seq/input/"),              # a CDnet sequence reads its input/
    ("seq/input", "seq/./input"),       # the folder itself, spelt another way
    ("seq/input/*.png", "seq/input"),   # a glob lists the folder its matches are in
    ("seq/input/in00000[1-3].png", "seq/sub/../input/"),
])
def test_mask_folder_that_is_the_input_folder_is_refused(tmp_path, capsys, given, output):
    frames = _image_folder(tmp_path / "seq" / "input")
    before = sorted(os.listdir(frames))
    code, err = _run(capsys, tmp_path / given, "-o", tmp_path / output, "-m", "_test_diff",
                     "--overwrite")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "the folder the input frames are read from" in err
    assert sorted(os.listdir(frames)) == before  # no bin*.png beside the frames


def test_mask_folder_beside_the_input_folder_is_fine(tmp_path, capsys):
    _image_folder(tmp_path / "seq" / "input")
    code, err = _run(capsys, tmp_path / "seq", "-o", tmp_path / "seq" / "masks", "-m",
                     "_test_diff")
    assert code == 0, err
    assert len(os.listdir(tmp_path / "seq" / "masks")) == 4


@pytest.mark.parametrize("flag", ["-o", "--vis"])
def test_writing_to_stdout_is_refused(tmp_path, clip, capsys, flag):
    outputs = {"-o": tmp_path / "m.mkv", flag: "-"}
    args = [arg for pair in outputs.items() for arg in pair]
    code, err = _run(capsys, clip, *args, "-m", "_test_diff")
    assert code == 2 and "writing to stdout is not supported" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "-").exists()


@pytest.mark.parametrize("name", ["", "  "])
def test_an_empty_method_is_refused_not_the_default(tmp_path, clip, capsys, name):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "--method", name)
    assert code == 2 and "--method is empty" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m.mkv").exists()


@pytest.mark.parametrize("smooth, hinted", [("0", True), ("1", False)])
def test_frames_taken_for_scene_cuts_suggest_smoothing(tmp_path, clip, capsys, smooth, hinted):
    code, err = _run(capsys, clip, "-o", tmp_path / "m.mkv", "-m", "_test_cuts", "--stop", "4",
                     "-p", f"smooth={smooth}")
    assert code == 0 and ("--param smooth=1" in err) == hinted, err


def test_summary_of_one_frame_and_of_frames_all_ok(tmp_path, clip, capsys):
    code, err = _run(capsys, clip, "-o", tmp_path / "a.mkv", "-m", "_test_diff", "--stop", "1")
    assert code == 0 and "1 frame in" in err and "1 frames" not in err
    code, err = _run(capsys, clip, "-o", tmp_path / "b.mkv", "-m", "_test_draw", "--stop", "2")
    assert code == 0 and "2 frames in" in err and err.strip().endswith("; all frames ok")
    assert "not ok" not in err


def _truncated_copy(video: Path, target: Path) -> Path:
    """The first half of ``video``'s bytes: its header still declares every frame."""
    data = video.read_bytes()
    target.write_bytes(data[: len(data) // 2])
    return target


def test_a_truncated_video_is_processed_with_a_warning(tmp_path, clip, capsys):
    cut = _truncated_copy(clip, tmp_path / "cut.mkv")
    with open_source(cut) as source:
        decoded = len(list(source))
    assert 0 < decoded < N - 2
    code, err = _run(capsys, cut, "-o", tmp_path / "m.mkv", "-m", "_test_diff", "--quiet")
    assert code == 0
    assert err == (f"bgsub: warning: {cut} ended after {decoded} of the {N} frames its header "
                   "declares (truncated or damaged?)\n")
    assert len(_video_frames(tmp_path / "m.mkv")) == decoded


def test_no_truncation_warning_when_the_run_stops_before_the_damage(tmp_path, clip, capsys):
    cut = _truncated_copy(clip, tmp_path / "cut.mkv")
    code, err = _run(capsys, cut, "-o", tmp_path / "m.mkv", "-m", "_test_diff", "--stop", "3")
    assert code == 0 and "bgsub: warning" not in err
    code, err = _run(capsys, clip, "-o", tmp_path / "w.mkv", "-m", "_test_diff", "--step", "3")
    assert code == 0 and "bgsub: warning" not in err  # a whole video read with a step


class _DotsModel:
    """What the engines' ``model`` attribute looks like to the warning: a random-dot model."""

    output_units = "binary"


class _WithModel(_FrameDiff):
    def __init__(self, units: str) -> None:
        super().__init__(30)
        self.model = _DotsModel() if units == "binary" else None


register_engine("_test_model", "test: has a model",
                params={"units": Param("binary", "output units of its model")})(_WithModel)


def test_a_random_dot_model_on_natural_frames_is_warned_about(tmp_path, clip, capsys):
    folder = tmp_path / "bright"
    folder.mkdir()
    for k, frame in enumerate(_clip_frames(3)):
        cv2.imwrite(str(folder / f"f{k}.png"), 255 - frame)  # mostly bright: not random dots
    code, err = _run(capsys, folder, "-o", tmp_path / "m", "-m", "_test_model", "--quiet")
    assert code == 0
    assert err == (f"bgsub: warning: {folder}: a binary (random-dot) model expects dark images "
                   "with sparse bright dots; for photographs and natural video use a Gaussian "
                   "model such as natural\n")
    assert len(os.listdir(tmp_path / "m")) == 3


@pytest.mark.parametrize("units, dark", [("binary", True), ("gaussian", False)])
def test_no_model_warning_for_dark_frames_or_other_models(tmp_path, clip, capsys, units, dark):
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, frame in enumerate(_clip_frames(2)):
        cv2.imwrite(str(folder / f"f{k}.png"), frame if dark else 255 - frame)
    code, err = _run(capsys, folder, "-o", tmp_path / "m", "-m", "_test_model", "--param",
                     f"units={units}", "--quiet")
    assert code == 0 and err == ""


def test_ctrl_c_while_the_parser_is_built_is_one_line_exit_130(monkeypatch, capsys):
    import bgsub.cli

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(bgsub.cli.importlib, "import_module", interrupted)
    assert main(["methods"]) == 130
    assert capsys.readouterr().err == "bgsub: interrupted\n"


def test_help_states_how_masks_are_numbered(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "numbered by position in INPUT" in out and "starts again at bin000001.png" in out
    assert "numbered like the input frames" not in out


def test_masks_of_part_of_a_folder_are_numbered_from_1(tmp_path, capsys):
    # What the help says: numbering is by position in the input, not by the frames' names.
    folder = _image_folder(tmp_path / "seq" / "input", 12)
    code, _ = _run(capsys, str(folder / "in00001*.png"), "-o", tmp_path / "m", "-m",
                   "_test_diff", "--start", "1")
    assert code == 0
    assert sorted(os.listdir(tmp_path / "m")) == ["bin000002.png", "bin000003.png"]


def test_fps_sets_the_rate_of_a_mask_video_from_a_folder(tmp_path, capsys):
    folder = tmp_path / "seq"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for k in range(3):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"),
                    rng.integers(0, 255, (32, 48, 3), dtype=np.uint8))
    code, err = _run(capsys, folder, "-o", tmp_path / "m.mkv", "-m", "framediff", "--fps", "12")
    assert code == 0 and "states no frame rate" not in err
    cap = cv2.VideoCapture(str(tmp_path / "m.mkv"))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(12.0)


def test_importing_the_cli_loads_no_numpy():
    """`bgsub` reaches main()'s Ctrl-C handling before the heavy imports (numpy, OpenCV)."""
    import subprocess
    import sys

    code = "import sys, bgsub, bgsub.cli; print('numpy' in sys.modules, 'cv2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.split() == ["False", "False"]


def _numbered_folder(folder, first: int, n: int = 6):
    """``folder`` holding ``n`` frames of the test clip named ``in{first}.png`` onwards."""
    folder.mkdir()
    for k, frame in enumerate(_clip_frames(n)):
        cv2.imwrite(str(folder / f"in{first + k:06d}.png"), frame)
    return folder


@pytest.mark.parametrize("first, start, noted", [
    (20, 0, True),   # a folder holding part of a sequence: in000020.jpg's mask is bin000001
    (1, 0, False),   # a whole CDnet input/ folder: the numbers agree
    (1, 4, False),   # ... also with --start
    (0, 0, False),   # names counted from 0
])
def test_a_note_when_mask_numbers_differ_from_the_file_names(tmp_path, capsys, first, start,
                                                             noted):
    folder = _numbered_folder(tmp_path / "part", first)
    code, err = _run(capsys, folder, "-o", tmp_path / "m", "-m", "_test_diff",
                     "--start", str(start))
    assert code == 0
    assert ("masks are numbered by position" in err) == noted
    if noted:
        assert "the mask of in000020.png is number 1 (bin000001.png), not 20" in err


def test_motion_file_holds_the_estimated_camera_motion(tmp_path, capsys):
    from bgsub.motion.global_motion import corner_error
    from bgsub.samples import SceneSpec, generate_scene

    scene = generate_scene(SceneSpec("pan", seed=2, width=160, height=120, n_frames=10),
                           tmp_path)
    out = tmp_path / "cam.npy"
    code, err = _run(capsys, scene, "-o", tmp_path / "m.mkv", "-m", "compensated",
                     "--motion", out)
    assert code == 0, err
    assert f"{out}" in err  # named in the summary
    motion = np.load(out, allow_pickle=False)
    truth = np.load(scene / "camera_motion.npy")
    assert motion.shape == truth.shape == (10, 3, 3) and motion.dtype == np.float64
    np.testing.assert_array_equal(motion[0], np.eye(3))
    errors = [corner_error(m, t, width=160, height=120) for m, t in zip(motion[1:], truth[1:])]
    assert np.median(errors) < 0.5, errors


@pytest.mark.parametrize("extra, words", [
    (["--motion", "cam.txt"], "a motion file is a .npy array"),
    (["--motion", "cam.npy", "-m", "mog2"], "--motion: method 'mog2' estimates no camera motion"),
    (["--motion", "m.mkv"], "given to both -o and --motion"),
])
def test_bad_motion_outputs_are_refused(tmp_path, clip, capsys, extra, words, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = _run(capsys, clip, "-o", "m.mkv", *extra)
    assert code == 2 and words in err, err
    assert not (tmp_path / "m.mkv").exists()


@pytest.mark.parametrize("first, hinted", [(20, False), (1, True)])
def test_no_eval_range_is_suggested_for_masks_numbered_by_position(tmp_path, capsys, first,
                                                                   hinted):
    # A folder holding frames 20-25 of a sequence: --start counts its positions, which name no
    # ground-truth frame, so a `bgsub eval --start` hint would score the wrong frames (a whole
    # sequence, from frame 1, keeps the hint).
    folder = _numbered_folder(tmp_path / "frames", first)
    code, err = _run(capsys, folder, "-o", tmp_path / "m.mkv", "-m", "_test_diff",
                     "--start", "2")
    assert code == 0
    assert ("masks are numbered by position" in err) == (not hinted)
    assert ("bgsub eval" in err and "--start 2" in err) == hinted


def _wait_for(path: Path, child: subprocess.Popen) -> None:
    deadline = time.monotonic() + 60
    while not path.exists() and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert path.exists(), child.communicate(timeout=60)[1]


def test_a_second_run_writing_the_same_output_is_refused_and_the_first_finishes(tmp_path, clip):
    out, marker, go = tmp_path / "m.mkv", tmp_path / "two-written", tmp_path / "go"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               BGSUB_TEST_MARKER=str(marker), BGSUB_TEST_GO=str(go))
    first = subprocess.Popen([sys.executable, "-c", _SLOW_RUN, str(clip), "-o", str(out)],
                             stderr=subprocess.PIPE, text=True, env=env)
    _wait_for(marker, first)  # the first run is writing, and waits for `go`
    second = subprocess.run([sys.executable, "-c", _SLOW_RUN, str(clip), "-o", str(out)],
                            capture_output=True, text=True, timeout=120,
                            env=dict(env, BGSUB_TEST_MARKER=str(tmp_path / "unused"),
                                     BGSUB_TEST_GO=""))
    go.touch()
    _, err = first.communicate(timeout=120)
    assert second.returncode == 2
    assert second.stderr == f"bgsub: error: {out}: another run is writing it now; wait for it " \
                            "to end or choose another name\n"
    assert first.returncode == 0, err
    assert len(_video_frames(out)) == N
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mkv", "go", "m.mkv",
                                                          "two-written"]


_CTRL_C_THEN_ANOTHER = """
import atexit, os, signal, sys
import cv2
import numpy as np
from bgsub.cli import main
from bgsub.engines import Engine, register_engine

second = getattr(signal, os.environ["BGSUB_TEST_SECOND"])
when = os.environ["BGSUB_TEST_WHEN"]
opencv_writer = cv2.VideoWriter


class Writer:
    # OpenCV's video writer, but a second signal arrives while the video is being finished.
    def __init__(self, *args):
        self._writer = opencv_writer(*args)

    def isOpened(self):
        return self._writer.isOpened()

    def write(self, image):
        return self._writer.write(image)

    def release(self):
        if when == "finishing":
            os.kill(os.getpid(), second)
        self._writer.release()


cv2.VideoWriter = Writer
if when == "exiting":  # (the last thing the process runs)
    atexit.register(lambda: os.kill(os.getpid(), second))


@register_engine("_test_ctrl_c", "test: Ctrl-C at the fourth frame")
class CtrlC(Engine):
    calls = 0

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        CtrlC.calls += 1
        if CtrlC.calls == 4:
            os.kill(os.getpid(), signal.SIGINT)
        return np.zeros(image.shape[:2], np.uint8)


sys.argv = ["bgsub", "run", *sys.argv[1:], "-m", "_test_ctrl_c"]  # as the console script
raise SystemExit(main())
"""


@pytest.mark.parametrize("second, when", [
    ("SIGTERM", "finishing"),  # a kill right after Ctrl-C
    ("SIGINT", "finishing"),  # Ctrl-C pressed twice
    ("SIGINT", "exiting"),
])
def test_a_second_signal_during_shutdown_keeps_the_output_and_prints_no_traceback(
        tmp_path, clip, second, when):
    out = tmp_path / "m.mkv"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               BGSUB_TEST_SECOND=second, BGSUB_TEST_WHEN=when)
    done = subprocess.run([sys.executable, "-c", _CTRL_C_THEN_ANOTHER, str(clip), "-o",
                           str(out)], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 130, done.stderr
    assert done.stderr == (f"bgsub: {out} is partial (interrupted) but valid: it holds 3 "
                           "frames\nbgsub: interrupted\n")
    assert len(_video_frames(out)) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.mkv", "m.mkv"]
