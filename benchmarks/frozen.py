"""A frozen background model (``learning_rate=0``) on generated scenes: F and false alarms.

The scenes are written as ``bgsub samples`` writes them (JPEG frames, PNG ground truth) and
read back as a user's run reads them. Each engine learns the first ``--learn`` frames at its own
rate, then runs with ``learning_rate=0`` to the end. Scored with CDnet rules on every frame but
the first (ground truth 255 positive, 0 negative). Also prints the share of the frame wrongly
called foreground at a few frames, which shows a drifting or blurring model, and, for the
moving-camera engines
(``grbm``, ``compensated``), the model's misalignment there: how far (px, at the farthest frame
corner) the affine map that registers the frame to the engine's background image
(``get_background_image()``; OpenCV's ECC over the pixels the ground truth calls background)
moves the frame.

Usage (a minute; the long pans a few)::

    OMP_NUM_THREADS=1 python benchmarks/frozen.py
    python benchmarks/frozen.py --categories pan --methods grbm --param grbm:still_below=0
    python benchmarks/frozen.py --categories pan pan-zoom-rotate --seed 0 1 2 --frames 100 \
        --methods grbm compensated
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import cv2
import numpy as np

from bgsub.engines import create_engine, parse_params
from bgsub.samples import SceneSpec, generate_scene
from bgsub.io.sources import open_source


def misalignment(background: np.ndarray, frame: np.ndarray, valid: np.ndarray) -> float:
    """Largest corner displacement (px) of the affine map registering ``frame`` to
    ``background`` (ECC over ``valid``); NaN when ECC does not converge."""
    h, w = valid.shape
    valid = valid.astype(np.uint8)
    valid[:8], valid[-8:], valid[:, :8], valid[:, -8:] = 0, 0, 0, 0
    gray = [cv2.cvtColor(im, cv2.COLOR_BGR2GRAY).astype(np.float32) for im in (frame, background)]
    warp = np.eye(2, 3, dtype=np.float32)
    try:
        _, warp = cv2.findTransformECC(gray[0], gray[1], warp, cv2.MOTION_AFFINE,
                                       (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-7),
                                       valid, 5)
    except cv2.error:
        return float("nan")
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], np.float64)
    return float(np.hypot(*(corners @ warp.T.astype(np.float64) - corners[:, :2]).T).max())


def run(method: str, params: dict, scene: Path, learn: int, at: tuple) -> str:
    engine = create_engine(method, **params)
    moving = hasattr(engine, "last_motion")
    tp = fp = fn = 0
    false, apart = {}, {}
    with open_source(scene) as source:
        frames = list(source)
    for k, image in frames:
        gt = cv2.imread(str(scene / "groundtruth" / f"gt{k + 1:06d}.png"), cv2.IMREAD_GRAYSCALE)
        mask = engine.apply(image, learning_rate=-1 if k < learn else 0) > 127
        if k in at:
            false[k] = np.count_nonzero(mask & (gt == 0)) / mask.size
            if moving:
                apart[k] = misalignment(engine.get_background_image(), image, gt == 0)
        if k == 0:
            continue
        tp += int(np.count_nonzero(mask & (gt == 255)))
        fp += int(np.count_nonzero(mask & (gt == 0)))
        fn += int(np.count_nonzero(~mask & (gt == 255)))
    f = 2 * tp / max(2 * tp + fp + fn, 1)
    shares = " / ".join(f"{false[k]:.3f}" for k in at if k in false)
    line = f"F={f:.3f}  false foreground at frames {'/'.join(map(str, at))}: {shares}"
    if apart:
        line += "  misalignment (px): " + " / ".join(f"{apart[k]:.2f}" for k in at if k in apart)
    return line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--methods", nargs="+", default=["grbm", "compensated", "mog2"])
    parser.add_argument("--categories", nargs="+", default=["static", "pan"])
    parser.add_argument("--seed", type=int, nargs="+", default=[0])
    parser.add_argument("--frames", type=int, default=80)
    parser.add_argument("--learn", type=int, default=24, help="frames learnt before freezing")
    parser.add_argument("--param", action="append", default=[], metavar="METHOD:KEY=VALUE")
    args = parser.parse_args()
    params = {m: [] for m in args.methods}
    for item in args.param:
        method, _, pair = item.partition(":")
        params[method].append(pair)
    at = tuple(sorted({k for k in (30, 50, args.frames - 1) if k < args.frames}))
    warnings.simplefilter("ignore")  # (lossy-codec and similar notes do not apply here)
    with tempfile.TemporaryDirectory() as tmp:
        for category in args.categories:
            for seed in args.seed:
                spec = SceneSpec(category, seed=seed, n_frames=args.frames)
                scene = generate_scene(spec, tmp)
                name = f"{category}_s{seed}"
                for method in args.methods:
                    typed = parse_params(method, params[method])
                    print(f"{name:10s} {method:12s} {run(method, typed, scene, args.learn, at)}",
                          flush=True)


if __name__ == "__main__":
    main()
