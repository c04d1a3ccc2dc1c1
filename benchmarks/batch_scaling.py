"""Wall and CPU time of `bgsub run` on many copies of a video: --jobs 1, --jobs N, a LocalCluster.

    PYTHONPATH=$PWD OMP_NUM_THREADS=1 python benchmarks/batch_scaling.py --copies 8 --jobs 1 2 \
        --dask 2 --tiny 8

For each configuration: the batch's wall-clock time, and the CPU time (user + system) of every
process it ran (the command, its worker processes, the Dask workers), so the figures mean
something on a shared machine too. ``--tiny K`` also times K one-frame mog2 jobs, in this
process (--jobs 1) and on the cluster: the per-video overhead of each path. Prints a Markdown
table.
"""

from __future__ import annotations

import argparse
import contextlib
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterator, List, Optional, Tuple

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "pan.mp4"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _bgsub(inputs: List[Path], out: Path, extra: List[str]) -> float:
    """Wall-clock seconds of one `bgsub run` batch (fails loudly if the batch does)."""
    argv = [sys.executable, "-m", "bgsub", "run", *map(str, inputs), "-o", str(out), "-q",
            *extra]
    started = time.perf_counter()
    subprocess.run(argv, check=True)
    return time.perf_counter() - started


@contextlib.contextmanager
def _cluster(workers: Optional[int]) -> Iterator[Optional[str]]:
    if not workers:
        yield None
        return
    from distributed import LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


def measure(inputs: List[Path], out: Path, *, jobs: int = 1, dask: Optional[int] = None,
            extra: Tuple[str, ...] = ()) -> Tuple[float, float]:
    """``(wall seconds, CPU seconds)`` of one batch; the CPU time counts the Dask workers,
    which end (and are counted) when the cluster closes."""
    shutil.rmtree(out, ignore_errors=True)
    cpu = _children_cpu()
    with _cluster(dask) as address:
        option = ["--scheduler", address] if address else ["--jobs", str(jobs)]
        wall = _bgsub(inputs, out, [*option, *extra])
    return wall, _children_cpu() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=8)
    parser.add_argument("--jobs", type=int, nargs="*", default=[1, 2])
    parser.add_argument("--dask", type=int, default=0, help="workers of a LocalCluster (0: none)")
    parser.add_argument("--tiny", type=int, default=0, help="one-frame jobs for the overhead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bgsub-batch-") as tmp:
        folder = Path(tmp)
        inputs = []
        for k in range(args.copies):
            inputs.append(folder / f"pan{k + 1}.mp4")
            shutil.copy(SAMPLE, inputs[-1])
        rows = [(f"--jobs {j}", *measure(inputs, folder / "out", jobs=j)) for j in args.jobs]
        if args.dask:
            rows.append((f"LocalCluster, {args.dask} workers",
                         *measure(inputs, folder / "out", dask=args.dask)))
        print(f"| {args.copies} x {SAMPLE.name} (grbm) | wall s | CPU s | videos/min |")
        print("|---|---|---|---|")
        for label, wall, cpu in rows:
            print(f"| {label} | {wall:.1f} | {cpu:.1f} | {60 * args.copies / wall:.1f} |")
        if args.tiny:
            tiny = [folder / f"t{k}.mp4" for k in range(args.tiny)]
            for path in tiny:
                shutil.copy(SAMPLE, path)
            flags = ("--method", "mog2", "--stop", "1")
            local = measure(tiny, folder / "tiny", jobs=1, extra=flags)[0]
            print(f"\none-frame jobs: --jobs 1 {local / args.tiny:.3f} s per video")
            if args.dask:
                started = time.perf_counter()
                with _cluster(args.dask) as address:
                    setup = time.perf_counter() - started
                    wall = _bgsub(tiny, folder / "tiny2", ["--scheduler", address, *flags])
                print(f"one-frame jobs: LocalCluster {wall / args.tiny:.3f} s per video "
                      f"(cluster start {setup:.1f} s, not included)")


if __name__ == "__main__":
    main()
