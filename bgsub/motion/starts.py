"""Where the coarsest pyramid level starts reading: the best of a few candidate motions.

Candidates are the prior (a steady pan continues), no motion (a shaking camera reverses) and,
when neither explains the level, a grid of shifts of about the model's range (a shake beyond
it). All candidates of a batch are read in one batched inference; each is refined by the motion
fitted to its readout, and the best refined one is kept: the one most of the level's patches
agree with, or (``start_tolerance``) the one under which most textured pixels keep their gray
value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, List, Optional

import cv2
import numpy as np

from bgsub.motion.global_motion import corner_distances, is_identity
from bgsub.motion.patches import (PatchGrids, patch_motion, patches_at, reading_from,
                                  textured_pixels)
from bgsub.motion.pyramid import scale_homography, warp_back

__all__ = ["Start", "StartSearch", "choose_start", "corner_shift", "photometric_agreement"]


def corner_shift(h_a: np.ndarray, h_b: np.ndarray, shape: tuple) -> float:
    """How far apart two motions put an image's corners: the largest distance (pixels) over
    the four corners of an image of ``shape`` ``(H, W, ...)``, for ``(3, 3)`` homographies in
    its pixels. The corners bound the difference anywhere inside for affine motions (and
    nearly so for the mild homographies between frames)."""
    return float(np.max(corner_distances(h_a, h_b, width=shape[1], height=shape[0])))


def photometric_agreement(g1: np.ndarray, g2: np.ndarray, matrix: np.ndarray, *,
                          tolerance: float, textured: Optional[np.ndarray] = None) -> float:
    """Fraction of ``g1``'s textured pixels whose gray value ``g2`` repeats, to within
    ``tolerance``, at the place ``matrix`` maps them to.

    Parameters
    ----------
    g1, g2 : (H, W) float32 gray in [0, 1]
    matrix : (3, 3) float64
        Motion from ``g1`` to ``g2`` in these images' pixels.
    tolerance : float
        Largest gray-value difference that agrees.
    textured : (H, W) bool, optional
        :func:`~bgsub.motion.patches.textured_pixels` of ``g1``, when already computed.

    Returns
    -------
    float
        In [0, 1]; pixels mapped outside ``g2`` count as disagreeing, so a motion that leaves
        most of the frame is not preferred for the little it explains.
    """
    if textured is None:
        textured = textured_pixels(g1)
    n = int(np.count_nonzero(textured))
    if n == 0:
        return 0.0
    h, w = g1.shape
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    # -1 marks pixels mapped outside g2 (gray values are >= 0): they never agree.
    warped = cv2.warpPerspective(g2, np.asarray(matrix, np.float64), (w, h), flags=flags,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
    agree = np.abs(warped - g1) <= np.float32(tolerance)
    return float(np.count_nonzero(agree & textured)) / n


@dataclass(frozen=True)
class Start:
    """A refined candidate start.

    Attributes
    ----------
    motion : (3, 3) float64
        Full-resolution motion.
    support : float
        Fraction of the level's read patches that agree with it (0 when none does).
    score : float
        What chose it: ``support``, or the :func:`photometric_agreement` under it (-1 when no
        candidate's fit succeeded).
    shift : float
        How far the refinement moved it (:func:`corner_shift`, the level's pixels; inf when no
        fit succeeded).
    """

    motion: np.ndarray
    support: float = 0.0
    score: float = -1.0
    shift: float = np.inf


@dataclass(frozen=True)
class StartSearch:
    """The coarsest level and how its start is searched.

    Attributes
    ----------
    g1, g2 : (H, W) float32
        The two frames' coarsest level.
    level : int
        Its index (pixels ``0.5**level`` of full resolution).
    grids : PatchGrids
        The first frame's cut patches.
    stride : int
        Patch grid step at that level.
    model
        The patch-motion model.
    max_disp : int
        Its displacement range.
    fit_model : str
        The motion model each candidate's readout is fitted with (``start_model``).
    threshold : float
        The RANSAC threshold of that fit (the level's pixels).
    tolerance : float
        ``start_tolerance``: above 0, candidates are scored photometrically.
    """

    g1: np.ndarray
    g2: np.ndarray
    level: int
    grids: PatchGrids
    stride: int
    model: Any
    max_disp: int
    fit_model: str
    threshold: float
    tolerance: float

    @property
    def factor(self) -> float:
        """Level pixels per full-resolution pixel."""
        return 0.5**self.level

    def best(self, candidates: List[np.ndarray], fallback: np.ndarray) -> Start:
        """The best of full-resolution ``(3, 3)`` ``candidates`` after refinement, all of them
        read in one batched inference; ``Start(fallback)`` when no candidate's fit succeeds."""
        grid = self.grids.grid(self.g1, self.stride)
        best, k = Start(fallback), len(grid.pick)
        if k == 0:
            return best
        scaled = [scale_homography(c, self.factor) for c in candidates]
        d, c, flat = self._read(grid, scaled)
        textured = self.grids.textured(self.g1) if self.tolerance > 0 else None
        for i, h in enumerate(scaled):
            sl = slice(i * k, (i + 1) * k)
            # Readings at the edge of the range are a larger motion clipped: a wrong start
            # reads them everywhere, consistently, so they must not count as support for it.
            reading = reading_from(grid, h, d[sl], c[sl], flat[sl], max_disp=self.max_disp)
            fitted = reading.fit(self.fit_model, threshold=self.threshold, shape=self.g1.shape)
            if not fitted.ok:
                continue
            support = fitted.n_inliers / k
            score = support if textured is None else photometric_agreement(
                self.g1, self.g2, fitted.matrix, tolerance=self.tolerance, textured=textured)
            if score > best.score:
                best = Start(scale_homography(fitted.matrix, 1.0 / self.factor), support, score,
                             corner_shift(h, fitted.matrix, self.g1.shape))
        return best

    def _read(self, grid: Any, scaled: List[np.ndarray]) -> tuple:
        """The model's ``(disp, confidence, flat)`` of ``grid``'s patches against the second
        frame pre-warped by each of ``scaled`` (level pixels), concatenated in that order."""
        centres, p = grid.centres[grid.pick], int(self.model.patch_size)
        ys = [patches_at(warp_back(self.g2, h) if not is_identity(h) else self.g2, centres, p)
              for h in scaled]
        xf = grid.features
        if xf is not None:
            xf = xf.take(np.tile(np.arange(len(grid.pick)), len(scaled)))
        return patch_motion(self.model, np.tile(grid.x, (len(scaled), 1)), np.concatenate(ys),
                            max_disp=self.max_disp, x_features=xf)


def choose_start(search: StartSearch, prior: Optional[np.ndarray], *, steps: int,
                 search_below: float) -> Start:
    """The coarsest level's start: the best of no motion and ``prior`` (full-resolution
    ``(3, 3)``), or of the grid of ``steps`` shifts of about the model's range on each side
    when fewer than ``search_below`` of the patches agree with either, or with no prior to go
    by (a first frame of a fast pan whose tracked subject reads as "no motion" would otherwise
    set a wrong prior for the next)."""
    step = max(1.0, search.max_disp - 1.0) / search.factor
    h_est = np.eye(3) if prior is None else np.asarray(prior, np.float64)
    basic = [np.eye(3)] + ([h_est] if prior is not None else [])
    grid = [np.array([[1.0, 0, i * step], [0, 1.0, j * step], [0, 0, 1]])
            for i in range(-steps, steps + 1) for j in range(-steps, steps + 1) if i or j]
    if grid and (search_below >= 1.0 or prior is None):
        basic, grid = basic + grid, []  # read anyway: one batched readout of all of them
    start = search.best(basic, h_est)
    if grid and start.support < search_below:
        shaken = search.best(grid, start.motion)
        if shaken.score > start.score:
            start = Start(shaken.motion, start.support, shaken.score, shaken.shift)
    return start
