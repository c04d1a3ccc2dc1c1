"""CDnet F-measure of bgsub engines on the development data, by halves (the tuning protocol).

Every default of the foreground stage is chosen on half **A** of each family / category and
confirmed on half **B**; both halves are reported (docs/BENCHMARKS.md). A sequence's half is its
position in its family, sorted by name: even positions (1st, 3rd, ...) are A, odd ones B, so a
family of one (CDnet traffic) is in A only.

Sets:

* ``generated``: ``../shared/data/generated/CATEGORY/CATEGORY_NN`` (CDnet layout, temporal ROI);
  F per sequence from the summed counts, category mean of its sequences, overall mean of the five
  categories;
* ``real``: ``../shared/data/real/NAME`` (family = the name's prefix), every frame in the
  temporal ROI but the first; overall = mean of the families;
* ``samples``: ``bgsub samples`` scenes rendered in memory (every moving category, seeds 0-2,
  60 frames), F per category over the seeds, mean over the categories (half A = seed 0 and 2,
  B = seed 1); ``static-samples``: the same for the static category alone. ``--seeds 3 4 5``
  renders scenes of the same generator that no default was chosen on.

Usage (minutes; two sequences at a time with ``--jobs 2``)::

    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set generated --half A -m grbm
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set real --half all -m grbm -p flow_boost=1
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set generated --oracle-camera -m grbm
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set generated --degrade jpeg=25
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set real --preset fast --json real_fast.json

The data folder is ``../shared/data`` beside the repository (``BGSUB_DATA`` overrides it).
``--oracle-camera`` (generated only) replaces the camera-motion fit by the generator's true
motion (``meta.json``), which separates the foreground stage's errors from the motion's.
``--degrade KIND=VALUE`` (folder sets) feeds the engine degraded copies of the frames, the same
on every run, to see how the figures carry over to poorer footage: ``noise=SIGMA`` (Gaussian,
gray levels, seeded by the frame number), ``jpeg=QUALITY`` (re-encoded), ``soft=F`` (shrunk by
F and enlarged back: softer detail), ``step=N`` (every N-th frame: N times the motion),
``orbit=V`` (an added camera motion of V px a frame around a circle of ``ORBIT_RADIUS`` px,
frames and ground truth cropped by the radius: slow pans of every direction), ``gain=A``
(brightness times ``1 + A sin(2 pi k / GAIN_PERIOD)``: a camera's auto exposure).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import re
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Tuple

import cv2
import numpy as np

from bgsub.engines import create_engine, get_engine_spec, parse_params
from bgsub.engines.lookback import primed
from bgsub.evaluation.cdnet import count_frame
from bgsub.motion.global_motion import GlobalMotion, apply_homography

DATA = Path(os.environ.get("BGSUB_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))
REAL_FAMILIES = {"CDnet2014": "CDnet", "BMS26": "BMS-26", "UCSD": "UCSD", "DAVIS2016": "DAVIS"}
SAMPLE_SEEDS = (0, 1, 2)


def sequences(which: str, half: str, seeds: Tuple[int, ...] = SAMPLE_SEEDS,
              root: Optional[Path] = None,
              numbers: Optional[Tuple[int, int]] = None) -> List[Tuple[str, str]]:
    """``[(family, path or 'category:seed')]`` of a set's half (``A``, ``B`` or ``all``);
    ``seeds``: the sample sets' scenes; ``root``: the generated set's folder (default
    ``DATA/generated``); ``numbers``: (first, last), only its scenes numbered so (``_NN``)."""
    groups: Dict[str, List[str]] = defaultdict(list)
    if which == "generated":
        for seq in sorted((root or DATA / "generated").glob("*/*_[0-9]*")):
            number = re.search(r"_(\d+)$", seq.name)
            if numbers is None or (number and numbers[0] <= int(number[1]) <= numbers[1]):
                groups[seq.parent.name].append(str(seq))
    elif which == "real":
        for seq in sorted((DATA / "real").iterdir()):
            if (seq / "input").is_dir():
                groups[REAL_FAMILIES[seq.name.split("_")[0]]].append(str(seq))
    else:
        from bgsub.samples import CATEGORIES
        for cat in CATEGORIES:
            if (cat == "static") == (which == "static-samples"):
                groups[cat] = [f"{cat}:{seed}" for seed in seeds]
    out = []
    for family, members in groups.items():
        for k, member in enumerate(members):
            if half == "all" or (k % 2 == 0) == (half == "A"):
                out.append((family, member))
    return out


class OracleFit:
    """A stand-in for the engine's camera fit that answers the true motion of the frame being
    processed (``matrix``, set before each ``apply``); inliers within 1.5 px of it."""

    def __init__(self) -> None:
        self.matrix = np.eye(3)

    def __call__(self, points, disp, weights, shape) -> GlobalMotion:
        pts = np.asarray(points, np.float64)
        err = np.hypot(*(apply_homography(self.matrix, pts) - (pts + disp)).T)
        return GlobalMotion(self.matrix.copy(), (err < 1.5) & (np.asarray(weights) > 0), True)


def true_motions(seq: Path) -> Optional[List[np.ndarray]]:
    """Frame k-1 -> k camera motion (3, 3) for every frame k (identity for k = 0)."""
    meta = seq / "meta.json"
    if not meta.is_file():
        return None
    affine = json.loads(meta.read_text())["world_to_view_affine"]
    full = [np.vstack([np.reshape(a, (2, 3)), [0.0, 0.0, 1.0]]) for a in affine]
    return [np.eye(3)] + [full[k] @ np.linalg.inv(full[k - 1]) for k in range(1, len(full))]


def temporal_roi(seq: Path, n_frames: int) -> Tuple[int, int]:
    roi = seq / "temporalROI.txt"
    first, last = ((int(v) for v in roi.read_text().split()[:2]) if roi.is_file()
                   else (1, n_frames))
    return max(first, 2), last  # the first frame has no history for any method


DEGRADATIONS = ("noise", "jpeg", "soft", "step", "orbit", "gain")
#: Frames per cycle of ``--degrade gain=A``.
GAIN_PERIOD = 40
#: Radius (px) of the circle ``--degrade orbit=V`` moves the view around.
ORBIT_RADIUS = 16


def parse_degrade(text: str) -> Tuple[str, float]:
    """``KIND=VALUE`` of ``--degrade`` as ``(kind, value)``, checked."""
    kind, _, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if kind not in DEGRADATIONS or not number > 0:
        raise argparse.ArgumentTypeError(
            f"--degrade wants KIND=VALUE with KIND one of {', '.join(DEGRADATIONS)} and a "
            f"positive VALUE, not {text!r}")
    if kind == "soft" and number >= 1:
        raise argparse.ArgumentTypeError("--degrade soft=F shrinks by F: below 1")
    return kind, number


def parse_range(text: str) -> Tuple[int, int]:
    """``FIRST-LAST`` of ``--scenes`` as ``(first, last)``, checked."""
    first, _, last = text.partition("-")
    if not (first.isdigit() and last.isdigit() and int(first) <= int(last)):
        raise argparse.ArgumentTypeError(
            f"--scenes wants FIRST-LAST (such as 13-24), not {text!r}")
    return int(first), int(last)


def degrade(image: np.ndarray, kind: str, value: float, k: int) -> np.ndarray:
    """Frame ``k`` (BGR uint8) degraded by ``kind`` (:data:`DEGRADATIONS`; ``step`` drops
    frames instead and leaves each frame as it is)."""
    if kind == "noise":
        noise = np.random.default_rng(k).normal(0.0, value, image.shape)
        return np.clip(image + noise, 0, 255).astype(np.uint8)
    if kind == "jpeg":
        _, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(value)])
        return cv2.imdecode(data, cv2.IMREAD_COLOR)
    if kind == "soft":
        h, w = image.shape[:2]
        small = cv2.resize(image, (max(1, round(w * value)), max(1, round(h * value))),
                           interpolation=cv2.INTER_AREA)
        return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    if kind == "orbit":
        return _orbit(image, value, k, cv2.INTER_LINEAR)
    if kind == "gain":
        return cv2.convertScaleAbs(image, alpha=1.0 + value * np.sin(2 * np.pi * k / GAIN_PERIOD))
    return image


def _orbit(image: np.ndarray, speed: float, k: int, interpolation: int) -> np.ndarray:
    """Frame ``k``'s view moved to angle ``k * speed / ORBIT_RADIUS`` on the circle, cropped by
    the radius on every side (``interpolation`` nearest for ground truth)."""
    r = ORBIT_RADIUS
    angle = k * speed / r
    h, w = image.shape[:2]
    shift = np.float32([[1, 0, r + r * np.cos(angle)], [0, 1, r + r * np.sin(angle)]])
    return cv2.warpAffine(image, shift, (w - 2 * r, h - 2 * r),
                          flags=interpolation | cv2.WARP_INVERSE_MAP)


def run_sequence(task: tuple) -> dict:
    """Counts and CPU seconds of one engine over one sequence (or one rendered sample)."""
    method, params, family, member, oracle, degraded = task
    t0 = time.process_time()
    engine = create_engine(method, **params)
    if member.count(":") == 1 and not Path(member).exists():
        counts, n = _run_sample(engine, member)
    else:
        counts, n = _run_folder(engine, Path(member), oracle, degraded)
    return dict(family=family, name=Path(member).name, counts=counts, frames=n,
                cpu=time.process_time() - t0)


def _run_folder(engine, seq: Path, oracle: bool,
                degraded: Optional[Tuple[str, float]] = None) -> Tuple[list, int]:
    frames = sorted((seq / "input").glob("in*.jpg")) + sorted((seq / "input").glob("in*.png"))
    first, last = temporal_roi(seq, len(frames))
    motions = true_motions(seq) if oracle else None
    fit = None
    if motions is not None:
        fit = engine.fit = OracleFit()
    counts = np.zeros(4, np.int64)
    read = _read_folder(frames, last, degraded)
    for k, image in (read if fit is not None else primed([engine], read)):
        if fit is not None:
            fit.matrix = motions[k - 1]
        mask = engine.apply(image)
        if k < first:
            continue
        gt = cv2.imread(str(seq / "groundtruth" / f"gt{k:06d}.png"), cv2.IMREAD_GRAYSCALE)
        if gt is not None and degraded is not None and degraded[0] == "orbit":
            gt = _orbit(gt, degraded[1], k, cv2.INTER_NEAREST)
        if gt is not None:
            c = count_frame(mask, gt)
            counts += (c.tp, c.fp, c.fn, c.tn)
    return counts.tolist(), len(frames)


def _read_folder(frames: List[Path], last: int,
                 degraded: Optional[Tuple[str, float]]) -> Iterator[Tuple[int, np.ndarray]]:
    """``(k, image)`` of a sequence's frames up to ``last``, degraded as asked."""
    for path in frames:
        k = int(path.stem[2:])
        if k > last:
            break
        image = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if degraded is not None:
            kind, value = degraded
            if kind == "step" and (k - 1) % int(value):
                continue
            image = degrade(image, kind, value, k)
        yield k, image


def _run_sample(engine, member: str) -> Tuple[list, int]:
    from bgsub.samples import SceneSpec, render_frames

    cat, seed = member.split(":")
    counts = np.zeros(4, np.int64)
    n = 0
    scene = list(render_frames(SceneSpec(cat, seed=int(seed), n_frames=60)))
    for k, img in primed([engine], ((k, f[0]) for k, f in enumerate(scene))):
        gt = scene[k][1]
        mask = engine.apply(img)
        n += 1
        if k:
            c = count_frame(mask, gt)
            counts += (c.tp, c.fp, c.fn, c.tn)
    return counts.tolist(), n


def f_measure(tp: int, fp: int, fn: int, tn: int = 0) -> float:
    return 2 * tp / max(2 * tp + fp + fn, 1)


def summarise(which: str, results: List[dict]) -> dict:
    """Per-sequence, per-family and overall F (CDnet averaging; samples sum over seeds)."""
    by_family: Dict[str, List[dict]] = defaultdict(list)
    for r in results:
        by_family[r["family"]].append(r)
    families = {}
    for family, rows in by_family.items():
        if which in ("samples", "static-samples"):
            families[family] = f_measure(*np.sum([r["counts"] for r in rows], axis=0))
        else:
            families[family] = float(np.mean([f_measure(*r["counts"]) for r in rows]))
    seqs = {r["name"]: f_measure(*r["counts"]) for r in results}
    frames = sum(r["frames"] for r in results)
    return dict(mean=float(np.mean(list(families.values()))), families=families,
                sequences=seqs, cpu_ms_per_frame=1000 * sum(r["cpu"] for r in results) / frames)


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--set", choices=("generated", "real", "samples", "static-samples"),
                    default="generated")
    ap.add_argument("--half", choices=("A", "B", "all"), default="all")
    ap.add_argument("--root", type=Path,
                    help="--set generated: another folder of CATEGORY/CATEGORY_NN scenes, such "
                         "as those ../shared/tools/scenes/gen_scenes2.py writes")
    ap.add_argument("-m", "--method", default="grbm")
    ap.add_argument("-p", "--param", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--preset", default=None, help="the engine's named preset (-p over it); "
                    "--json records it for `bgsub bench --presets --accuracy FILE`")
    ap.add_argument("--oracle-camera", action="store_true")
    ap.add_argument("--degrade", type=parse_degrade, metavar="KIND=VALUE",
                    help="degraded frames: noise=SIGMA, jpeg=QUALITY, soft=F, step=N, "
                         "orbit=V or gain=A")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--match", default="", help="only sequences whose path contains this")
    ap.add_argument("--scenes", type=parse_range, metavar="FIRST-LAST",
                    help="--set generated: only the scenes numbered so (_13 to _24: 13-24), "
                         "such as those no default was chosen on")
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(SAMPLE_SEEDS),
                    help="the sample sets' scene seeds (default 0 1 2, the tuned ones; "
                         "others are scenes no default was chosen on)")
    args = ap.parse_args(argv)
    params = {**get_engine_spec(args.method).preset_values(args.preset),
              **parse_params(args.method, args.param)}
    if args.degrade and (args.set not in ("generated", "real") or
                         (args.oracle_camera and args.degrade[0] in ("step", "orbit"))):
        ap.error("--degrade needs --set generated or real (and step or orbit no --oracle-camera)")
    todo = [(args.method, params, fam, m, args.oracle_camera, args.degrade)
            for fam, m in sequences(args.set, args.half, tuple(args.seeds), args.root,
                                    args.scenes)
            if args.match in m]
    with multiprocessing.get_context("fork").Pool(args.jobs) as pool:
        results = pool.map(run_sequence, todo, chunksize=1)
    summary = summarise(args.set, results)
    preset = [f"--preset {args.preset}"] if args.preset else []
    label = " ".join([args.method, f"{args.set}/{args.half}", *preset, *args.param])
    if args.degrade:
        label += " degraded {}={:g}".format(*args.degrade)
    fams = "  ".join(f"{k} {v:.3f}" for k, v in summary["families"].items())
    print(f"{label}: mean {summary['mean']:.3f} | {fams} | "
          f"{summary['cpu_ms_per_frame']:.1f} ms/frame CPU")
    print("   " + " ".join(f"{k}={v:.3f}" for k, v in summary["sequences"].items()))
    if args.json:
        Path(args.json).write_text(json.dumps(dict(args=vars(args), **summary), indent=1,
                                                   default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
