"""Plane plus parallax: the background's motion beyond the camera's homography.

A camera that translates through a 3-D scene moves a static point off the plane its homography
describes, by its *parallax*: a displacement along the line through the point and the epipole
(the image of the camera's path), of a size set by the point's depth. Near rocks, a ground band,
posts: all of it is background, and no homography explains it. An object moving in the world
leaves that line, or moves along it by another amount than the background around it.

The camera modelled translates across the view (the epipole at infinity: parallax along one
direction). :func:`fit_epipole` finds that direction from the vectors' residuals (what the
homography leaves) by RANSAC; :class:`CameraPath` asks that it hold steady over frames (an
object's motion gives a direction of its own each frame); :class:`ParallaxField` turns the
residuals along it into a per-pixel field of background displacement, ``(h, w, 2) float32``:
a parallax factor per cell, the median over cells (small objects leave it), remembered in the
scene's coordinates (a static point keeps its depth from frame to frame; an object that moves
along the parallax direction does not). Enough parallax is a share of the vectors' weight that
reaches across the frame along the camera's motion (a subject the camera follows over a plain
sky can carry that share alone, but it does not reach across), or a thin layer across the
frame: ahead of the plane (near ground), or lagging behind it, all by one share of its step,
frame after frame (a far layer, where the fit took a near band for the plane). Without enough
parallax (a still or rotating camera, a planar scene) it returns None and the homography alone
is the background's motion. A near layer that moves too far beyond the plane for the next
frame's read is remembered for a second read, or guessed where no field stands
(:mod:`bgsub.camera.near_layer`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Optional

import cv2
import numpy as np

from bgsub._util import FieldWarp, cell_index
from bgsub.camera.near_layer import NEAR_REACH, NearLayer, leading_layer, probed_layer
from bgsub.motion.global_motion import apply_homography
from bgsub.settings import check_settings, setting

#: A post's cells depart from the 5 x 5 median by more than this (px of parallax).
POST_GAP = 0.5
#: A farther layer's vectors move as one: their steps along the plane's, as shares of the plane's
#: step, lie within this much of each other (the 10th to the 90th percentile).
FAR_SPREAD = 0.4
#: After a guessed layer's read is refused (its vectors scatter: water, a crowd), the next
#: guess waits 1, 2, 4, ... frames, at most this many: a refused read changes nothing but costs
#: a read.
PROBE_WAIT = 8

__all__ = ["ParallaxConfig", "ParallaxField", "fit_epipole", "parallax_directions"]


@dataclass(frozen=True)
class ParallaxConfig:
    """Settings of the plane-plus-parallax background motion (:class:`ParallaxField`)."""

    parallax: float = setting(0.08, "take the background's motion as the homography plus a "
                                    "parallax field when vectors that depart from the "
                                    "homography by more than parallax_min px along one "
                                    "direction carry at least this share of the vectors' "
                                    "weight and reach across half the frame along the "
                                    "camera's motion (a camera translating through a 3-D "
                                    "scene, not a subject it follows; 0 = homography only)",
                              low=0, high=1)
    parallax_near: float = setting(0.01, "... or when those that depart towards a nearer "
                                         "layer (moving faster than the plane, in its "
                                         "direction) carry this share and reach across half "
                                         "the frame along the camera's motion: near ground "
                                         "(0 = off)",
                                   low=0, high=1)
    parallax_far: int = setting(6, "... or when those that lag behind the plane (a farther "
                                   "layer: the fit took a near band for the plane) carry "
                                   "parallax_near of the weight, reach across half the frame "
                                   "along its motion, move as one, and have done so on each "
                                   "of this many frames in a row (a subject the camera "
                                   "follows drifts back for a few frames; 0 = off)", low=0)
    parallax_frames: int = setting(3, "... over this many frames in a row, in one direction "
                                      "(within parallax_angle): a steady camera path", low=1)
    parallax_angle: float = setting(15.0, "the parallax directions of those frames lie "
                                          "within this many degrees of each other",
                                    above=0, high=90)
    parallax_rate: float = setting(0.2, "the depths the field remembers follow each frame's "
                                        "at this rate, where the last mask was background",
                                   low=0, high=1)
    parallax_edges: float = setting(0.5, "where the field's depths step by a pixel (an "
                                         "occlusion, which the cells' smooth field does not "
                                         "follow), the background score counts this much "
                                         "less and the motion evidence has no opinion",
                                    low=0, high=1)
    parallax_min: float = setting(0.75, "a vector's departure from the homography (px) that "
                                        "counts as parallax evidence", above=0)
    parallax_tolerance: float = setting(0.5, "a vector's departure is along the parallax "
                                             "direction when it leaves that line by less "
                                             "than this (px)", above=0)
    parallax_cell: int = setting(16, "the parallax field is the median of its cells (px) "
                                     "over 5 x 5 cells, which objects smaller than about two "
                                     "cells do not move", low=4, high=64)
    parallax_posts: float = setting(0.4, "a line of cells across the camera's path (a column, "
                                         "for a camera moving sideways) whose 5 x 1 median "
                                         "departs from the 5 x 5 one by more than POST_GAP px "
                                         "over at least this share of its cells is a post at "
                                         "another depth: those cells take this frame's 5 x 1 "
                                         "depths (0 = off)", low=0, high=1)
    parallax_keep: int = setting(10, "for this many frames after the last parallax field, "
                                     "the camera fit keeps its plane (parallax_hold)", low=0)
    parallax_hold: float = setting(0.7, "... the fit keeps the last frame's plane when that "
                                        "plane's vectors are at least this share of the best "
                                        "fit's inliers: the layers of a 3-D scene would "
                                        "otherwise take turns as the camera's (0 = off)",
                                   low=0, high=1)
    parallax_layer: float = setting(3.0, "a near layer (ahead of the plane, across half the "
                                         "frame) that departs from the plane by at least "
                                         "this many px is read a second time, pre-warped by "
                                         "its motion, for parallax_keep frames after the "
                                         "field that showed it: the finest level alone, "
                                         "pre-warped by the plane, reads it wrong near the "
                                         "edge of the model's 4 px range (0 = off)", low=0)
    parallax_layers: int = setting(6, "where the field stands, the background model is also "
                                      "warped by the plane alone and by the field with each "
                                      "cell's depth the least and the greatest of its 5 x 5 "
                                      "neighbours', and each block of this many px a side "
                                      "(outside the last mask) takes the warp that explains "
                                      "the frame best: the cells' field is smooth across an "
                                      "occlusion, the scene is not (0 = the field alone)",
                                   low=0)
    parallax_probe: float = setting(0.15, "where the last frame had no parallax field and at "
                                          "least this share of the vectors scatter off the fit "
                                          "by over 1 px, the frame is read a second time "
                                          "(their lines across the view too) pre-warped by "
                                          "twice the plane's motion, for near ground read "
                                          "wrong from the start (a plane moving at least half "
                                          "parallax_layer px a frame; 0 = off)",
                                    low=0, high=1)

    def __post_init__(self) -> None:
        check_settings(self)


def parallax_directions(epipole: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``(N, 2) float64``: the direction of parallax at the ``(N, 2)`` points ``at`` for the
    homogeneous ``epipole`` (3,): towards it (unnormalised; constant for an epipole at
    infinity, a camera translating across the view)."""
    ex, ey, ew = epipole
    return np.stack([ex - ew * at[:, 0], ey - ew * at[:, 1]], 1)


def _across(residual: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """``(..., N)``: how far each residual leaves its parallax line (px): ``|r x u| / |u|``."""
    cross = residual[..., 0] * direction[..., 1] - residual[..., 1] * direction[..., 0]
    return np.abs(cross) / np.maximum(np.hypot(direction[..., 0], direction[..., 1]), 1e-9)


def fit_epipole(anchors: np.ndarray, residual: np.ndarray, weights: np.ndarray, *,
                tolerance: float, trials: int = 64,
                rng: Optional[np.random.Generator] = None) -> tuple:
    """RANSAC for the epipole at infinity (a camera translating across the view) of the
    ``(N, 2)`` residuals at ``anchors`` (where the homography puts each point), weighted
    ``(N,)``: each residual proposes its own direction, the one that most weight leaves by less
    than ``tolerance`` px wins, refined as its inliers' principal direction. Returns
    ``(epipole (3,) float64 (dx, dy, 0), inliers (N,) bool)``, or ``(None, None)`` for fewer
    than two residuals."""
    n = len(anchors)
    if n < 2:
        return None, None
    rng = rng or np.random.default_rng(0)
    pick = rng.integers(0, n, min(trials, n))
    cand = residual[pick] / np.maximum(np.hypot(*residual[pick].T), 1e-12)[:, None]
    inl = _across(residual[None], np.broadcast_to(cand[:, None], (len(cand), n, 2))) < tolerance
    best = inl[int(np.argmax(inl @ weights))]
    r, w = residual[best], weights[best]
    _, vectors = np.linalg.eigh((r * w[:, None]).T @ r)  # the scatter's main axis
    d = vectors[:, -1]
    if (residual[best] @ d) @ w < 0:  # signed towards the inliers' parallax: frames agree
        d = -d
    inliers = _across(residual, np.broadcast_to(d, (n, 2))) < tolerance
    return np.array([d[0], d[1], 0.0]), inliers


#: A count of frames that is never within ``parallax_keep``: nothing seen yet.
_LONG_AGO = 1 << 30


class CameraPath:
    """Whether the parallax directions of the last frames describe one steady camera path:
    within ``degrees`` of each other over ``frames`` frames (an object's motion, or a fit's
    error, gives a direction of its own, a new one each frame)."""

    def __init__(self, *, frames: int, degrees: float) -> None:
        self.frames, self.cos = frames, float(np.cos(np.radians(degrees)))
        self.recent: list = []  # unit directions (2,) of the last epipoles, None for none

    def forget(self) -> None:
        """A frame without an epipole."""
        self.recent = (self.recent + [None])[-self.frames:]

    def aligned(self, epipole: np.ndarray) -> np.ndarray:
        """``epipole`` (3,), at infinity, signed as the last frame's: parallax keeps its sign
        when the homography takes another plane of the scene for the camera's motion."""
        last = next((d for d in reversed(self.recent) if d is not None), None)
        return -epipole if last is not None and epipole[:2] @ last < 0 else epipole

    def steady(self, epipole: np.ndarray) -> bool:
        """Take the frame's ``epipole`` (3,), at infinity; whether the path is steady with
        it."""
        self.recent = (self.recent + [epipole[:2] / np.hypot(*epipole[:2])])[-self.frames:]
        if len(self.recent) < self.frames or any(v is None for v in self.recent):
            return False
        dirs = np.array(self.recent)
        return bool((np.abs(dirs @ dirs.T) >= self.cos).all())


class ParallaxField:
    """The background's displacement beyond the homography, from a frame's motion vectors."""

    def __init__(self, config: ParallaxConfig) -> None:
        self.config = config
        self.rng = np.random.default_rng(0)
        self.path = CameraPath(frames=config.parallax_frames, degrees=config.parallax_angle)
        self.memory: Optional[tuple] = None  # (gamma (gh, gw) float32, known (gh, gw) uint8)
        self.epipole: Optional[np.ndarray] = None  # (3,) of the last field made
        self.edges: Optional[np.ndarray] = None  # (h, w) float32 of it: _depth_edges
        self.depths: Optional[np.ndarray] = None  # (gh, gw) float32: its cells' depths
        self.share = 0.0  # the share of the vectors' weight it explained, 0 without one
        self.since = _LONG_AGO  # frames since the last field (0: the last frame had one)
        self.layer: Optional[NearLayer] = None  # the last near layer seen ahead of the plane
        self.layer_since = _LONG_AGO  # frames since it was seen
        self.looked = 0  # frames looked at since the start (the last restart)
        self.far_run = 0  # frames in a row that showed a farther layer (_farther)
        self._probe_wait, self._probe_next = 0, 1  # frames to the next guess; the next wait

    def discount_edges(self, score: np.ndarray, violation: Optional[np.ndarray]) -> None:
        """At the last field's depth edges, lower the background ``score`` ((h, w) float32) by
        up to ``parallax_edges`` of itself and draw the ``violation`` map ((h, w) float32 in
        [0, 1], or None) towards 0.5 (no opinion), in place: across an occlusion the warp and
        the vectors both straddle two depths."""
        if self.edges is None:
            return
        score *= 1 - np.float32(self.config.parallax_edges) * self.edges
        if violation is not None:
            violation -= self.edges * (violation - np.float32(0.5))

    def neighbour_warps(self, matrix: np.ndarray, shape: tuple) -> list:
        """The other warps the background may follow beside the last field's, for a frame of
        ``shape`` (h, w) and the camera's ``matrix`` (3, 3): None (the plane alone), then
        :class:`~bgsub._util.FieldWarp` s with each cell's depth the least and the greatest
        of its 5 x 5 neighbours'. An occlusion's two sides each take one of them, where the
        field, a median, is between the two. Empty without a field or with
        ``parallax_layers=0``."""
        if self.depths is None or self.config.parallax_layers == 0:
            return []
        k = np.ones((5, 5), np.uint8)  # the reach of the cells' 5 x 5 median
        return [None] + [FieldWarp(matrix, self._field(near(self.depths, k), self.epipole, shape))
                         for near in (cv2.erode, cv2.dilate)]

    def restart(self) -> None:
        """Forget the scene's depths (a new shot)."""
        self.memory = None
        self.path.recent = []
        self.since = self.layer_since = _LONG_AGO
        self.layer = None
        self.looked = self.far_run = 0

    def standing(self) -> bool:
        """Whether a field was made within the last ``parallax_keep`` frames: a 3-D scene."""
        return self.since <= self.config.parallax_keep

    def estimate(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                 matrix: np.ndarray, shape: tuple, *,
                 foreground: Optional[np.ndarray] = None) -> Optional[np.ndarray]:
        """``(h, w, 2) float32`` in current-frame pixels: the static background's displacement
        beyond ``matrix``'s (3, 3) for a frame of ``shape`` (h, w), from the ``(N, 2)``
        ``points`` (previous frame) and ``disp`` with ``(N,)`` ``weights``; None when no
        parallax stands out (module docstring). ``foreground`` ((h, w) uint8, the last mask)
        keeps the depths the field remembers from learning an object's motion."""
        field = self._estimate(points, disp, weights, matrix, shape, foreground=foreground)
        self.looked += 1
        self.since = 0 if field is not None else self.since + 1
        layer = None if field is None else leading_layer(field, matrix,
                                                         least=self.config.parallax_min)
        self.layer_since = 0 if layer is not None else self.layer_since + 1
        self.layer = layer or self.layer
        return field

    def layer_to_read(self) -> Optional[NearLayer]:
        """The near layer the next frame is read for a second time
        (:mod:`~bgsub.camera.near_layer`): the last one seen, within ``parallax_keep`` frames,
        when it departs from the plane by at least ``parallax_layer`` px; else None."""
        c, layer = self.config, self.layer
        if (layer is None or c.parallax_layer == 0 or self.layer_since > c.parallax_keep
                or float(np.hypot(*layer.shift)) < c.parallax_layer):
            return None
        return layer

    def layer_to_probe(self, result: Any, shape: tuple) -> Optional[NearLayer]:
        """Where the last frame had no field, the near layer the frame's vectors suggest
        (:func:`~bgsub.camera.near_layer.probed_layer`) for a second read: ``result`` is the
        front end's :class:`~bgsub.motion.result.MotionResult` of a frame of ``shape``
        (h, w). None right after a frame with a field, before the field has had
        ``parallax_frames`` frames to stand (the depths it remembers start from the first
        ones), without a fit, or with ``parallax``, ``parallax_layer`` or ``parallax_probe``
        off. A field that stood a few frames ago does not hold the guess back: one too weak
        to show a layer to read again would leave the ground out of reach meanwhile."""
        c = self.config
        if self._probe_wait > 0:
            self._probe_wait -= 1
            return None
        if (self.since == 0 or self.looked < c.parallax_frames or not result.motion.ok
                or 0 in (c.parallax, c.parallax_layer, c.parallax_probe)):
            return None
        return probed_layer(result.points, result.disp, result.weights, result.motion.matrix,
                            shape, share=c.parallax_probe, least=c.parallax_layer / 2)

    def probe_taken(self, taken: bool) -> None:
        """Whether the second read of the last :meth:`layer_to_probe` layer was taken: after a
        refusal the next guess waits (:data:`PROBE_WAIT`)."""
        if taken:
            self._probe_next = 1
        else:
            self._probe_wait = self._probe_next
            self._probe_next = min(2 * self._probe_next, PROBE_WAIT)

    def _estimate(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                  matrix: np.ndarray, shape: tuple, *,
                  foreground: Optional[np.ndarray]) -> Optional[np.ndarray]:
        self.epipole = self.edges = self.depths = None
        self.share = 0.0
        self._carry(matrix)
        if self.config.parallax == 0 or len(points) < 8:
            self.path.forget()
            return None
        v = _Residuals(points, disp, weights, matrix, self.config.parallax_min)
        if not self._near_enough(v, v.big):
            # (a frame with parallax enough without a farther layer neither counts nor breaks)
            self.far_run = self.far_run + 1 if self._farther(v, v.big) else 0
        e, along = self._direction(v)
        if e is None:
            return None
        # Static: what the homography explains, and what departs from it along the direction.
        static = v.ok & ~v.big
        static[np.flatnonzero(v.big)[along]] = True
        u = parallax_directions(e, v.anchors[static])
        gamma = (v.res[static] * u).sum(1) / np.maximum((u * u).sum(1), 1e-12)
        # Where each point is now: the field is read at the current frame's pixels.
        grid = self._gamma_grid(v.now[static], gamma, v.weights[static], shape)
        cells = cv2.medianBlur(grid, 5)
        posts, own = _posts(grid, cells, e, share=self.config.parallax_posts)
        depths = self._remember(cells, foreground)
        if posts is not None:
            depths = np.where(posts, own, depths).astype(np.float32)
        field = self._field(depths, e, shape)
        # The field must explain what the homography does not, once smoothed: objects, which
        # the cells' median leaves out, do not count.
        left = np.hypot(*(v.res - _read(field, v.now)).T) <= self.config.parallax_min
        if not self._enough(v, v.big & left):
            return None
        self.epipole, self.share, self.depths = e, v.share(v.big & left), depths
        self.edges = _depth_edges(depths, shape, self.config.parallax_cell)
        return field

    def _enough(self, v: "_Residuals", which: np.ndarray,
                among: Optional[np.ndarray] = None) -> bool:
        """Whether the vectors ``which`` (N,) bool (with ``among``, (M,) bool, those of them)
        are parallax enough, reaching across ``NEAR_REACH`` of the frame along the plane's
        motion: ``parallax`` of the weight, or ``parallax_near`` in the vectors that move
        ahead of the plane, or in those that lag behind it as a farther layer
        (:meth:`_farther`) that has stood for ``parallax_far`` frames. Near ground, ahead of
        the plane, may be a thin band of a flat scene; an object that the camera follows lags
        behind the plane, and one that overtakes it is compact."""
        c = self.config
        return (self._near_enough(v, which, among)
                or 0 < c.parallax_far <= self.far_run and self._farther(v, which, among))

    def _near_enough(self, v: "_Residuals", which: np.ndarray,
                     among: Optional[np.ndarray] = None) -> bool:
        """:meth:`_enough` without the farther layer: the share, reaching across
        ``NEAR_REACH`` of the frame along the plane's motion, or near ground. A subject the
        camera follows over a plain sky carries much of the weight (the sky's vectors carry
        little) and lags the plane in one steady direction, as a farther layer does, but it
        does not reach across the frame."""
        c = self.config
        if v.share(which, among) >= c.parallax and v.reach(which, among) >= NEAR_REACH:
            return True
        near = v.nearer[which] if among is None else v.nearer[which] & among
        return (c.parallax_near > 0 and v.share(which, near) >= c.parallax_near
                and v.reach(which, near) >= NEAR_REACH)

    def _farther(self, v: "_Residuals", which: np.ndarray,
                 among: Optional[np.ndarray] = None) -> bool:
        """Whether the vectors of ``which`` (and ``among``, as in :meth:`_enough`) that lag
        behind the plane make a farther layer: ``parallax_near`` of the weight, reaching
        across ``NEAR_REACH`` of the frame along the plane's motion, their steps within
        :data:`FAR_SPREAD` of each other. When the fit takes a textured near band for the
        plane over a flat far layer, the far layer's towers lag behind it, all by one share
        of its step; water round a swan the camera follows lags by scattered amounts."""
        c = self.config
        if c.parallax_near == 0 or c.parallax_far == 0:
            return False
        far = v.farther[which] if among is None else v.farther[which] & among
        if v.share(which, far) < c.parallax_near or v.reach(which, far) < NEAR_REACH:
            return False
        lo, hi = np.percentile(v.steps(which, far), [10, 90])
        return float(hi - lo) <= FAR_SPREAD

    def _direction(self, v: "_Residuals") -> tuple:
        """``(epipole (3,), along (M,) bool over the big residuals)`` of a steady camera path,
        or ``(None, None)``: too little parallax, or a direction of this frame's alone."""
        if not self._enough(v, v.big):
            self.path.forget()
            return None, None
        e, along = fit_epipole(v.anchors[v.big], v.res[v.big], v.weights[v.big],
                               tolerance=self.config.parallax_tolerance, rng=self.rng)
        if e is None or not self._enough(v, v.big, along):
            self.path.forget()
            return None, None
        e = self.path.aligned(e)
        return (e, along) if self.path.steady(e) else (None, None)

    def _carry(self, matrix: np.ndarray) -> None:
        """Move the remembered depths (cells) into the current frame by the camera's
        ``matrix`` (3, 3, pixels): cells the previous frame did not see are unknown."""
        if self.memory is None:
            return
        cell = self.config.parallax_cell
        to_cells = np.diag([1.0 / cell, 1.0 / cell, 1.0])
        m = to_cells @ np.asarray(matrix, np.float64) @ np.linalg.inv(to_cells)
        gamma, known = self.memory
        size = gamma.shape[::-1]
        self.memory = (cv2.warpPerspective(gamma, m, size, flags=cv2.INTER_NEAREST),
                       cv2.warpPerspective(known, m, size, flags=cv2.INTER_NEAREST,
                                           borderMode=cv2.BORDER_CONSTANT, borderValue=0))

    def _remember(self, grid: np.ndarray, foreground: Optional[np.ndarray]) -> np.ndarray:
        """The depths of the frame's cells ``grid`` (gh, gw) float32 as remembered: a cell
        seen before keeps its depth, drawn towards the frame's at ``parallax_rate`` where the
        last mask (``foreground``) was background; a new cell takes the frame's. A static
        point keeps its depth over frames; an object moving along the parallax direction
        does not, and stays foreground."""
        c = self.config
        gamma, known = self.memory or (None, None)
        if (gamma is None or gamma.shape != grid.shape or not known.any()
                or np.ptp(gamma[known > 0]) < 0.5):
            # No depths remembered yet (a first frame, a camera that just began to move).
            self.memory = (grid.copy(), np.ones(grid.shape, np.uint8))
            return grid
        scale, offset = _relation(gamma, grid, known > 0)
        gamma = np.where(known > 0, gamma * scale + offset, grid).astype(np.float32)
        rate = np.full(grid.shape, c.parallax_rate, np.float32)
        if foreground is not None:
            # An object's cells learn slowly: a static band the model misread as an object
            # still comes right, an object crossing is gone before it is learnt.
            share = cv2.resize((foreground > 0).astype(np.float32), grid.shape[::-1],
                               interpolation=cv2.INTER_AREA)
            rate[share >= 0.25] *= np.float32(0.25)
        gamma += rate * (grid - gamma)
        self.memory = (gamma, np.ones(grid.shape, np.uint8))
        return gamma

    def _gamma_grid(self, at: np.ndarray, gamma: np.ndarray, wt: np.ndarray,
                    shape: tuple) -> np.ndarray:
        """``(gh, gw) float32``: the parallax factor per cell, a weighted mean, gaps filled from
        the neighbours."""
        cell = self.config.parallax_cell
        cells, (gh, gw) = cell_index(at, shape, cell)
        num = np.bincount(cells, wt * gamma, minlength=gh * gw).reshape(gh, gw)
        den = np.bincount(cells, wt, minlength=gh * gw).reshape(gh, gw)
        num, den = num.astype(np.float32), den.astype(np.float32)
        grid = np.where(den > 0, num / np.maximum(den, 1e-9), 0).astype(np.float32)
        wide_n = cv2.blur(num, (7, 7), borderType=cv2.BORDER_REPLICATE)
        wide_d = cv2.blur(den, (7, 7), borderType=cv2.BORDER_REPLICATE)
        fill = np.where(wide_d > 0, wide_n / np.maximum(wide_d, 1e-9), 0).astype(np.float32)
        return np.where(den > 0, grid, fill).astype(np.float32)

    def _field(self, grid: np.ndarray, e: np.ndarray, shape: tuple) -> np.ndarray:
        """``(h, w, 2) float32``: the cells' parallax factors ``grid`` (gh, gw) interpolated to
        the frame's pixels, times the direction of the epipole ``e`` (3,), at infinity."""
        h, w = int(shape[0]), int(shape[1])
        cell = self.config.parallax_cell
        gh, gw = grid.shape
        gamma = cv2.resize(grid, (gw * cell, gh * cell), interpolation=cv2.INTER_LINEAR)[:h, :w]
        return gamma[:, :, None] * e[:2].astype(np.float32)


class _Residuals:
    """A frame's vectors against the homography ``matrix`` (3, 3): ``anchors`` (N, 2), where
    it puts each of the ``points``; ``res`` (N, 2), what it leaves of the displacement
    ``disp``; ``now`` (N, 2), where each point is; ``ok`` (N,) bool, the usable ones; ``big``
    (N,) bool, those that depart by more than ``least`` px; ``nearer`` (N,) bool, those of them
    that move further than the plane in its own direction (a layer nearer than the plane);
    ``farther`` (N,) bool, those that lag behind it; ``path`` (2,), the plane's mean
    displacement."""

    def __init__(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                 matrix: np.ndarray, least: float) -> None:
        pts = np.asarray(points, np.float64)
        self.weights = np.asarray(weights, np.float64)
        self.anchors = apply_homography(matrix, pts)
        self.now = pts + np.asarray(disp, np.float64)
        self.res = self.now - self.anchors
        size = np.hypot(self.res[:, 0], self.res[:, 1])
        self.ok = (self.weights > 0) & np.isfinite(size)
        self.big = self.ok & (size > least)
        plane = self.anchors - pts
        self.nearer = self.big & ((self.res * plane).sum(1) > 0)
        self.farther = self.big & ((self.res * plane).sum(1) < 0)
        self.path = plane[self.ok].mean(0) if self.ok.any() else np.zeros(2)
        self.total = max(float(self.weights[self.ok].sum()), 1e-12)

    def share(self, which: np.ndarray, among: Optional[np.ndarray] = None) -> float:
        """The share of the usable vectors' weight that ``which`` (N,) bool carry (with
        ``among``, (M,) bool over ``which``'s vectors, those of them)."""
        w = self.weights[which] if among is None else self.weights[which][among]
        return float(w.sum()) / self.total

    def steps(self, which: np.ndarray, among: Optional[np.ndarray] = None) -> np.ndarray:
        """``(K,) float64``: how far the vectors ``which`` (as in :meth:`share`) move along
        ``path``, as shares of it (1: with the plane); ones when the plane does not move."""
        res = self.res[which] if among is None else self.res[which][among]
        length = float(np.hypot(*self.path))
        if length == 0.0:
            return np.ones(len(res))
        return 1.0 + (res @ (self.path / length)) / length

    def reach(self, which: np.ndarray, among: Optional[np.ndarray] = None) -> float:
        """How far the vectors ``which`` (as in :meth:`share`) reach along ``path``, as a share
        of how far the usable vectors reach: 0 when the plane does not move."""
        length = float(np.hypot(*self.path))
        if length == 0.0:
            return 0.0
        at = self.now[which] if among is None else self.now[which][among]
        along, every = at @ (self.path / length), self.now[self.ok] @ (self.path / length)
        if not len(along):
            return 0.0
        return float(np.ptp(along)) / max(float(np.ptp(every)), 1e-12)


def _posts(grid: np.ndarray, cells: np.ndarray, epipole: np.ndarray, *,
           share: float) -> tuple:
    """``(posts (gh, gw) bool, depths (gh, gw) float32)`` or ``(None, None)``: the cells of
    the lines across the camera's path (columns for a camera moving sideways, along the
    ``epipole`` (3,) at infinity) where the median of 5 cells along the line departs from the
    5 x 5 median ``cells`` by more than ``POST_GAP`` over at least ``share`` of the line, and
    that median. A post 13-28 px wide is lost in the 5 x 5 median of 16 px cells, and it moves
    against the plane, so it slides off depths remembered in the plane's coordinates: its
    cells take this frame's depths along the line."""
    if share == 0:
        return None, None
    sideways = abs(float(epipole[0])) >= abs(float(epipole[1]))
    flip = (lambda a: a) if sideways else np.transpose
    g, c = flip(grid), flip(cells)
    padded = np.pad(g, ((2, 2), (0, 0)), mode="edge")
    own = np.median(np.stack([padded[i:i + g.shape[0]] for i in range(5)]), axis=0)
    departs = np.abs(own - c) > POST_GAP
    posts = departs & (departs.mean(axis=0) >= share)[None, :]
    if not posts.any():
        return None, None
    return flip(posts), flip(own).astype(np.float32)


def _depth_edges(depths: np.ndarray, shape: tuple, cell: int) -> np.ndarray:
    """``(h, w) float32`` in [0, 1]: where the cells' parallax factors ``depths`` (gh, gw) step
    by a pixel or more within a cell's reach (1 = a full pixel: an occlusion between depths,
    which the cells' smooth field does not follow)."""
    k = np.ones((3, 3), np.uint8)
    step = cv2.dilate(depths, k) - cv2.erode(depths, k)
    gh, gw = depths.shape
    up = cv2.resize(np.clip(step, 0, 1), (gw * cell, gh * cell), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(up[:int(shape[0]), :int(shape[1])])


def _relation(memory: np.ndarray, grid: np.ndarray, known: np.ndarray, *,
              trials: int = 64) -> tuple:
    """``(scale, offset)``: the frame's parallax ``grid`` as ``scale * memory + offset`` over
    the ``known`` cells, the line through two cells (of depths at least half a pixel apart)
    that most cells follow within 0.3 px (objects do not). Parallax grows with the camera's
    speed (the scale), and is measured from whichever plane the homography took (the
    offset); ``(1, 0)`` when too few cells tell."""
    x, y = memory[known].astype(np.float64), grid[known].astype(np.float64)
    if len(x) < 8:
        return 1.0, 0.0
    rng = np.random.default_rng(len(x))
    i, j = rng.integers(0, len(x), trials), rng.integers(0, len(x), trials)
    apart = np.abs(x[i] - x[j]) >= 0.5
    if not apart.any():
        return 1.0, 0.0
    i, j = i[apart], j[apart]
    scale = (y[i] - y[j]) / (x[i] - x[j])
    offset = y[i] - scale * x[i]
    follow = np.abs(scale[:, None] * x[None] + offset[:, None] - y[None]) < 0.3
    best = int(np.argmax(follow.sum(1)))
    return float(np.clip(scale[best], 0.25, 4.0)), float(offset[best])


def _read(field: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``(N, 2)``: the ``(h, w, 2)`` ``field`` at the nearest pixels to the ``(N, 2)`` points
    ``at`` (clipped to the frame)."""
    h, w = field.shape[:2]
    x = np.clip(np.rint(at[:, 0]), 0, w - 1).astype(np.intp)
    y = np.clip(np.rint(at[:, 1]), 0, h - 1).astype(np.intp)
    return field[y, x]


def without_parallax(result: Any, field: Optional[np.ndarray]) -> Any:
    """``result`` (a :class:`~bgsub.motion.result.MotionResult`) with the background's parallax
    ``field`` ((h, w, 2) float32, or None: ``result`` itself) taken off each vector where it
    lands, so what remains departs from the homography only where the scene is not static."""
    if field is None or len(result.points) == 0:
        return result
    moved = _read(field, result.points + result.disp)
    return replace(result, disp=(result.disp - moved).astype(np.float32))
