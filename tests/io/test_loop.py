"""The frame loop: several engines, consumers in step, interrupts held and shutdown finished."""

from __future__ import annotations

import signal
from typing import List, Optional

import cv2
import numpy as np
import pytest

from bgsub.errors import ProcessingError
from bgsub.io.loop import Consumer, FrameLoop, FrameResult, hold_interrupts
from bgsub.io.sinks import VideoSink, VisSink, open_mask_sink
from bgsub.io.writers import DebugImageWriter, MaskWriter, MotionWriter, VisWriter

from helpers import read_frames

W, H = 48, 32


def _frames(n: int, seed: int = 2):
    rng = np.random.default_rng(seed)
    return [(k, rng.integers(0, 256, (H, W, 3), dtype=np.uint8)) for k in range(n)]


class _Threshold:
    """Foreground above a gray level; ``last_status`` "fallback" on every other frame."""

    def __init__(self, level: int = 128) -> None:
        self.level, self.n, self.last_status = level, 0, "ok"

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        self.n += 1
        self.last_status = "ok" if self.n % 2 else "fallback: test"
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        return np.where(gray > self.level, 255, 0).astype(np.uint8)

    def debug_image(self):
        return np.full((H, W, 3), 200, np.uint8)


class _Record(Consumer):
    """Records what the loop calls, in one list shared by several consumers."""

    def __init__(self, name: str, log: List[str]) -> None:
        self.name, self.log = name, log
        self.results: List[FrameResult] = []
        self.closed: Optional[tuple] = None

    def prepare(self, result):
        self.log.append(f"prepare {self.name} {result.index}")

    def add(self, result):
        self.log.append(f"add {self.name} {result.index}")
        self.results.append(result)

    def close(self, *, complete, error):
        self.log.append(f"close {self.name}")
        self.closed = (complete, error)


class _Signal(Consumer):
    """Sends the process ``signum`` (the signal itself, as Ctrl-C does) from ``when``: "add"
    at frame ``at``, or "close"."""

    def __init__(self, when: str, *, at: int = 0, signum: int = signal.SIGINT) -> None:
        self.when, self.at, self.signum = when, at, signum

    def add(self, result):
        if self.when == "add" and result.index == self.at:
            signal.raise_signal(self.signum)

    def close(self, *, complete, error):
        if self.when == "close":
            signal.raise_signal(self.signum)


def test_every_consumer_gets_every_frame_with_the_masks_of_every_engine():
    log: List[str] = []
    first, second = _Record("a", log), _Record("b", log)
    engines = {"low": _Threshold(60), "high": _Threshold(200)}
    frames = _frames(3)
    stats = FrameLoop(engines, [first, second]).run(frames)
    assert [r.index for r in first.results] == [0, 1, 2]
    result = second.results[1]
    gray = cv2.cvtColor(frames[1][1], cv2.COLOR_BGR2GRAY)
    np.testing.assert_array_equal(result.masks["high"], np.where(gray > 200, 255, 0))
    np.testing.assert_array_equal(result.masks["low"], np.where(gray > 60, 255, 0))
    assert result.engines["low"] is engines["low"]
    assert stats.frames == 3 and stats.complete
    assert stats.engines["high"].statuses["fallback: test"] == 1 and stats.not_ok == 2
    assert first.closed == (True, None) and second.closed == (True, None)


def test_every_consumer_prepares_a_frame_before_any_adds_it_and_they_close_in_reverse():
    log: List[str] = []
    FrameLoop(_Threshold(), [_Record("a", log), _Record("b", log)]).run(_frames(1))
    assert log == ["prepare a 0", "prepare b 0", "add a 0", "add b 0", "close b", "close a"]


class _StopWhilePreparing(Consumer):
    def prepare(self, result):
        if result.index == 2:
            raise KeyboardInterrupt

    def add(self, result):
        pass


def test_an_interrupt_while_a_frame_is_prepared_leaves_it_out_of_every_output(tmp_path,
                                                                             capsys):
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks:
        loop = FrameLoop(_Threshold(), [MaskWriter(masks), _StopWhilePreparing()])
        with pytest.raises(KeyboardInterrupt):
            loop.run(_frames(5))
    assert loop.stats.frames == 2 and not loop.stats.complete
    assert len(read_frames(tmp_path / "m.mkv")) == 2
    assert capsys.readouterr().err == (f"bgsub: {tmp_path / 'm.mkv'} is partial (interrupted) "
                                       "but valid: it holds 2 frames\n")


def test_a_signal_while_a_frame_is_handed_out_waits_until_every_output_has_it(tmp_path):
    # The signal arrives while the first consumer takes frame 3 (index 2): the writers after it
    # still get frame 3, so the outputs stay the same length.
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks, \
                VisSink(tmp_path / "v.mkv", width=W, height=H, fps=10) as vis, \
                VideoSink(tmp_path / "f.mkv", fps=10) as flow:
            FrameLoop(_Threshold(), [_Signal("add", at=2), MaskWriter(masks), VisWriter(vis),
                                     DebugImageWriter(flow)]).run(_frames(6))
    assert [len(read_frames(tmp_path / name)) for name in ("m.mkv", "v.mkv", "f.mkv")] == [3] * 3
    assert signal.getsignal(signal.SIGINT) is before


def test_a_second_signal_while_the_outputs_are_finished_is_ignored(tmp_path, capsys):
    # Ctrl-C at frame 2, then a second Ctrl-C while the first output to close is finished: the
    # interrupt is raised once, after every output is finished.
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks:
        loop = FrameLoop(_Threshold(), [MaskWriter(masks), _Signal("add", at=1),
                                        _Signal("close")])
        with pytest.raises(KeyboardInterrupt) as caught:
            loop.run(_frames(5))
    assert caught.value.__context__ is None  # no second KeyboardInterrupt on the way
    assert len(read_frames(tmp_path / "m.mkv")) == 2
    assert capsys.readouterr().err == (f"bgsub: {tmp_path / 'm.mkv'} is partial (interrupted) "
                                       "but valid: it holds 2 frames\n")


class _FailsWhenFinished(Consumer):
    """Fails as it is finished, as an output the full disk cut short does."""

    def add(self, result):
        pass

    def close(self, *, complete, error):
        raise ProcessingError("another output failed")


@pytest.mark.parametrize("last, stop, words", [
    (_FailsWhenFinished(), ProcessingError, "the run stopped by an error"),
    (_Signal("close"), KeyboardInterrupt, "the run was interrupted"),
])
def test_an_output_that_got_every_frame_is_called_complete_not_partial(tmp_path, capsys, last,
                                                                       stop, words):
    # The last consumer is closed first; a signal while it is closed is raised after it.
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks, \
            open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as folder:
        engines = {"a": _Threshold(), "b": _Threshold()}
        with pytest.raises(stop):
            FrameLoop(engines, [MaskWriter(masks, engine="a"), MaskWriter(folder, engine="b"),
                                last]).run(_frames(4))
    assert len(read_frames(tmp_path / "m.mkv")) == 4 and len(list((tmp_path / "out").iterdir())) == 4
    assert capsys.readouterr().err == (
        f"bgsub: {tmp_path / 'out'} is complete: {words} after writing all 4 frames\n"
        f"bgsub: {tmp_path / 'm.mkv'} is complete: {words} after writing all 4 frames\n")


def test_a_signal_held_while_an_output_is_finished_is_raised_after_it(tmp_path):
    with open_mask_sink(tmp_path / "m.mkv", width=W, height=H, fps=10) as masks:
        loop = FrameLoop(_Threshold(), [MaskWriter(masks), _Signal("close")])
        with pytest.raises(KeyboardInterrupt):
            loop.run(_frames(3))
    assert loop.stats.complete and len(read_frames(tmp_path / "m.mkv")) == 3


class _Plain:
    """An engine with no camera motion and no debug picture."""

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        return np.zeros(image.shape[:2], np.uint8)


def test_a_writer_that_reads_what_the_engine_lacks_is_refused_before_the_first_frame(tmp_path):
    from bgsub.io.sinks import MotionSink

    with MotionSink(tmp_path / "cam.npy") as motion:
        with pytest.raises(TypeError, match="_Plain has no last_motion"):
            FrameLoop(_Plain(), [MotionWriter(motion)]).run(_frames(2))
    assert list(tmp_path.iterdir()) == []


def test_a_writer_among_several_engines_must_name_its_engine(tmp_path):
    with open_mask_sink(tmp_path / "out", width=W, height=H, fps=10) as masks:
        with pytest.raises(ValueError, match="name the engine"):
            FrameLoop({"a": _Plain(), "b": _Plain()}, [MaskWriter(masks)]).run(_frames(1))


@pytest.mark.parametrize("bad, words", [
    (np.zeros((H, W), np.float32), "a mask must be a .32, 48. uint8 array"),
    (np.zeros((H // 2, W), np.uint8), "a mask must be 48x32, got 48x16"),
    (None, "a mask must be .* array, got NoneType"),
])
def test_an_unusable_mask_stops_the_run_naming_the_engine_and_frame(bad, words):
    class _Bad:
        def apply(self, image, fgmask=None, learning_rate=-1.0):
            return bad

    with pytest.raises(ProcessingError, match=f"plugin returned an unusable mask for frame 1: "
                                              f"{words}"):
        FrameLoop({"plugin": _Bad()}, []).run(_frames(1))


def test_hold_interrupts_delivers_a_held_ctrl_c_when_the_block_ends():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with hold_interrupts():
            signal.raise_signal(signal.SIGINT)
            done.append("after the signal")
    assert done == ["after the signal"]
