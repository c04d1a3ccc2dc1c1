"""Diagnostic (UCSD): the `grbm` pipeline with a warped sample-based background model.

SuBSENSE, the reference row that sets UCSD's bar, is built on a ViBe-style sample model: each
pixel keeps N past values and is background when at least ``min_matches`` of them lie within
``radius`` gray levels. This script swaps such a model (nearest-neighbour warped by the camera
motion, conservative random update with neighbour diffusion) in for `CompensatedBackground`
and runs `benchmarks/pipeline_real.py` with it, to measure whether the background model is what
limits UCSD (docs/BENCHMARKS.md, "Tried and rejected"). The engines' own sample model,
:class:`bgsub.background.sample.SampleBackground`, differs: it is never warped and is used
only while the camera is judged still.

Usage (minutes; one thread)::

    OMP_NUM_THREADS=1 python benchmarks/sample_model.py [--samples 20 --radius 20 --min-matches 2
        --subsample 16] -- --methods grbm [--sequences UCSD_birds ...]
"""

from __future__ import annotations

import argparse
import runpy
import sys
from pathlib import Path
from typing import Optional

import cv2
import numpy as np

import bgsub.engines.moving
from bgsub.background.compensated import BackgroundConfig as BackgroundParams
from bgsub._util import warp_image as _warp


class SampleBackground:
    """ViBe-style model with :class:`bgsub.background.compensated.CompensatedBackground`'s interface."""

    def __init__(self, params: Optional[BackgroundParams] = None, *, samples: int = 20,
                 radius: float = 20.0, min_matches: int = 2, subsample: int = 16,
                 seed: int = 0) -> None:
        self.params = self.config = params or BackgroundParams()
        self.n, self.radius, self.min_matches, self.subsample = samples, radius, min_matches, subsample
        self.rng = np.random.default_rng(seed)
        self.s: Optional[np.ndarray] = None  # (N, H, W, C) uint8
        self.age: Optional[np.ndarray] = None  # (H, W) float32

    @staticmethod
    def _f(frame: np.ndarray) -> np.ndarray:
        return frame[:, :, None] if frame.ndim == 2 else frame

    def _init(self, f: np.ndarray) -> np.ndarray:
        """N samples per pixel drawn from its 3x3 neighbourhood (ViBe's one-frame start)."""
        h, w, _ = f.shape
        pad = np.pad(f, ((1, 1), (1, 1), (0, 0)), mode="edge")
        ys, xs = np.mgrid[0:h, 0:w]
        s = np.stack([pad[ys + 1 + self.rng.integers(-1, 2, (h, w)),
                          xs + 1 + self.rng.integers(-1, 2, (h, w))] for _ in range(self.n)])
        s[0] = f
        return s

    @property
    def mean(self) -> Optional[np.ndarray]:
        return None if self.s is None else self.s.mean(0, dtype=np.float32)

    def reset(self, frame: np.ndarray) -> None:
        f = self._f(frame)
        self.s, self.age = self._init(f), np.zeros(f.shape[:2], np.float32)

    def warp(self, matrix: np.ndarray, *, sharp: bool = False) -> None:
        if self.s is None or np.allclose(matrix, np.eye(3), atol=1e-9):
            return
        n, h, w, c = self.s.shape
        flat = np.ascontiguousarray(self.s.transpose(1, 2, 0, 3).reshape(h, w, n * c))
        out = np.empty_like(flat)
        for k in range(0, n * c, 4):  # OpenCV warps up to 4 channels at once
            chunk = np.ascontiguousarray(flat[:, :, k:k + 4])
            out[:, :, k:k + 4] = _warp(chunk, matrix, (w, h), cv2.INTER_NEAREST,
                                       cv2.BORDER_REPLICATE).reshape(h, w, -1)
        self.s = np.ascontiguousarray(out.reshape(h, w, n, c).transpose(2, 0, 1, 3))
        self.age = _warp(self.age, matrix, (w, h), cv2.INTER_LINEAR, cv2.BORDER_CONSTANT)

    def score(self, frame: np.ndarray) -> np.ndarray:
        """(H, W) float32: the ``min_matches``-th smallest sample distance / ``radius``."""
        f = self._f(frame)
        if self.s is None:
            return np.zeros(f.shape[:2], np.float32)
        d = cv2.absdiff(self.s.reshape(self.n, -1),
                        np.ascontiguousarray(np.broadcast_to(f.reshape(1, -1), (self.n, f.size))))
        d = d.reshape(self.s.shape).max(axis=3)
        kth = np.partition(d, self.min_matches - 1, axis=0)[self.min_matches - 1]
        out = kth.astype(np.float32) / np.float32(self.radius)
        out[self.age < self.params.min_age] = self.params.young_score
        return out

    def update(self, frame: np.ndarray, fgmask: Optional[np.ndarray] = None,
               learning_rate: float = -1.0) -> None:
        f = self._f(frame)
        if learning_rate >= 1.0 or self.s is None:
            self.reset(frame)
            self.age[:] = 1.0
            return
        h, w = f.shape[:2]
        new = self.age < 1.0
        if new.any():
            self.s[:, new] = self._init(f)[:, new]
        if learning_rate != 0.0:
            p = 1.0 / self.subsample if learning_rate < 0 else learning_rate
            bg = (np.ones((h, w), bool) if fgmask is None or learning_rate >= 0
                  else ~np.asarray(fgmask, bool))
            ys, xs = np.nonzero(bg & (self.rng.random((h, w)) < p))
            self.s[self.rng.integers(0, self.n, ys.size), ys, xs] = f[ys, xs]
            ys, xs = np.nonzero(bg & (self.rng.random((h, w)) < p))  # neighbour diffusion
            ny = np.clip(ys + self.rng.integers(-1, 2, ys.size), 0, h - 1)
            nx = np.clip(xs + self.rng.integers(-1, 2, xs.size), 0, w - 1)
            self.s[self.rng.integers(0, self.n, ys.size), ny, nx] = f[ys, xs]
        self.age += 1.0
        np.minimum(self.age, np.float32(self.params.max_age), out=self.age)

    def background_image(self) -> Optional[np.ndarray]:
        if self.s is None:
            return None
        img = np.median(self.s, axis=0).astype(np.uint8)
        return img[:, :, 0] if img.shape[2] == 1 else img


def main() -> None:
    argv = sys.argv[1:]
    split = argv.index("--") if "--" in argv else len(argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=20)
    ap.add_argument("--radius", type=float, default=20.0)
    ap.add_argument("--min-matches", type=int, default=2)
    ap.add_argument("--subsample", type=int, default=16)
    a = ap.parse_args(argv[:split])
    kw = dict(samples=a.samples, radius=a.radius, min_matches=a.min_matches,
              subsample=a.subsample)
    bgsub.engines.moving.CompensatedBackground = lambda params=None: SampleBackground(params, **kw)
    script = Path(__file__).with_name("pipeline_real.py")
    sys.argv = [str(script)] + argv[split + 1:]
    runpy.run_path(str(script), run_name="__main__")


if __name__ == "__main__":
    main()
