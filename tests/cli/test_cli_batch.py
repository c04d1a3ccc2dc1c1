"""`bgsub run IN1 IN2 ... -o OUTDIR/` end to end on small generated clips."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.engines import Engine, Param, register_engine
from bgsub.io.sources import open_source
from helpers import write_box_clip

W, H, N = 64, 48, 12


class _StopsAt(Engine):
    """mog2 that acts as if Ctrl-C were pressed at frame ``at`` (0-based)."""

    def __init__(self, at: int) -> None:
        self.engine = cv2.createBackgroundSubtractorMOG2()
        self.at, self.seen = at, 0

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        if self.seen == self.at:
            raise KeyboardInterrupt
        self.seen += 1
        mask = self.engine.apply(image)
        return np.where(mask > 127, 255, 0).astype(np.uint8)


register_engine("_test_batch_ctrl_c", "test: Ctrl-C at a frame",
                params={"at": Param(5, "frame")})(_StopsAt)


def _clip(path: Path, *, seed: int = 0) -> Path:
    return write_box_clip(path, seed=seed, n=N, width=W, height=H)


@pytest.fixture
def clips(tmp_path) -> list:
    folder = tmp_path / "clips"
    folder.mkdir()
    return [_clip(folder / f"v{k}.mkv", seed=k) for k in range(3)]


def _masks(path: Path) -> list:
    with open_source(path) as source:
        return [frame[:, :, 0].copy() for _, frame in source]


def _run(capsys, *args) -> tuple:
    code = main(["run", *map(str, args)])
    return code, capsys.readouterr().err


def test_a_batch_on_two_processes_gives_each_input_its_masks(tmp_path, clips, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, *clips, "-o", out, "--method", "mog2", "--jobs", "2",
                     "--summary", tmp_path / "s.json")
    assert code == 0, err
    for clip in clips:
        single = tmp_path / f"single-{clip.stem}.mkv"
        assert _run(capsys, clip, "-o", single, "--method", "mog2")[0] == 0
        batch_masks, single_masks = _masks(out / f"{clip.stem}.mkv"), _masks(single)
        assert len(batch_masks) == N
        assert all(np.array_equal(a, b) for a, b in zip(batch_masks, single_masks))
    summary = json.loads((tmp_path / "s.json").read_text())
    assert [(r["name"], r["status"], r["frames"]) for r in summary["results"]] == \
        [("v0", "done", N), ("v1", "done", N), ("v2", "done", N)]
    assert summary["results"][0]["outputs"] == {"masks": str(out / "v0.mkv")}


def test_a_broken_input_fails_alone(tmp_path, clips, capsys):
    broken = tmp_path / "clips" / "broken.mp4"
    broken.write_bytes(b"not a video")
    code, err = _run(capsys, clips[0], broken, clips[1], "-o", tmp_path / "out",
                     "--method", "mog2", "--jobs", "2", "--summary", tmp_path / "s.json")
    assert code == 1
    errors = [line for line in err.splitlines() if line.startswith("bgsub: error:")]
    assert len(errors) == 1 and str(broken) in errors[0]
    assert "failed: broken" in err.splitlines()[-1]
    statuses = {r["name"]: r["status"] for r in json.loads((tmp_path / "s.json").read_text())
                ["results"]}
    assert statuses == {"v0": "done", "broken": "failed", "v1": "done"}


def test_ctrl_c_stops_the_batch_and_a_rerun_finishes_it(tmp_path, clips, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, *clips, "-o", out, "--method", "_test_batch_ctrl_c", "--jobs", "1",
                     "--summary", tmp_path / "s.json")
    assert code == 130, err
    summary = json.loads((tmp_path / "s.json").read_text())
    assert [r["status"] for r in summary["results"]] == ["interrupted", "not started",
                                                         "not started"]
    assert len(_masks(out / "v0.mkv")) == 5  # partial but valid
    # The partial output is the batch's own: redone, whatever the settings now.
    code, err = _run(capsys, *clips, "-o", out, "--method", "_test_batch_ctrl_c", "--param",
                     "at=99", "--jobs", "1")
    assert code == 0, err
    assert all(len(_masks(out / f"{clip.stem}.mkv")) == N for clip in clips)
    # Complete outputs made with other settings are not taken for this run's: kept, and each
    # input reported as a skip that names the change.
    before = [(out / f"{clip.stem}.mkv").read_bytes() for clip in clips]
    code, err = _run(capsys, *clips, "-o", out, "--method", "mog2", "--jobs", "1")
    assert code == 0, err
    assert err.splitlines()[:3] == [
        f"bgsub: {clip.stem}: made with other settings (method _test_batch_ctrl_c -> mog2, at 99 "
        "-> default): --overwrite redoes it" for clip in clips]
    assert "3 skipped" in err.splitlines()[-1]
    assert [(out / f"{clip.stem}.mkv").read_bytes() for clip in clips] == before


def test_a_rerun_redoes_only_what_is_not_complete(tmp_path, clips, capsys):
    out = tmp_path / "out"
    one = str(tmp_path / "clips" / "v0*")  # a glob of videos is a batch, even of one
    assert _run(capsys, one, "-o", out, "--method", "mog2", "--jobs", "1",
                "--mask-format", "png")[0] == 0
    code, err = _run(capsys, *clips, "-o", out, "--method", "mog2", "--jobs", "2",
                     "--mask-format", "png", "--summary", tmp_path / "s.json")
    assert code == 0, err
    statuses = [r["status"] for r in json.loads((tmp_path / "s.json").read_text())["results"]]
    assert statuses == ["skipped", "done", "done"]
    assert sorted(p.name for p in (out / "v1").iterdir())[:2] == ["bin000001.png",
                                                                 "bin000002.png"]


def test_outputs_not_made_by_a_batch_are_kept(tmp_path, clips, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "v0.mkv").write_bytes(b"mine")
    code, err = _run(capsys, *clips[:2], "-o", out, "--method", "mog2", "--jobs", "1")
    assert code == 1 and "--overwrite replaces it" in err
    assert (out / "v0.mkv").read_bytes() == b"mine"
    assert len(_masks(out / "v1.mkv")) == N


def test_a_folder_of_videos_is_a_batch_with_side_outputs_in_folders(tmp_path, clips, capsys):
    code, err = _run(capsys, tmp_path / "clips", "-o", tmp_path / "out", "--method", "mog2",
                     "--vis", tmp_path / "vis", "--jobs", "1")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "vis").iterdir()) == ["v0.mp4", "v1.mp4",
                                                                    "v2.mp4"]


@pytest.mark.parametrize("argv, message", [
    (["-o", "OUT/masks.mkv"], "is a folder"),
    (["-o", "OUT", "--vis", "OUT/v.mp4"], "--vis of several inputs is a folder"),
    (["-o", "OUT", "--jobs", "-1"], "--jobs takes a number of inputs at once, or 0"),
    (["-o", "OUT", "--objects", "objects.jsonl"], "--objects of several inputs is a folder"),
])
def test_batch_options_are_checked_first(tmp_path, clips, bgsub_error, argv, message):
    argv = [str(a).replace("OUT", str(tmp_path / "out")) for a in argv]
    assert message in bgsub_error(["run", *clips, *argv, "--method", "mog2"])


def test_summary_is_for_batches(tmp_path, clips, bgsub_error):
    err = bgsub_error(["run", clips[0], "-o", tmp_path / "m.mkv", "--summary",
                       tmp_path / "s.json"])
    assert "--summary is for several inputs" in err


def test_a_summary_in_the_batch_s_own_output_folder(tmp_path, clips, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, *clips, "-o", out, "--method", "mog2", "--jobs", "1",
                     "--summary", out / "s.json")
    assert code == 0, err
    assert json.loads((out / "s.json").read_text())["counts"] == {"done": 3}


def test_an_existing_summary_needs_overwrite(tmp_path, clips, capsys, bgsub_error):
    summary = tmp_path / "s.json"
    summary.write_text("mine\n")
    err = bgsub_error(["run", *clips, "-o", tmp_path / "out", "--method", "mog2",
                       "--summary", summary])
    assert f"{summary}: already exists (--overwrite replaces it" in err
    assert summary.read_text() == "mine\n" and not (tmp_path / "out").exists()
    code, err = _run(capsys, *clips, "-o", tmp_path / "out", "--method", "mog2", "--jobs", "1",
                     "--summary", summary, "--overwrite")
    assert code == 0 and json.loads(summary.read_text())["counts"] == {"done": 3}


def test_a_truncated_input_s_warning_names_it_once(tmp_path, clips, capsys):
    data = clips[1].read_bytes()
    cut = tmp_path / "clips" / "cut.mkv"
    cut.write_bytes(data[: len(data) // 2])  # its header still declares every frame
    code, err = _run(capsys, clips[0], cut, "-o", tmp_path / "out", "--method", "mog2",
                     "--jobs", "1")
    assert code == 0, err
    warnings = [line for line in err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].count(str(cut)) == 1, err
    assert warnings[0].startswith(f"bgsub: warning: {cut} ended after ")


def test_an_input_named_like_the_record_folder_is_refused(tmp_path, clips, bgsub_error):
    odd = tmp_path / "clips" / ".bgsub-batch.mkv"
    odd.write_bytes(clips[0].read_bytes())
    err = bgsub_error(["run", odd, clips[1], "-o", tmp_path / "out", "--method", "mog2",
                       "--mask-format", "png"])
    assert "the batch's own record folder" in err
    assert not (tmp_path / "out").exists()


def test_without_dask_the_scheduler_option_names_the_extra(tmp_path, clips):
    code = ("import sys; sys.modules['distributed'] = None\n"
            "from bgsub.cli import main\n"
            f"raise SystemExit(main(['run', {str(clips[0])!r}, {str(clips[1])!r}, '-o', "
            f"{str(tmp_path / 'out')!r}, '--method', 'mog2', '--scheduler', 'tcp://x:1']))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "bgsub: error: --scheduler needs Dask's distributed client: pip install 'bgsub[dask]'"]
    assert not (tmp_path / "out").exists()  # a refused batch creates nothing


def test_a_batch_on_a_dask_cluster(tmp_path, clips, capsys):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster:
        code, err = _run(capsys, *clips, tmp_path / "broken.mp4", "-o", tmp_path / "out",
                         "--method", "mog2", "--scheduler", cluster.scheduler_address,
                         "--summary", tmp_path / "s.json")
    assert code == 1 and "broken.mp4: no such file or folder" in err
    statuses = [r["status"] for r in json.loads((tmp_path / "s.json").read_text())["results"]]
    assert statuses == ["done", "done", "done", "failed"]
    assert all(len(_masks(tmp_path / "out" / f"{clip.stem}.mkv")) == N for clip in clips)


@pytest.fixture
def dataset(tmp_path) -> Path:
    """Three small CDnet-style scenes under one root."""
    from bgsub.samples import SceneSpec, generate_scene

    root = tmp_path / "dataset"
    for seed, category in enumerate(("pan", "jitter", "static")):
        generate_scene(SceneSpec(category, seed=seed, width=64, height=48, n_frames=10,
                                 warmup=0, n_objects=1), root)
    return root


def _eval_json(capsys, *args) -> dict:
    assert main(["eval", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_a_dataset_runs_as_a_batch_and_evals_the_same_on_two_processes(tmp_path, dataset,
                                                                         capsys):
    code, err = _run(capsys, str(dataset / "*"), "-o", tmp_path / "preds", "--method", "mog2",
                     "--jobs", "2")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "preds").glob("*.mkv")) == [
        "jitter_s1.mkv", "pan_s0.mkv", "static_s2.mkv"]
    one = _eval_json(capsys, tmp_path / "preds", dataset, "--jobs", "1")
    two = _eval_json(capsys, tmp_path / "preds", dataset, "--jobs", "2")
    assert one == two and len(one["sequences"]) == 3


def test_eval_on_a_dask_cluster_gives_the_same_figures(tmp_path, dataset, capsys):
    distributed = pytest.importorskip("distributed")
    assert _run(capsys, str(dataset / "*"), "-o", tmp_path / "preds", "--method", "mog2",
                "--jobs", "1")[0] == 0
    one = _eval_json(capsys, tmp_path / "preds", dataset, "--jobs", "1")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster:
        on_dask = _eval_json(capsys, tmp_path / "preds", dataset, "--scheduler",
                             cluster.scheduler_address)
    assert one == on_dask


def _compare_rows(folder: Path) -> list:
    rows = json.loads((folder / "report.json").read_text())["rows"]
    return [{k: v for k, v in row.items() if k not in ("seconds", "fps")} for row in rows]


def test_compare_on_two_processes_reports_what_one_does(tmp_path, dataset, capsys):
    for jobs in ("1", "2"):
        assert main(["compare", str(dataset), "-o", str(tmp_path / f"cmp{jobs}"), "--methods",
                     "mog2,framediff", "--mask-format", "mkv", "--no-video", "--jobs", jobs]) == 0
    capsys.readouterr()
    assert _compare_rows(tmp_path / "cmp1") == _compare_rows(tmp_path / "cmp2")
    files = [sorted(p.relative_to(tmp_path / f"cmp{jobs}").as_posix()
                    for p in (tmp_path / f"cmp{jobs}").rglob("*.mkv")) for jobs in ("1", "2")]
    assert files[0] == files[1] and len(files[0]) == 6
