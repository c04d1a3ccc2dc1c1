"""Where the ``grbm`` engine's per-frame time goes: ms per frame of each stage, and the gated
RBM's FLOPs per frame against one core's float32 BLAS peak.

It runs the engine over the clip ``bgsub bench`` times (a :mod:`bgsub.samples` scene generated
in memory) with each stage's functions wrapped by a timer, and prints a Markdown table. A
stage's time is *exclusive* CPU time (``time.thread_time``, so other processes on a shared
machine hardly change it): the CPU time of its thread inside its functions less that of the
timed functions they call, so the rows add up to the whole step. ``overlap=0`` by default
(every stage in the calling thread); with ``--overlap 1`` the second thread's stages are timed
in their own thread, and on an idle machine the sum of the stages less the wall time per frame
is what the overlap saves. The timers cost a few microseconds per call.

Usage::

    OMP_NUM_THREADS=1 python benchmarks/profile_stages.py                      # 320x240
    OMP_NUM_THREADS=1 python benchmarks/profile_stages.py --size 640x480 --overlap 1
    OMP_NUM_THREADS=1 python benchmarks/profile_stages.py --preset fast -p stride=8
"""

from __future__ import annotations

import argparse
import functools
import importlib
import os
import sys
import threading
import time
from collections import defaultdict

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

# (module, attribute path, stage). A function is wrapped wherever it is looked up by name.
STAGES = [
    ("bgsub.engines.moving", "MovingCameraEngine.apply", "engine: gray, sizes, parts"),
    ("bgsub.engines.frontends.grbm", "GrbmFrontEnd.measure", "front end: re-read decisions"),
    ("bgsub.motion.pyramid", "FramePyramid.__init__", "front end: pyramid build"),
    ("bgsub.motion.pyramid", "FramePyramid.levels", "front end: pyramid build"),
    ("bgsub.motion.patches", "level_texture_map", "front end: texture maps"),
    ("bgsub.motion.patches", "textured_pixels", "front end: texture maps"),
    ("bgsub.motion.patches", "patches_at", "front end: patch extraction"),
    ("bgsub.motion.starts", "patches_at", "front end: patch extraction"),
    ("bgsub.motion.patches", "warp_back", "front end: pre-warps of the second frame"),
    ("bgsub.motion.starts", "warp_back", "front end: pre-warps of the second frame"),
    ("bgsub.model.readout", "patch_features", "gRBM: projections onto the factors"),
    ("bgsub.model.readout", "raw_patch_motion", "gRBM: hidden units + readout"),
    ("bgsub.model.readout", "_peaks", "gRBM: peaks and confidence"),
    ("bgsub.motion.global_motion", "fit_global_motion", "front end: RANSAC fits"),
    ("bgsub.motion.patches", "fit_global_motion", "front end: RANSAC fits"),
    ("bgsub.camera.config", "CameraFit.__call__", "front end: RANSAC fits"),
    ("bgsub.motion.starts", "photometric_agreement", "front end: start choice (photometric)"),
    ("bgsub.engines.frontends.grbm", "refine_vectors", "front end: sub-pixel refinement"),
    ("bgsub.motion.flowfield", "estimate_flow", "front end: coarse-to-fine bookkeeping"),
    ("bgsub.engines.frontends.grbm", "estimate_flow", "front end: coarse-to-fine bookkeeping"),
    ("bgsub.engines.frontends.grbm", "prepare_first_frame",
     "front end: coarse-to-fine bookkeeping"),
    ("bgsub.background.compensated", "CompensatedBackground.warp", "background: warp"),
    ("bgsub.background.compensated", "CompensatedBackground.score", "background: score"),
    ("bgsub.background.compensated", "CompensatedBackground.update", "background: update"),
    ("bgsub.background.still_switch", "StillCameraSwitch.judge", "still-camera model: score"),
    ("bgsub.background.still_switch", "StillCameraSwitch.update", "still-camera model: update"),
    ("bgsub.background.fusion", "flow_violation_map", "fusion: flow-violation map"),
    ("bgsub.background.fusion", "frame_evidence", "fusion: the frames' own evidence"),
    ("bgsub.background.fusion", "residual_field", "fusion: the frames' own evidence"),
    ("bgsub.background.fusion", "Fusion.vector_evidence", "fusion: flow-violation map"),
    ("bgsub.background.fusion", "fuse_masks", "fusion: fuse + clean"),
    ("bgsub.background.fusion", "Fusion.learn_slowly", "fusion: fuse + clean"),
    ("bgsub.engines.moving", "guided_mask", "fusion: mask on the frame's edges"),
    ("bgsub.background.object_colour", "ObjectColours.grow", "fusion: the objects' colours"),
    ("bgsub.background.object_colour", "ObjectColours.learn", "fusion: the objects' colours"),
    ("bgsub.background.fusion", "Fusion.close_by_edges", "fusion: holes the edges close"),
]


class Timers:
    """Exclusive CPU time per stage (``time.thread_time``: what another process on the same
    core takes is not counted), per thread (a stack of open calls in each thread)."""

    def __init__(self) -> None:
        self.total = defaultdict(float)
        self.second = defaultdict(float)  # of which in another thread than the main one
        self.calls = defaultdict(int)
        self.flops = 0.0
        self.reread_s = 0.0
        self.reads = 0
        self._local = threading.local()

    def wrap(self, fn, stage):
        @functools.wraps(fn)
        def timed(*args, **kwargs):
            stack = getattr(self._local, "stack", None)
            if stack is None:
                stack = self._local.stack = []
            stack.append(0.0)  # time of timed children
            start = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.thread_time() - start
                children = stack.pop()
                self.total[stage] += spent - children
                if threading.current_thread() is not threading.main_thread():
                    self.second[stage] += spent - children
                self.calls[stage] += 1
                if stack:
                    stack[-1] += spent
        return timed


def _count_flops(timers: Timers, model) -> None:
    """Count the model's matmul FLOPs: projections 2 N p^2 F, hidden units 2 N F K, readout
    2 N K D."""
    from bgsub.model import readout

    p2, n_f = model.wxf.shape
    n_k = model.whf.shape[0]
    features, motion = readout.patch_features, readout.raw_patch_motion

    def patch_features(m, raw, *, side):
        timers.flops += 2.0 * len(raw) * p2 * n_f
        return features(m, raw, side=side)

    def raw_patch_motion(m, x_raw, y_raw, *, max_disp, **kw):
        n_d = (2 * int(max_disp) + 1) ** 2
        timers.flops += 2.0 * len(y_raw) * n_f * n_k + 2.0 * len(y_raw) * n_k * n_d
        return motion(m, x_raw, y_raw, max_disp=max_disp, **kw)

    readout.patch_features, readout.raw_patch_motion = patch_features, raw_patch_motion


def _count_rereads(timers: Timers) -> None:
    """Time the readouts after the first of each frame (coarser re-reads; the full pyramid
    after a refused reduced readout)."""
    from bgsub.engines.frontends import grbm

    read, measure = grbm.GrbmFrontEnd.read, grbm.GrbmFrontEnd.measure

    def counted_measure(self, *args, **kwargs):
        timers.reads = 0
        return measure(self, *args, **kwargs)

    def counted_read(self, *args, **kwargs):
        timers.reads += 1
        start = time.thread_time()
        try:
            return read(self, *args, **kwargs)
        finally:
            if timers.reads > 1:
                timers.reread_s += time.thread_time() - start

    grbm.GrbmFrontEnd.read, grbm.GrbmFrontEnd.measure = counted_read, counted_measure


def instrument(timers: Timers, model) -> None:
    _count_rereads(timers)
    _count_flops(timers, model)
    for module_name, path, stage in STAGES:
        owner = importlib.import_module(module_name)
        *parents, name = path.split(".")
        for part in parents:
            owner = getattr(owner, part)
        setattr(owner, name, timers.wrap(getattr(owner, name), stage))


def sgemm_peak(n: int = 2048, repeats: int = 5) -> float:
    """GFLOP/s of a float32 ``n x n`` matmul per CPU second of this thread (one BLAS thread;
    best of runs)."""
    a = np.random.default_rng(0).random((n, n), dtype=np.float32)
    b = a.T.copy()
    a @ b
    best = min(_timed(lambda: a @ b) for _ in range(repeats))
    return 2.0 * n**3 / best / 1e9


def _timed(fn) -> float:
    start = time.thread_time()
    fn()
    return time.thread_time() - start


def read_clip(path: str, n_frames: int) -> tuple:
    """``(frames, description)``: the first ``n_frames`` frames of the video at ``path`` as one
    ``(N, H, W, 3) uint8`` array."""
    import cv2

    cap, frames = cv2.VideoCapture(path), []
    while len(frames) < n_frames:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    cap.release()
    if len(frames) < 2:
        sys.exit(f"profile_stages.py: {path}: fewer than two frames could be read")
    return np.stack(frames), f"{path}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240", help="frame size WxH")
    ap.add_argument("--frames", type=int, default=100, help="timed frames")
    ap.add_argument("--overlap", type=int, default=0, choices=(0, 1))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--input", help="profile on this video's frames (at their own size) "
                                    "instead of the generated clip")
    ap.add_argument("--preset", help="named settings (fast, balanced, accurate)")
    ap.add_argument("-p", "--param", action="append", default=[], metavar="KEY=VALUE",
                    help="engine parameter over the preset (repeatable)")
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    from bgsub import create_engine
    from bgsub.engines.base import parse_params
    from bgsub.evaluation.bench import make_clip

    if args.input:
        clip, description = read_clip(args.input, args.frames + 1)
        args.size = f"{clip.shape[2]}x{clip.shape[1]}"
        args.frames = len(clip) - 1
    else:
        clip, description = make_clip(width=width, height=height, n_frames=args.frames + 1,
                                      seed=args.seed)
    params = parse_params("grbm", args.param)
    engine = create_engine("grbm", preset=args.preset, overlap=args.overlap, **params)
    timers = Timers()
    instrument(timers, engine.frontend.model)
    engine.apply(clip[0])
    timers.total.clear()
    timers.second.clear()
    timers.flops = timers.reread_s = 0.0
    wall, cpu = time.perf_counter(), time.process_time()
    for frame in clip[1:]:
        engine.apply(frame)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    engine.close()
    report(timers, n=args.frames, wall=wall, cpu=cpu, description=description, args=args)
    return 0


def report(timers: Timers, *, n: int, wall: float, cpu: float, description: str, args) -> None:
    ms = {stage: 1e3 * s / n for stage, s in timers.total.items()}
    summed = sum(ms.values())
    settings = "".join([f"; --preset {args.preset}" if args.preset else "",
                        *(f" -p {pair}" for pair in args.param)])
    print(f"grbm, {args.size}, overlap={args.overlap}, {n} frames of {description}; "
          f"load {os.getloadavg()[0]:.2f}{settings}")
    second = {stage: 1e3 * s / n for stage, s in timers.second.items()}
    print("\n| stage | ms/frame | share | of which second thread |\n|---|---:|---:|---:|")
    for stage in sorted(ms, key=lambda s: (s.split(":")[0], -ms[s])):
        print(f"| {stage} | {ms[stage]:.2f} | {100 * ms[stage] / summed:.1f} % | "
              f"{second.get(stage, 0.0):.2f} |")
    print(f"| **sum of stages** | **{summed:.2f}** | | {sum(second.values()):.2f} |")
    print(f"| of which readouts after the first (coarser re-reads, full after reduced) | "
          f"{1e3 * timers.reread_s / n:.2f} | {100e3 * timers.reread_s / n / summed:.1f} % |")
    print(f"\nwall {1e3 * wall / n:.2f} ms/frame ({n / wall:.1f} fps), CPU "
          f"{1e3 * cpu / n:.2f} ms/frame (process); sum of stages less wall "
          f"{summed - 1e3 * wall / n:.2f} ms/frame")
    model_s = sum(timers.total[s] for s in ("gRBM: projections onto the factors",
                                            "gRBM: hidden units + readout"))
    peak = sgemm_peak()
    gflops = timers.flops / model_s / 1e9 if model_s else 0.0
    print("\n| model | per frame |\n|---|---:|")
    print(f"| matmul FLOPs (projections, hidden units, readout) | "
          f"{timers.flops / n / 1e6:.1f} MFLOP |")
    print(f"| time in projections + hidden units + readout | {1e3 * model_s / n:.2f} ms |")
    print(f"| achieved | {gflops:.1f} GFLOP/s |")
    print(f"| one-core sgemm peak (2048^2, float32) | {peak:.1f} GFLOP/s |")
    print(f"| fraction of peak | {100 * gflops / peak:.0f} % |")


if __name__ == "__main__":
    sys.exit(main())
