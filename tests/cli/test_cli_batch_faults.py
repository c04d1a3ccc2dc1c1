"""A batch that meets a fault (a worker killed, Ctrl-C, a Dask worker lost, a full disk) keeps
the outputs of the inputs that finished, reports each of the others in one line, and a rerun
completes exactly those.

The batches run ``tests/cli/slow_engine.py`` (``bgsub`` with a test engine that waits between
frames) in a process of their own, so a fault can be dealt while a job runs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bgsub.io.sources import open_source
from helpers import write_box_clip

W, H, N = 64, 48, 12
SCRIPT = Path(__file__).with_name("slow_engine.py")
NAMES = ("c0", "c1", "c2", "c3")


@pytest.fixture
def clips(tmp_path) -> Path:
    folder = tmp_path / "clips"
    folder.mkdir()
    for k, name in enumerate(NAMES):
        write_box_clip(folder / f"{name}.mkv", seed=k, n=N, width=W, height=H)
    return folder


def _argv(clips: Path, out: Path, pids: Path, *extra, delay: float = 0.1) -> list:
    pids.mkdir(exist_ok=True)
    return [sys.executable, str(SCRIPT), "run", str(clips), "-o", str(out), "-m", "_test_slow",
            "-p", f"pids={pids}", "-p", f"delay={delay}", *map(str, extra)]


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))


def _start(argv: list) -> subprocess.Popen:
    return subprocess.Popen(argv, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)


def _wait_for(condition, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "the batch never got there"
        time.sleep(0.02)


def _statuses(out: Path) -> dict:
    """The status of each input's completion record (None: no record)."""
    records = out / ".bgsub-batch"
    found = {}
    for name in NAMES:
        try:
            found[name] = json.loads((records / f"{name}.json").read_text())["status"]
        except (OSError, ValueError):
            found[name] = None
    return found


def _workers(pids: Path, batch: subprocess.Popen) -> list:
    """The process ids of the workers that built an engine (the batch's own process builds
    one too, to check the method)."""
    return [int(p.name) for p in pids.iterdir() if int(p.name) != batch.pid]


def _frames(path: Path) -> int:
    with open_source(path) as source:
        return sum(1 for _ in source)


def _summary(path: Path) -> dict:
    return {r["name"]: r["status"] for r in json.loads(path.read_text())["results"]}


def _check_after_fault(clips: Path, out: Path, summary: dict, stderr: str, *,
                       rerun_argv: list) -> None:
    """Done inputs hold every frame; each other input has one line of its own; a rerun does
    exactly the others and skips the done ones."""
    done = [name for name, status in summary.items() if status == "done"]
    for name in done:
        assert _frames(out / f"{name}.mkv") == N
    lines = stderr.splitlines()
    for name in (name for name in NAMES if name not in done):
        own = (f"bgsub: {name}: ", f"bgsub: error: {clips / name}.mkv: ")
        assert len([line for line in lines if line.startswith(own)]) == 1, (name, stderr)
    rerun = subprocess.run(rerun_argv, env=_env(), capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    again = _summary(Path(rerun_argv[rerun_argv.index("--summary") + 1]))
    assert again == {name: "skipped" if name in done else "done" for name in NAMES}
    assert all(_frames(out / f"{name}.mkv") == N for name in NAMES)


def test_a_worker_killed_mid_batch(tmp_path, clips):
    out, pids = tmp_path / "out", tmp_path / "pids"
    batch = _start(_argv(clips, out, pids, "--jobs", 2, "--summary", tmp_path / "s.json"))
    _wait_for(lambda: "complete" in _statuses(out).values())
    os.kill(_workers(pids, batch)[0], signal.SIGKILL)
    _, err = batch.communicate(timeout=60)
    assert batch.returncode == 1, err
    assert "its worker process ended abruptly" in err
    assert "done" in _summary(tmp_path / "s.json").values()
    _check_after_fault(clips, out, _summary(tmp_path / "s.json"), err, rerun_argv=_argv(
        clips, out, pids, "--jobs", 2, "--summary", tmp_path / "again.json"))


def _one_started_after_another_ended(statuses: dict) -> bool:
    """Two jobs running and one complete, in one reading of the records: the job that started
    after the first one ended still has most of its frames to go when Ctrl-C comes (two readings
    would let both first jobs end in between)."""
    values = list(statuses.values())
    return values.count("running") == 2 and values.count("complete") >= 1


def test_ctrl_c_during_two_jobs(tmp_path, clips):
    out, pids = tmp_path / "out", tmp_path / "pids"
    batch = _start(_argv(clips, out, pids, "--jobs", 2, "--summary", tmp_path / "s.json"))
    _wait_for(lambda: _one_started_after_another_ended(_statuses(out)))
    os.killpg(batch.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole process group
    _, err = batch.communicate(timeout=60)
    assert batch.returncode == 130, err
    summary = _summary(tmp_path / "s.json")
    assert "interrupted" in summary.values(), summary
    _check_after_fault(clips, out, summary, err, rerun_argv=_argv(
        clips, out, pids, "--jobs", 2, "--summary", tmp_path / "again.json"))


def test_a_dask_worker_that_dies(tmp_path, clips):
    distributed = pytest.importorskip("distributed")
    out, pids = tmp_path / "out", tmp_path / "pids"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  preload=[str(SCRIPT)], dashboard_address=":0") as cluster:
        argv = _argv(clips, out, pids, "--scheduler", cluster.scheduler_address)
        batch = _start(argv + ["--summary", str(tmp_path / "s.json")])
        _wait_for(lambda: "running" in _statuses(out).values() and _workers(pids, batch))
        os.kill(_workers(pids, batch)[0], signal.SIGKILL)
        _, err = batch.communicate(timeout=120)
        assert batch.returncode in (0, 1), err
        _check_after_fault(clips, out, _summary(tmp_path / "s.json"), err,
                           rerun_argv=argv + ["--summary", str(tmp_path / "again.json")])


@pytest.fixture
def small_disk(tmp_path):
    """A 16-page tmpfs at ``tmp_path/disk`` (skipped where it cannot be mounted)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    page = os.sysconf("SC_PAGE_SIZE")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={16 * page}", "tmpfs",
                              str(disk)], capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f"no small file system to fill: mounting a tmpfs failed (it needs root): "
                    f"{mounted.stderr.strip()}")
    try:
        yield disk, page
    finally:
        subprocess.run(["umount", str(disk)], check=True)


def test_a_full_disk(tmp_path, clips, small_disk):
    disk, page = small_disk
    # Three pages left: room for the first input's masks (3.4 kB) and its record, not more.
    (disk / "filler").write_bytes(bytes(13 * page))
    out, pids = disk / "out", tmp_path / "pids"
    argv = _argv(clips, out, pids, "--jobs", 1, delay=0)
    done = subprocess.run(argv + ["--summary", str(tmp_path / "s.json")], env=_env(),
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "the disk is full" in done.stderr or "No space left on device" in done.stderr
    summary = _summary(tmp_path / "s.json")
    assert summary["c0"] == "done" and "failed" in summary.values(), summary
    (disk / "filler").unlink()
    _check_after_fault(clips, out, summary, done.stderr,
                       rerun_argv=argv + ["--summary", str(tmp_path / "again.json")])
