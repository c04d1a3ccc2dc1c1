"""A near layer of a 3-D scene that moves beyond the reduced read's reach.

The front end reads a frame on its finest level alone, pre-warped by the camera's last motion
(``prior_levels``). A camera translating past near ground moves that ground several pixels a
frame faster than the plane the fit follows. Beyond the gated RBM's range (it is trained on
shifts up to 4 px) the finest level reads the ground wrong, near the plane's motion, and the
parallax field that explained it dies: the ground becomes foreground.

:func:`leading_layer` finds, in a frame's parallax field, the layer that moves ahead of the plane
across the frame (near ground, not an object: see ``NEAR_REACH``). For the next frames the
engine reads the frame a second time, pre-warped by the plane followed by that layer's shift,
and inside the layer's region keeps the second read's vectors where they read with more
confidence (:meth:`~bgsub.engines.frontend.MotionFrontEnd.read_layer`).

A layer read wrong from the start leaves no field to find it in: its vectors scatter off the
plane. :func:`probed_layer` then guesses, from those scattered vectors alone, a layer that moves
twice as fast as the plane, and the frame is read a second time for it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from bgsub.motion.global_motion import apply_homography

__all__ = ["NEAR_REACH", "NearLayer", "leading_layer", "probed_layer"]

#: Near ground reaches across the view along the camera's motion; an object that moves ahead
#: of the plane (overtaking the camera's motion) covers a compact part of it. A layer ahead of
#: the plane is near ground when it reaches across this share of the view.
NEAR_REACH = 0.5
#: A layer is looked for only when the field departs from the plane (by ``parallax_min``) over
#: more than this share of the frame.
LAYER_COVER = 0.05
#: The field is looked at every STEP px: it is smooth over its cells (``parallax_cell``).
STEP = 4
#: A vector off the fit by more than this many px is scattered (RANSAC's threshold is 1 px).
OFF_PX = 1.0
#: A guessed layer is taken only when the vectors its read takes move as one: their median
#: distance from their median under this many px (water or a crowd read again scatter still).
GUESS_SPREAD = 1.0


@dataclass(frozen=True)
class NearLayer:
    """A layer nearer than the camera's plane: its ``shift`` ((2,) float64 px a frame beyond
    the plane's motion) and its ``region`` ((h // STEP, w // STEP) bool, current-frame pixels
    every ``STEP``: where the field departs along the shift by at least half of it).
    ``spread``: how far (px, median) the vectors a second read takes for it may scatter about
    their median (a guess must move as one layer)."""

    shift: np.ndarray
    region: np.ndarray
    spread: float = float("inf")

    def prior(self, plane: np.ndarray) -> np.ndarray:
        """``(3, 3) float64``: the motion ``plane`` (3, 3) followed by the layer's shift."""
        ahead = np.eye(3)
        ahead[:2, 2] = self.shift
        return ahead @ np.asarray(plane, np.float64)

    def covers(self, points: np.ndarray) -> np.ndarray:
        """``(N,) bool``: which of the ``(N, 2)`` points (x, y) lie in the layer's region."""
        xy, inside = _cells(points, self.region.shape)
        out = np.zeros(len(xy), bool)
        out[inside] = self.region[xy[inside, 1], xy[inside, 0]]
        return out


def _cells(points: np.ndarray, grid: tuple) -> tuple:
    """``(xy (N, 2) intp, inside (N,) bool)``: the STEP x STEP cell (column, row) of each of the
    ``(N, 2)`` points (x, y), and whether it lies on the ``grid`` (rows, columns)."""
    xy = np.floor(np.asarray(points, np.float64) / STEP).astype(np.intp)
    inside = (xy[:, 0] >= 0) & (xy[:, 0] < grid[1]) & (xy[:, 1] >= 0) & (xy[:, 1] < grid[0])
    return xy, inside


def leading_layer(field: np.ndarray, matrix: np.ndarray, *,
                  least: float) -> Optional[NearLayer]:
    """The layer that departs most from the plane in a parallax ``field`` ((h, w, 2) float32),
    when it moves ahead of the camera's ``matrix`` ((3, 3): further in the plane's own
    direction, as nearer ground does) and reaches across ``NEAR_REACH`` of the view along it;
    None otherwise. Its shift is the field's median over the upper half of the departures
    beyond ``least`` px. A subject the camera follows departs the other way (it lags behind
    the plane), and one that overtakes the plane is compact."""
    field = field[STEP // 2::STEP, STEP // 2::STEP]
    size = np.hypot(field[..., 0], field[..., 1])
    big = size > least
    if np.count_nonzero(big) <= LAYER_COVER * size.size:
        return None
    top = size >= np.percentile(size[big], 50)
    shift = np.median(field[top], axis=0).astype(np.float64)
    region = field[..., 0] * shift[0] + field[..., 1] * shift[1] >= 0.5 * float(shift @ shift)
    # (the region's reach, not the upper half's: the field's depths vary along the ground)
    path = np.asarray(matrix, np.float64)[:2, 2]
    if float(shift @ path) <= 0 or _reach(region, path) < NEAR_REACH:
        return None
    return NearLayer(shift, region)


def _reach(where: np.ndarray, path: np.ndarray) -> float:
    """How far the pixels ``where`` ((h, w) bool) reach along ``path`` ((2,) px), as a share of
    the view's extent in that direction (the 5th to the 95th percentile of their positions)."""
    u = path / max(float(np.hypot(*path)), 1e-12)
    ys, xs = np.nonzero(where)
    along = xs * u[0] + ys * u[1]
    h, w = where.shape
    lo, hi = np.percentile(along, [5, 95])
    return float(hi - lo) / (abs(u[0]) * w + abs(u[1]) * h)


def probed_layer(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                 matrix: np.ndarray, shape: tuple, *, share: float,
                 least: float) -> Optional[NearLayer]:
    """A guess of a near layer where no parallax field shows one: the vectors that scatter off
    the fit ``matrix`` ((3, 3)) by over :data:`OFF_PX`, when they are at least ``share`` of the
    ``(N, 2)`` ``points`` / ``disp`` with ``(N,)`` ``weights`` > 0, taken as a layer that moves
    twice as fast as the plane (its shift is the plane's motion at the centre of the ``(h, w)``
    frame). None when fewer scatter, when they do not reach across ``NEAR_REACH`` of the view
    along that shift (an object is compact), or when the shift is under ``least`` px: a layer
    ahead of a slower plane stays within the read's reach. Its region is the cells of the scattered
    vectors' ``points``, and the lines along the shift that they reach across
    (:func:`_lines_across`).

    Nearer ground moves further in the plane's direction than the plane; twice the plane's
    motion halves the departure of ground that moves up to three times as fast, which the first
    read, pre-warped by the plane alone, can leave beyond the model's 4 px range: read wrong, and
    scattered. The layer's ``spread`` is :data:`GUESS_SPREAD`."""
    use = np.asarray(weights) > 0
    pts = np.asarray(points, np.float64)[use]
    off = np.hypot(*(np.asarray(disp, np.float64)[use] - apply_homography(matrix, pts)
                     + pts).T) > OFF_PX
    if not off.any() or np.count_nonzero(off) < share * len(off):
        return None
    h, w = shape[:2]
    centre = np.array([[w / 2.0, h / 2.0]])
    shift = (apply_homography(np.asarray(matrix, np.float64), centre) - centre)[0]
    if float(np.hypot(*shift)) < least:
        return None
    region = np.zeros((-(-h // STEP), -(-w // STEP)), bool)
    xy, inside = _cells(pts[off], region.shape)
    region[xy[inside, 1], xy[inside, 0]] = True
    if not region.any() or _reach(region, shift) < NEAR_REACH:
        return None
    return NearLayer(shift, region | _lines_across(region, shift), GUESS_SPREAD)


def _lines_across(cells: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """``(gh, gw) bool``: the lines of the grid along ``shift`` ((2,) px; rows for a sideways
    shift) whose ``cells`` ((gh, gw) bool) reach across ``NEAR_REACH`` of the line. Near
    ground is a band along the camera's path, and the first read scatters only part of it:
    where it is flat or repeats itself (a page of text), the ground reads the plane's motion
    and stays on the fit. An object is compact along its lines."""
    u = shift / max(float(np.hypot(*shift)), 1e-12)
    ys, xs = np.mgrid[0:cells.shape[0], 0:cells.shape[1]]
    line = np.rint(ys * u[0] - xs * u[1]).astype(np.intp).ravel()
    line -= line.min()
    along = (xs * u[0] + ys * u[1]).ravel()
    held = cells.ravel()
    return (_extent(line[held], along[held], line.max() + 1)
            >= NEAR_REACH * _extent(line, along, line.max() + 1))[line].reshape(cells.shape)


def _extent(line: np.ndarray, along: np.ndarray, lines: int) -> np.ndarray:
    """``(lines,) float64``: how far the points ``along`` ((N,) positions) of each of the
    ``lines`` reach (the greatest less the least; -inf for a line without a point)."""
    lo, hi = np.full(lines, np.inf), np.full(lines, -np.inf)
    np.minimum.at(lo, line, along)
    np.maximum.at(hi, line, along)
    return hi - lo
