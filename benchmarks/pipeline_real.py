"""F-measure of bgsub engines on the real moving-camera set (../shared/data/real).

Every engine runs over each sequence from its first frame; every frame with ground truth inside
the sequence's temporal ROI (temporalROI.txt, all frames but the first where absent) is scored
with CDnet 2014 conventions: GT 255 positive, 0/50 negative, 85/170 ignored; prediction
foreground where > 127. Per sequence F = 2TP / (2TP + FP + FN) over all its scored frames (the
CDnet per-sequence figure); family mean = mean over its sequences; overall = mean of the families.

Two more modes share the engine plumbing:

* ``--generated SEEDS``: the same F-measure on scenes rendered in memory by
  :mod:`bgsub.samples` (every category, the given seeds), plus the median error of the fitted
  camera motion at the frame corners against the exact ``camera_motion`` (engines that expose
  it);
* ``--speed``: frames/s of the whole per-frame step (``engine.apply``) at 320x240 and 640x480 on
  a generated pan, wall-clock and process CPU time (CPU time is what an unloaded core would
  take when the machine is shared).

Usage (minutes; keep the machine quiet with one thread when not timing)::

    OMP_NUM_THREADS=1 python benchmarks/pipeline_real.py --methods grbm compensated mog2
    python benchmarks/pipeline_real.py --methods compensated --param compensated:flow_weight=1
    OMP_NUM_THREADS=1 python benchmarks/pipeline_real.py --generated 0 1 2 --methods grbm compensated mog2
    python benchmarks/pipeline_real.py --speed --methods grbm compensated
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from bgsub.engines import create_engine, parse_params

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"

FAMILIES = {"CDnet2014": "CDnet traffic", "BMS26": "BMS-26", "UCSD": "UCSD", "DAVIS2016": "DAVIS"}


def family_of(name: str) -> str:
    return FAMILIES[name.split("_")[0]]


def roi_of(seq: Path, n_frames: int) -> tuple:
    roi = seq / "temporalROI.txt"
    if roi.is_file():
        first, last = (int(v) for v in roi.read_text().split()[:2])
    else:
        first, last = 1, n_frames
    return max(first, 2), last  # the first frame has no history for any method


def run_sequence(method: str, params: dict, seq: Path, *, start_before: int = 0) -> tuple:
    """Counts (tp, fp, fn, tn) and frames/s of ``method`` on one sequence."""
    frames = sorted((seq / "input").glob("in*.jpg")) + sorted((seq / "input").glob("in*.png"))
    first, last = roi_of(seq, len(frames))
    begin = 1 if start_before <= 0 else max(1, first - start_before)
    engine = create_engine(method, **params)
    tp = fp = fn = tn = 0
    elapsed = 0.0
    n = 0
    for path in frames:
        k = int(path.stem[2:])
        if k < begin or k > last:
            continue
        frame = cv2.imread(str(path), cv2.IMREAD_COLOR)
        t0 = time.perf_counter()
        mask = engine.apply(frame)
        elapsed += time.perf_counter() - t0
        n += 1
        if k < first:
            continue
        gt = cv2.imread(str(seq / "groundtruth" / f"gt{k:06d}.png"), cv2.IMREAD_GRAYSCALE)
        if gt is None:
            continue
        c = _count(mask, gt)
        tp, fp, fn, tn = tp + c[0], fp + c[1], fn + c[2], tn + c[3]
    return (tp, fp, fn, tn), n / max(elapsed, 1e-9)


def _count(mask: np.ndarray, gt: np.ndarray) -> tuple:
    """(tp, fp, fn, tn) of one frame with CDnet 2014 labels (bgsub.evaluation.cdnet when present)."""
    try:
        from bgsub.evaluation.cdnet import count_frame
    except ImportError:  # the evaluation module is optional for this script
        pred = mask > 127
        pos = gt == 255
        neg = (gt == 0) | (gt == 50)
        return (int(np.count_nonzero(pred & pos)), int(np.count_nonzero(pred & neg)),
                int(np.count_nonzero(~pred & pos)), int(np.count_nonzero(~pred & neg)))
    c = count_frame(mask, gt)
    return c.tp, c.fp, c.fn, c.tn


def f_measure(tp: int, fp: int, fn: int) -> float:
    return 2 * tp / max(2 * tp + fp + fn, 1)


def run_generated(method: str, params: dict, seeds, *, n_frames: int = 60) -> None:
    """F per category over ``seeds`` and the median corner error of the camera motion each
    frame applied (``engine.last_motion``)."""
    from bgsub.motion.global_motion import corner_error
    from bgsub.samples import CATEGORIES, SceneSpec, render_frames

    means = []
    for cat in CATEGORIES:
        tp = fp = fn = 0
        errs = []
        statuses = defaultdict(int)
        for seed in seeds:
            engine = create_engine(method, **params)
            spec = SceneSpec(cat, seed=seed, n_frames=n_frames)
            for k, (img, gt, motion) in enumerate(render_frames(spec)):
                mask = engine.apply(img)
                statuses[getattr(engine, "last_status", "ok")] += 1
                if k == 0:
                    continue
                pred = mask > 127
                tp += int(np.count_nonzero(pred & (gt == 255)))
                fp += int(np.count_nonzero(pred & (gt == 0)))
                fn += int(np.count_nonzero(~pred & (gt == 255)))
                # The motion the engine applied (what `bgsub run --motion` writes): the fit, or
                # the fallback, or none for a still camera's sub-pixel readings.
                applied = getattr(engine, "last_motion", None)
                if applied is not None:
                    errs.append(corner_error(applied, motion, width=spec.width,
                                             height=spec.height))
        f = f_measure(tp, fp, fn)
        if cat != "static":
            means.append(f)
        med = f"{np.median(errs):.3f}" if errs else "-"
        bad = sum(v for k, v in statuses.items() if k != "ok")
        print(f"{method:12s} {cat:16s} F={f:.3f}  corner error median {med} px  "
              f"non-ok frames {bad}", flush=True)
    print(f"{method:12s} mean F over the moving categories: {np.mean(means):.3f}", flush=True)


def run_speed(method: str, params: dict, *, n_frames: int = 60, repeats: int = 1) -> None:
    """Frames/s of ``engine.apply`` at 320x240 and 640x480 inputs (a generated pan, upscaled).

    Each size is timed ``repeats`` times (a new engine each time); the median and the best run
    are printed, by wall clock and by process CPU time (less affected by other jobs)."""
    from bgsub.samples import SceneSpec, render_frames

    base = [f.image for f in render_frames(SceneSpec("pan", seed=1, n_frames=n_frames))]
    for w, h in ((320, 240), (640, 480)):
        frames = [cv2.resize(f, (w, h), interpolation=cv2.INTER_LINEAR) for f in base]
        walls, cpus = [], []
        for _ in range(max(1, repeats)):
            # The engines' defaults (work_width=320 for grbm/compensated); pass
            # --param grbm:work_width=0 to time processing at the input size.
            engine = create_engine(method, **params)
            engine.apply(frames[0])
            t0, c0 = time.perf_counter(), time.process_time()
            for f in frames[1:]:
                engine.apply(f)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            n = len(frames) - 1
            walls.append(n / wall)
            cpus.append(n / cpu)
        print(f"{method:12s} {w}x{h}: {np.median(walls):6.1f} frames/s wall-clock "
              f"(best {max(walls):.1f}), {np.median(cpus):6.1f} frames/s of process CPU time "
              f"(best {max(cpus):.1f}); median of {len(walls)}", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", nargs="+", default=["grbm", "compensated"])
    ap.add_argument("--param", action="append", default=[], metavar="METHOD:KEY=VALUE",
                    help="engine parameter, e.g. grbm:work_width=320 (repeatable)")
    ap.add_argument("--sequences", nargs="*", default=None, help="subset of sequence names")
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--traffic-lead", type=int, default=100,
                    help="frames run before CDnet traffic's temporal ROI (default 100)")
    ap.add_argument("--generated", nargs="+", type=int, default=None, metavar="SEED",
                    help="evaluate on generated scenes with these seeds instead")
    ap.add_argument("--speed", action="store_true", help="measure frames/s instead")
    ap.add_argument("--repeat", type=int, default=1, help="--speed: timed runs per size (median)")
    args = ap.parse_args(argv)
    if args.generated is not None or args.speed:
        for method in args.methods:
            pairs = [p.split(":", 1)[1] for p in args.param if p.split(":", 1)[0] == method]
            params = parse_params(method, pairs)
            if args.speed:
                run_speed(method, params, repeats=args.repeat)
            else:
                run_generated(method, params, args.generated)
        return 0
    if not args.data.is_dir():
        print(f"real data not found at {args.data}", file=sys.stderr)
        return 2
    seqs = sorted(p for p in args.data.iterdir() if (p / "input").is_dir())
    if args.sequences:
        seqs = [p for p in seqs if p.name in set(args.sequences)]
    results = {}
    for method in args.methods:
        pairs = [p.split(":", 1)[1] for p in args.param if p.split(":", 1)[0] == method]
        params = parse_params(method, pairs)
        per_seq = {}
        for seq in seqs:
            lead = args.traffic_lead if seq.name.startswith("CDnet") else 0
            counts, fps = run_sequence(method, params, seq, start_before=lead)
            f = f_measure(*counts[:3])
            per_seq[seq.name] = (f, fps)
            print(f"{method:12s} {seq.name:34s} F={f:.3f}  {fps:6.1f} frames/s", flush=True)
        fam = defaultdict(list)
        for name, (f, _) in per_seq.items():
            fam[family_of(name)].append(f)
        fam_mean = {k: float(np.mean(v)) for k, v in fam.items()}
        results[method] = (fam_mean, float(np.mean(list(fam_mean.values()))))
    order = ["CDnet traffic", "BMS-26", "UCSD", "DAVIS"]
    print()
    print("| method | " + " | ".join(order) + " | mean of families |")
    print("|---|" + "---|" * (len(order) + 1))
    for method, (fam_mean, overall) in results.items():
        cells = " | ".join(f"{fam_mean[k]:.3f}" if k in fam_mean else "-" for k in order)
        print(f"| {method} | {cells} | {overall:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
