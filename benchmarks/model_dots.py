"""Benchmark the gated RBM on random dots: training time, accuracy, inference speed.

Usage (from the repository root; results go to docs/BENCHMARKS.md by hand)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/model_dots.py train
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/model_dots.py eval
    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/model_dots.py speed

* ``train``: the paper's setup (13x13, 200 factors, 100 mapping units, CD-1, momentum 0.9,
  sparsity 0.02, one fixed set of 10,000 pairs of 9 one-pixel translations), learning rate 0.05.
  Every ``--every`` epochs the model is scored on 1,000 fresh pairs (not counted in the training
  clock); stops when global direction and per-pixel max-flow both reach ``--target``.
* ``eval``: the shipped (or given) models on 1,000 fresh pairs each.
* ``speed``: inference for a 320x240 frame pair cut into 13x13 patches at stride 6.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bgsub.model.rbm import load_model  # noqa: E402
from bgsub.model.readout import max_flow_field, patch_displacements, precompute  # noqa: E402
from bgsub.model.training import (  # noqa: E402
    FixedPairs,
    TrainConfig,
    TranslatedDots,
    evaluate_rotation,
    evaluate_translation,
    train,
)


def machine() -> str:
    threads = os.environ.get("OMP_NUM_THREADS", "unset")
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, OMP_NUM_THREADS={threads}"


def bench_train(args: argparse.Namespace) -> dict:
    rng = np.random.default_rng(args.seed)
    source = TranslatedDots(max_shift=1)
    if not args.fresh:
        x, y, _ = source.sample(rng, 10_000)
        source = FixedPairs(x, y)
    cfg = TrainConfig(lr=args.lr, epochs=args.max_epochs, seed=args.seed, fresh_pairs=args.fresh)
    clock = {"train": 0.0, "last": time.perf_counter()}
    history = []

    def on_epoch(epoch, error, get_model):
        now = time.perf_counter()
        clock["train"] += now - clock["last"]
        stop = False
        if (epoch + 1) % args.every == 0:
            scores = evaluate_translation(get_model(), max_shift=1, n=1000, seed=777)
            history.append((epoch + 1, round(clock["train"], 2), scores["patch_accuracy"], scores["pixel_accuracy"]))
            print(f"epoch {epoch + 1:4d}  train {clock['train']:6.1f} s  err {error:.4f}  "
                  f"direction {scores['patch_accuracy']:.4f}  max-flow {scores['pixel_accuracy']:.4f}", flush=True)
            stop = scores["patch_accuracy"] >= args.target and scores["pixel_accuracy"] >= args.target
        clock["last"] = time.perf_counter()
        return stop

    result = train(source, cfg, on_epoch=on_epoch)
    return {
        "reached_target": bool(result.stopped_early),
        "epochs": result.epochs_run,
        "train_seconds": round(clock["train"], 2),
        "seconds_per_epoch": round(clock["train"] / result.epochs_run, 3),
        "history": history,
    }


def bench_eval(args: argparse.Namespace) -> dict:
    out = {}
    for name in args.models:
        model = load_model(name)
        kind = model.meta.get("data_kind", "")
        t0 = time.perf_counter()
        if "rotation" in name or kind == "dots-rotation":
            r = evaluate_rotation(model, max_angle=30.0, n=1000, seed=args.seed + 1000)
        else:
            shift = int(model.meta.get("max_shift", 0)) or (3 if "3px" in name else 1)
            r = evaluate_translation(model, max_shift=shift, n=1000, seed=args.seed + 1000)
            rw = evaluate_translation(model, max_shift=shift, n=1000, seed=args.seed + 1000, radius=shift)
            r["pixel_accuracy_windowed"] = rw["pixel_accuracy"]
            r["max_shift"] = shift
        r["seconds"] = round(time.perf_counter() - t0, 2)
        out[name] = r
        print(name, json.dumps(r), flush=True)
    return out


def _best_time(fn, repeats: int, clock=time.perf_counter) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def bench_speed(args: argparse.Namespace) -> dict:
    from numpy.lib.stride_tricks import sliding_window_view

    model = load_model(args.speed_model)
    p, stride = model.patch_size, 6
    rng = np.random.default_rng(args.seed)
    big = (rng.random((242, 322)) < 0.1).astype(np.float32)
    f1, f2 = big[1:-1, 1:-1], big[1:-1, :-2]  # frame 2 = frame 1 moved right by 1 px

    def cut(img):
        return sliding_window_view(img, (p, p))[::stride, ::stride].reshape(-1, p * p)

    xr, yr = cut(f1), cut(f2)
    n = len(xr)
    x, y, _ = model.prepare(xr, yr)
    max_disp = args.max_disp
    precompute(model, max_disp=max_disp)  # as the engines do (OpenBLAS warmed up)
    patch_displacements(model, x, y, max_disp=max_disp)  # fills the per-model cache
    max_flow_field(model, x, y, radius=max_disp)

    def displacements():
        xx, yy, _ = model.prepare(xr, yr)
        h = model.hidden_probs(xx, yy)
        patch_displacements(model, xx, yy, max_disp=max_disp, h=h)

    h = model.hidden_probs(x, y)
    result = {
        "patches": n,
        "model": args.speed_model,
        "max_disp": max_disp,
        "hidden_plus_displacements_ms": round(1e3 * _best_time(displacements, args.repeats), 2),
        "windowed_max_flow_ms": round(1e3 * _best_time(lambda: max_flow_field(model, x, h=h, radius=max_disp), args.repeats), 2),
        "full_max_flow_ms": round(1e3 * _best_time(lambda: max_flow_field(model, x, h=h), 1), 1),
        # CPU time of this process: what an idle core would take, less sensitive to other load.
        "hidden_plus_displacements_cpu_ms": round(1e3 * _best_time(displacements, args.repeats, time.process_time), 2),
        "windowed_max_flow_cpu_ms": round(
            1e3 * _best_time(lambda: max_flow_field(model, x, h=h, radius=max_disp), args.repeats, time.process_time), 2),
        "load_average": os.getloadavg()[0],
    }
    disp, _ = patch_displacements(model, x, y, max_disp=max_disp, subpixel=False)
    result["displacement_correct"] = float(np.mean(np.all(disp == [1, 0], axis=1)))
    print(json.dumps(result), flush=True)
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=("train", "eval", "speed", "all"))
    parser.add_argument("--lr", type=float, default=0.05)
    parser.add_argument("--max-epochs", type=int, default=300)
    parser.add_argument("--every", type=int, default=5, help="evaluate every N epochs (train)")
    parser.add_argument("--target", type=float, default=0.995)
    parser.add_argument("--fresh", action="store_true", help="fresh pairs every epoch instead of a fixed set")
    parser.add_argument("--models", nargs="+", default=["dots-translation", "dots-translation-3px", "dots-rotation"])
    parser.add_argument("--speed-model", default="dots-translation-3px")
    parser.add_argument("--max-disp", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, help="also write the results here")
    args = parser.parse_args()
    results = {"machine": machine(), "command": " ".join(sys.argv)}
    if args.what in ("train", "all"):
        results["train"] = bench_train(args)
    if args.what in ("eval", "all"):
        results["eval"] = bench_eval(args)
    if args.what in ("speed", "all"):
        results["speed"] = bench_speed(args)
    print(json.dumps({k: v for k, v in results.items() if k != "train"} | (
        {"train": {k: v for k, v in results["train"].items() if k != "history"}} if "train" in results else {}), indent=1))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
