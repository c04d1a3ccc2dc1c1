"""bgsub.batch through its Python API: inputs, completion records, thread limits, jobs."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.batch import inputs, record, runner, threads
from bgsub.batch.job import DONE, INTERRUPTED, NOT_STARTED, RunJob, run_input
from bgsub.batch.plan import OutputLayout
from bgsub.errors import InputError
from helpers import write_box_clip

W, H, N = 64, 48, 12


def write_clip(path: Path, *, seed: int = 0) -> Path:
    return write_box_clip(path, seed=seed, n=N, width=W, height=H)


def _job(clip: Path, out: Path) -> RunJob:
    layout = OutputLayout(str(out))
    layout.create_folders()
    name = clip.stem
    return RunJob(str(clip), name, layout.outputs(name), layout.record(name), "mog2")


def test_a_folder_of_videos_is_one_input_per_video(tmp_path):
    for name in ("b10.mkv", "b2.mkv", "notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    items = inputs.expand([str(tmp_path)])
    assert [item.name for item in items] == ["b2", "b10"]


def test_a_folder_or_glob_of_images_is_one_input(tmp_path):
    frames = tmp_path / "seq"
    frames.mkdir()
    for k in range(3):
        cv2.imwrite(str(frames / f"in{k:06d}.png"), np.zeros((16, 16, 3), np.uint8))
    assert inputs.expand([str(frames)]) == [inputs.BatchInput(str(frames), "seq")]
    assert not inputs.is_batch([f"{frames}/"])
    pattern = str(frames / "*.png")
    assert inputs.expand([pattern]) == [inputs.BatchInput(pattern, "seq")]
    assert not inputs.is_batch([pattern])


def test_a_missing_input_stays_an_input_of_its_own(tmp_path):
    items = inputs.expand([str(tmp_path / "gone.mp4"), str(tmp_path / "b.mp4")])
    assert [item.name for item in items] == ["gone", "b"]


def test_two_inputs_of_one_name_are_refused(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for folder in ("a", "b"):
        (tmp_path / folder / "cam.mkv").write_bytes(b"x")
    with pytest.raises(InputError, match="both write outputs named 'cam'"):
        inputs.expand([str(tmp_path / "a" / "cam.mkv"), str(tmp_path / "b" / "cam.mkv")])


def test_one_core_per_job_turns_the_engines_second_thread_off():
    assert threads.engine_params("grbm", {}, threads=1)["overlap"] == 0
    assert "overlap" not in threads.engine_params("grbm", {}, threads=2)
    assert threads.engine_params("grbm", {"overlap": 1}, threads=1)["overlap"] == 1
    assert threads.engine_params("mog2", {}, threads=1) == {}


def test_a_finished_job_is_recorded_complete_and_then_skipped(tmp_path):
    job = _job(write_clip(tmp_path / "v.mkv"), tmp_path / "out")
    result = run_input(job)
    assert (result.status, result.frames) == (DONE, N)
    assert record.read(job.record)["status"] == "complete"
    assert record.decide(job.record, settings=job.settings(), outputs=job.outputs,
                         overwrite=False) == (record.SKIP, None)


def test_a_stopped_job_leaves_a_valid_partial_output_that_is_redone(tmp_path):
    job = _job(write_clip(tmp_path / "v.mkv"), tmp_path / "out")
    asked = []

    def stop_after_four() -> bool:
        asked.append(1)
        return len(asked) > 5  # asked before the job starts, then before each frame's writes

    result = run_input(job, stop_after_four)
    assert (result.status, result.frames) == (INTERRUPTED, 4)
    capture = cv2.VideoCapture(job.outputs["masks"])
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 4
    assert record.decide(job.record, settings=job.settings(), outputs=job.outputs,
                         overwrite=False) == (record.REDO, None)


def test_a_job_stopped_before_its_turn_writes_nothing(tmp_path):
    job = _job(write_clip(tmp_path / "v.mkv"), tmp_path / "out")
    assert run_input(job, lambda: True).status == NOT_STARTED
    assert not Path(job.outputs["masks"]).exists() and record.read(job.record) is None


def test_outputs_made_otherwise_are_not_replaced_without_overwrite(tmp_path):
    job = _job(write_clip(tmp_path / "v.mkv"), tmp_path / "out")
    Path(job.outputs["masks"]).write_bytes(b"someone else's")
    decision, reason = record.decide(job.record, settings=job.settings(), outputs=job.outputs,
                                     overwrite=False)
    assert "no batch record says it is complete" in reason
    assert record.decide(job.record, settings=job.settings(), outputs=job.outputs,
                         overwrite=True) == (record.REDO, None)


def test_other_settings_are_not_taken_for_complete(tmp_path):
    job = _job(write_clip(tmp_path / "v.mkv"), tmp_path / "out")
    run_input(job)
    other = RunJob(**{**job.__dict__, "params": {"history": 50}, "source": {"step": 2}})
    assert record.decide(other.record, settings=other.settings(), outputs=other.outputs,
                         overwrite=False) == (
        record.KEEP, "made with other settings (history default -> 50, step default -> 2): "
                     "--overwrite redoes it")


def test_plan_skips_complete_inputs_and_runs_the_rest(tmp_path):
    clips = [write_clip(tmp_path / f"v{k}.mkv", seed=k) for k in range(2)]
    layout = OutputLayout(str(tmp_path / "out"))
    layout.create_folders()
    run_input(_job(clips[0], tmp_path / "out"))
    items = inputs.expand([str(c) for c in clips])
    todo, settled = runner.plan(items, layout, method="mog2", params={}, run_params={},
                                source={}, overwrite=False, threads=1)
    assert [job.name for job in todo] == ["v1"]
    assert [(r.name, r.status) for r in settled] == [("v0", "skipped")]
