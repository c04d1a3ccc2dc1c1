"""Follow scenes over a flat world: a camera that follows its subject through fog or over sky.

The follow category of ``../shared/tools/scenes/gen_scenes2.py`` has textured backgrounds: the
patches read the camera's motion there. This script writes the same scenes (other seeds: 100 and
on) with the world's photographs blurred by ``--blur`` px and their contrast cut to ``--flat`` of
itself, plus a faint vertical gradient, so that only the subject has texture enough for a patch.
Score them with ``accuracy.py`` (scenes 1-4 are the tuning half, 5-8 the confirming one)::

    python benchmarks/flat_follow.py --out ../scenes_flat                          # fog
    python benchmarks/flat_follow.py --out ../scenes_flat2 --flat 0.35 --blur 5    # haze
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set generated --root ../scenes_flat -m grbm

Generate them beside the repository, never in it.
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2
import numpy as np

SCENES = Path(__file__).resolve().parents[2] / "shared" / "tools" / "scenes"


def _flattened(world, flat: float, blur: float):
    """gen_scenes2's ``world`` with its panorama blurred, its contrast cut to ``flat``, and a
    gradient of 20 gray levels from top to bottom."""
    def flat_world(rng, cfg, cx, cy, theta=None, scale=None):
        pano, matrices, centres = world(rng, cfg, cx, cy, theta, scale)
        p = cv2.GaussianBlur(pano.astype(np.float32), (0, 0), blur)
        mean = p.mean((0, 1), keepdims=True)
        rows = np.linspace(-1, 1, p.shape[0], dtype=np.float32)[:, None, None]
        p = mean + flat * (p - mean) + 20 * rows
        return np.clip(p, 0, 255).astype(np.uint8), matrices, centres
    return flat_world


def _job(args: tuple) -> str:
    out, k, flat, blur = args
    sys.path.insert(0, str(SCENES))
    import gen_scenes2
    cv2.setNumThreads(1)
    # (a worker runs several jobs: flatten the generator's own world, once)
    original = gen_scenes2.__dict__.setdefault("original_world", gen_scenes2.world)
    gen_scenes2.world = _flattened(original, flat, blur)
    name = f"follow_{k + 1:02d}"
    gen_scenes2.generate_sequence(os.path.join(out, "follow", name), "dev", "follow", k + 100)
    return name


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="../scenes_flat", help="folder to write (its follow/)")
    parser.add_argument("--scenes", type=int, default=8, help="how many scenes")
    parser.add_argument("--flat", type=float, default=0.15, help="contrast kept (0-1)")
    parser.add_argument("--blur", type=float, default=12.0, help="blur sigma (px)")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    if not (SCENES / "gen_scenes2.py").is_file():
        print(f"flat_follow: error: the scene generator is not at {SCENES}", file=sys.stderr)
        return 2
    jobs = [(args.out, k, args.flat, args.blur) for k in range(args.scenes)]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for name in pool.map(_job, jobs):
            print(f"  {args.out}/follow/{name}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
