"""Benchmark of the classical engines (mog2, knn, framediff): CDnet F per scene category, speed,
and the real CDnet 2014 cameraJitter/traffic sequence.

Run from the repository root::

    OMP_NUM_THREADS=1 python benchmarks/classical.py --seeds 0 1 2 --out /tmp/bgsub-classical

What it does:

1. Renders the synthetic scenes (``bgsub.samples.generate_scene``, the same writer as
   ``bgsub samples DIR --seed S``, default scene parameters) for every category and seed into
   ``--out`` (outside the repository).
2. Runs each engine with its default parameters over each scene's ``input/`` JPEG frames and
   scores the masks with :func:`bgsub.evaluation.cdnet.evaluate_sequence` (temporal ROI; label 170 is
   ignored). Per-category F is the mean over seeds (CDnet averaging). A second, diagnostic
   scoring leaves the first ``--warmup`` frames out, to separate start-up effects (objects
   already in view in frame 1 are learnt as background) from the camera's motion.
3. Speed: frames per second of ``apply()`` alone at 320x240 (frames decoded into memory first),
   on a fresh engine per run, median of ``--repeats`` runs, with OpenCV's default thread count
   and with ``cv2.setNumThreads(1)``.
4. Real data (skipped when ``../shared/data`` is absent): every frame of
   ``CDnet2014_cameraJitter_traffic`` goes through the engine (frames 1-899 are warm-up);
   frames 900-1570 (temporalROI.txt) are scored, labels 85/170 ignored, the malformed ROI.bmp
   ignored (``ignore_roi_bmp``).

Prints Markdown tables; ``--json FILE`` also saves every number.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.engines import create_engine
from bgsub.evaluation.cdnet import DatasetResult, SequenceResult, evaluate_sequence
from bgsub.samples import CATEGORIES, SceneSpec, generate_scene
from bgsub.io.sources import open_source

ENGINES = ("mog2", "knn", "framediff")
REAL_TRAFFIC = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / \
    "CDnet2014_cameraJitter_traffic"


def masks_of(engine_name: str, source_path: Path) -> Iterator[Tuple[int, np.ndarray]]:
    """Run a fresh engine over a sequence; yield ``(frame_number, mask)`` (1-based numbers)."""
    engine = create_engine(engine_name)
    with open_source(str(source_path)) as source:
        for index, frame in source:
            yield index + 1, engine.apply(frame)


def score_scenes(scenes: Sequence[Path], *,
                 warmup_first: int) -> Dict[str, Dict[str, DatasetResult]]:
    """Engine name -> {"roi": scored over the temporal ROI, "warm": scored from frame
    ``warmup_first`` on} per-scene and per-category results."""
    results: Dict[str, Dict[str, DatasetResult]] = {}
    for name in ENGINES:
        roi: List[SequenceResult] = []
        warm: List[SequenceResult] = []
        for scene in scenes:
            masks = dict(masks_of(name, scene))  # 100 small masks: kept to score twice
            roi.append(evaluate_sequence(masks, scene))
            warm.append(evaluate_sequence(masks, scene, first_frame=warmup_first))
        results[name] = {"roi": DatasetResult.from_sequences(roi),
                         "warm": DatasetResult.from_sequences(warm)}
    return results


def time_apply(name: str, frames: Sequence[np.ndarray], repeats: int) -> float:
    """Median frames per second of ``apply()`` over ``frames`` (fresh engine per run)."""
    rates = []
    for _ in range(repeats):
        engine = create_engine(name)
        engine.apply(frames[0])  # untimed: allocations of the first frame
        start = time.perf_counter()
        for frame in frames[1:]:
            engine.apply(frame)
        rates.append((len(frames) - 1) / (time.perf_counter() - start))
    return statistics.median(rates)


def machine() -> Dict[str, Any]:
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        lscpu = "\n".join(lscpu.splitlines()[:10])
    except OSError:
        lscpu = "n/a"
    return {"date": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
            "python": platform.python_version(), "numpy": np.__version__,
            "opencv": cv2.__version__, "opencv_threads": cv2.getNumThreads(), "lscpu": lscpu}


def fmt(value: Any) -> str:
    return "n/a" if value is None or (isinstance(value, float) and np.isnan(value)) \
        else f"{value:.3f}"


def print_scene_scores(scenes: Sequence[Path], args: argparse.Namespace,
                       report: Dict[str, Any]) -> None:
    """Score every engine on every scene; print per-category and per-scene tables."""
    results = score_scenes(scenes, warmup_first=args.warmup + 1)
    report["scenes"] = {name: {k: r.to_dict() for k, r in by.items()}
                        for name, by in results.items()}
    roi = (scenes[0] / "temporalROI.txt").read_text().split()
    for key, title in (("roi", f"scored over the temporal ROI (frames {roi[0]}-{roi[1]})"),
                       ("warm", f"scored from frame {args.warmup + 1} on (diagnostic: the "
                                f"first {args.warmup} frames as warm-up)")):
        print(f"## CDnet F-measure per category, {title}; mean over seeds "
              + ", ".join(map(str, args.seeds)) + "; default parameters\n")
        print("| category | " + " | ".join(ENGINES) + " |")
        print("|---|" + "---|" * len(ENGINES))
        for category in CATEGORIES:
            cells = []
            for name in ENGINES:
                cat = next(c for c in results[name][key].categories if c.name == category)
                cells.append(fmt(cat.metrics.f_measure))
            print(f"| {category} | " + " | ".join(cells) + " |")
        print(f"\n### per scene (F / recall / precision), {title}\n")
        print("| scene | " + " | ".join(ENGINES) + " |")
        print("|---|" + "---|" * len(ENGINES))
        for i, scene in enumerate(scenes):
            cells = []
            for name in ENGINES:
                m = results[name][key].sequences[i].metrics
                cells.append(f"{fmt(m.f_measure)} / {fmt(m.recall)} / {fmt(m.precision)}")
            print(f"| {scene.name} | " + " | ".join(cells) + " |")
        print()


def speed(scene: Path, args: argparse.Namespace, report: Dict[str, Any]) -> None:
    """Frames per second of apply() at 320x240, decoding excluded."""
    with open_source(str(scene)) as source:
        frames = [frame for _, frame in source]
    report["fps"] = {}
    default_threads = cv2.getNumThreads()
    for threads in (default_threads, 1):
        cv2.setNumThreads(threads)
        report["fps"][threads] = {name: time_apply(name, frames, args.repeats)
                                  for name in ENGINES}
    cv2.setNumThreads(default_threads)
    print(f"## Speed: apply() only, 320x240 BGR, {len(frames) - 1} frames, median of "
          f"{args.repeats} runs\n")
    print("| OpenCV threads | " + " | ".join(ENGINES) + " |")
    print("|---|" + "---|" * len(ENGINES))
    for threads, rates in report["fps"].items():
        print(f"| {threads} | " + " | ".join(f"{rates[n]:.0f} fps" for n in ENGINES) + " |")
    print(f"\nload average (1, 5, 15 min) after timing: {os.getloadavg()}")


def real(report: Dict[str, Any]) -> None:
    """The real CDnet 2014 cameraJitter/traffic sequence."""
    print("\n## CDnet 2014 cameraJitter/traffic (frames 900-1570 scored, 1-899 warm-up; "
          "85/170 ignored, ROI.bmp ignored)\n")
    print("| engine | F | recall | precision | specificity | PWC |")
    print("|---|---|---|---|---|---|")
    report["traffic"] = {}
    for name in ENGINES:
        r = evaluate_sequence(masks_of(name, REAL_TRAFFIC), REAL_TRAFFIC,
                              ignore_roi_bmp=True)
        report["traffic"][name] = r.to_dict()
        m = r.metrics
        print(f"| {name} | {fmt(m.f_measure)} | {fmt(m.recall)} | {fmt(m.precision)} | "
              f"{fmt(m.specificity)} | {fmt(m.pwc)} |")


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("/tmp/bgsub-classical"),
                        help="where the scenes are rendered (default: /tmp/bgsub-classical)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--repeats", type=int, default=5, help="timing runs (median)")
    parser.add_argument("--warmup", type=int, default=50,
                        help="frames left out of the diagnostic second scoring (default: 50)")
    parser.add_argument("--json", type=Path, default=None, help="also save all numbers here")
    parser.add_argument("--skip-scenes", action="store_true",
                        help="no scoring of the synthetic scenes (speed and real data only)")
    parser.add_argument("--skip-real", action="store_true", help="no real-data run")
    args = parser.parse_args(argv)

    report: Dict[str, Any] = {"machine": machine(), "seeds": args.seeds}
    print(f"# machine\n```\n{report['machine']['lscpu']}\n```\n{report['machine']['date']}, "
          f"OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), numpy {np.__version__}, "
          f"load average {os.getloadavg()}\n")

    # 1-2. Synthetic scenes.
    scenes = []
    for category in CATEGORIES:
        for seed in args.seeds:
            spec = SceneSpec(category, seed=seed)
            folder = args.out / spec.name
            scenes.append(folder if folder.is_dir() else
                          generate_scene(spec, args.out, overwrite=False))
    if not args.skip_scenes:
        print_scene_scores(scenes, args, report)
    speed(scenes[0], args, report)
    if not args.skip_real and REAL_TRAFFIC.is_dir():
        real(report)
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
