"""Peak memory of `bgsub run` against input length: it must stay flat (streaming).

Generates a long synthetic clip (default 10,000 frames of 320x240, ``--size``: a noise texture
panning slowly with a bright box moving across, mp4v in /tmp), then runs `python -m bgsub run` on
its first 1,000 frames and on all of it, each in a fresh process, and reports the peak resident
memory (``ru_maxrss`` of that child from ``os.wait4``). A run on the first 10 frames gives the
fixed cost of Python, numpy and OpenCV. A sampled VmRSS timeline of the longest run shows the
memory over time.

    python benchmarks/memory_run.py                       # mog2, 10,000 frames
    python benchmarks/memory_run.py --frames 3000 --vis   # also write the overlay video
    python benchmarks/memory_run.py --method grbm --preset fast   # a named preset
    python benchmarks/memory_run.py --method grbm --preset accurate --size 640x480

Nothing here asserts anything; it prints a Markdown table for docs/BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import List, Optional, Tuple

import cv2
import numpy as np

FPS = 25.0


def make_clip(path: Path, frames: int, size: Tuple[int, int] = (320, 240)) -> None:
    """A panning noise texture with a moving box; cheap to generate and to decode."""
    W, H = size
    rng = np.random.default_rng(0)
    texture = cv2.GaussianBlur(rng.integers(0, 256, (H + 64, W + 64, 3), dtype=np.uint8), (5, 5), 0)
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"mp4v"), FPS,
                             (W, H), True)
    if not writer.isOpened():
        raise SystemExit(f"cannot write {path}")
    for k in range(frames):
        dx = int(32 + 24 * np.sin(k / 50.0))  # the camera sways left and right
        frame = texture[32:32 + H, dx:dx + W].copy()
        x = (3 * k) % (W - 40)
        frame[H // 2 - 20:H // 2 + 20, x:x + 40] = (40, 220, 250)
        writer.write(frame)
    writer.release()


def _rss_kib(pid: int) -> Optional[int]:
    try:
        with open(f"/proc/{pid}/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def measure(cmd: List[str], *, sample_every: float = 0.5
            ) -> Tuple[int, float, List[Tuple[float, int]]]:
    """Run ``cmd``; return (peak RSS in KiB from wait4, seconds, [(t, VmRSS KiB), ...])."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    started = time.perf_counter()
    child = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    samples: List[Tuple[float, int]] = []
    done = threading.Event()

    def sample() -> None:
        while not done.wait(sample_every):
            rss = _rss_kib(child.pid)
            if rss is not None:
                samples.append((time.perf_counter() - started, rss))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    stderr = child.stderr.read()
    _, status, usage = os.wait4(child.pid, 0)
    done.set()
    sampler.join()
    child.returncode = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - started
    if child.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({child.returncode}): {stderr.decode()}")
    return usage.ru_maxrss, seconds, samples  # ru_maxrss is in KiB on Linux


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--method", default="mog2")
    parser.add_argument("--size", default="320x240", metavar="WxH",
                        help="the clip's frame size (default: 320x240)")
    parser.add_argument("--preset", default=None, metavar="NAME",
                        help="the method's named preset, passed to `bgsub run --preset`")
    parser.add_argument("--vis", action="store_true", help="also write the overlay video")
    parser.add_argument("--workdir", type=Path, default=Path("/tmp/bgsub-bench-memory"))
    parser.add_argument("--keep", action="store_true", help="keep the work folder")
    args = parser.parse_args()

    args.workdir.mkdir(parents=True, exist_ok=True)
    size = tuple(int(n) for n in args.size.lower().split("x"))
    clip = args.workdir / f"clip_{args.frames}_{args.size}.mp4"
    if not clip.exists():
        t0 = time.perf_counter()
        make_clip(clip, args.frames, size)
        print(f"generated {clip} ({clip.stat().st_size / 1e6:.0f} MB) in "
              f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)

    rows = []
    timeline: List[Tuple[float, int]] = []
    for stop in sorted({10, min(1000, args.frames), args.frames}):
        out = args.workdir / f"masks_{stop}.mkv"
        cmd = [sys.executable, "-m", "bgsub", "run", str(clip), "-o", str(out), "--method",
               args.method, "--stop", str(stop), "--overwrite", "--quiet"]
        if args.preset:
            cmd += ["--preset", args.preset]
        if args.vis:
            cmd += ["--vis", str(args.workdir / f"vis_{stop}.mp4")]
        peak, seconds, samples = measure(cmd)
        rows.append((stop, peak, seconds))
        if stop == args.frames:
            timeline = samples
        print(f"{stop} frames: peak RSS {peak / 1024:.1f} MiB, {seconds:.1f} s", file=sys.stderr)

    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, OpenCV {cv2.__version__}")
    preset = f", preset {args.preset}" if args.preset else ""
    print(f"input: {clip.name}, {args.size}, method {args.method}{preset}, "
          f"vis {'on' if args.vis else 'off'}\n")
    print("| frames processed | peak RSS (MiB) | wall time (s) |")
    print("|---:|---:|---:|")
    for stop, peak, seconds in rows:
        print(f"| {stop} | {peak / 1024:.1f} | {seconds:.1f} |")
    if timeline:
        # A few evenly spaced samples of the longest run: flat means nothing grows per frame.
        picks = [timeline[int(i * (len(timeline) - 1) / 9)] for i in range(10)] \
            if len(timeline) >= 10 else timeline
        print("\nVmRSS during the longest run (s: MiB): "
              + ", ".join(f"{t:.0f}: {rss / 1024:.1f}" for t, rss in picks))
    if not args.keep:
        shutil.rmtree(args.workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
