"""The region of interest and a known camera motion on generated pans (the scenes of
``tests/engines/test_roi.py`` and ``tests/engines/test_known_motion.py``).

* **Region of interest**: the top 56 of 120 rows pan 5 px a frame; the bottom 64 rows are a
  static textured dashboard with a bright block moving over it. For each moving-camera engine,
  with and without ``roi`` (the top 56 rows): the median over 11 frames of the largest error
  (px) of the camera motion over a grid of the watched rows, and the foreground pixels outside
  the region.
* **Known camera motion**: a 5 px/frame pan with a textured object half the frame wide moving
  1 px a frame (enough vectors to pull a RANSAC fit). F over 13 frames (the first not scored)
  with the motion estimated, given exactly (``known_motion``), and given the wrong way.

Usage (a minute)::

    OMP_NUM_THREADS=1 python benchmarks/roi_known_motion.py
"""

from __future__ import annotations

import cv2
import numpy as np

from bgsub.engines import create_engine
from bgsub.motion.global_motion import apply_homography

H, W, PAN, TOP = 120, 160, 5, 56


def world(seed: int, h: int, w: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 4, w // 4, 3)).astype(np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def dashboard_scene(n: int = 12):
    big, dashboard = world(0, H, W + PAN * n + 8), world(1, H - TOP, W)
    for k in range(n):
        frame = big[:, PAN * (n - k):PAN * (n - k) + W].copy()
        frame[TOP:] = dashboard
        frame[TOP + 10:TOP + 22, 10 + 4 * k:22 + 4 * k] = 250
        frame[20:36, 60 + k:76 + k] = (30, 30, 220)
        yield frame


def object_scene(n: int = 14, width: int = 80):
    big, thing = world(0, H, W + PAN * n + 8), world(2, 90, width)
    for k in range(n):
        frame = big[:, PAN * (n - k):PAN * (n - k) + W].copy()
        truth = np.zeros((H, W), bool)
        frame[15:105, 10 + k:10 + k + width] = thing
        truth[15:105, 10 + k:10 + k + width] = True
        yield frame, truth


def roi_row(name: str, roi) -> str:
    engine = create_engine(name, **({} if roi is None else {"roi": roi}))
    ys, xs = np.mgrid[4:TOP:8, 4:W:8]
    grid = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    errors, outside = [], 0
    for k, frame in enumerate(dashboard_scene()):
        mask = engine.apply(frame)
        outside += int(np.count_nonzero(mask[TOP:]))
        if k:
            motion = engine.last_motion if engine.last_motion is not None else np.eye(3)
            errors.append(float(np.abs(apply_homography(motion, grid) - grid - [PAN, 0]).max()))
    return (f"| {name} | {'top rows' if roi is not None else 'none'} | "
            f"{np.median(errors):.2f} | {outside} |")


def f_measure(name: str, known) -> float:
    engine = create_engine(name, **({} if known is None else {"known_motion": known}))
    tp = fp = fn = 0
    for k, (frame, truth) in enumerate(object_scene()):
        mask = engine.apply(frame) > 0
        if k:
            tp += np.count_nonzero(mask & truth)
            fp += np.count_nonzero(mask & ~truth)
            fn += np.count_nonzero(~mask & truth)
    return 2 * tp / max(2 * tp + fp + fn, 1)


def main() -> None:
    roi = np.zeros((H, W), np.uint8)
    roi[:TOP] = 255
    print("| engine | roi | median camera-motion error in the watched rows (px) | "
          "foreground pixels outside |")
    print("|---|---|---|---|")
    for name in ("grbm", "compensated"):
        for region in (None, roi):
            print(roi_row(name, region))
    pan = np.repeat(np.eye(3)[None], 14, axis=0)
    pan[1:, 0, 2] = PAN
    wrong = pan.copy()
    wrong[1:, 0, 2] = -PAN
    print("\n| engine | F estimated | F known (exact) | F known (wrong way) |")
    print("|---|---|---|---|")
    for name in ("grbm", "compensated"):
        print(f"| {name} | {f_measure(name, None):.3f} | {f_measure(name, pan):.3f} | "
              f"{f_measure(name, wrong):.3f} |")


if __name__ == "__main__":
    main()
