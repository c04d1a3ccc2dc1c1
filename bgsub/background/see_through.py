"""A semi-transparent overlay, and the scene seen through it (:class:`SeeThrough`).

A watermark word burnt in at a third of full opacity is fixed in the frame, yet the scene
streams through it: each of its pixels is ``gain * scene + offset``, the gain and the offset its
own (the word's opacity and colour, its anti-aliased rim). Its patches' vectors read a mixture of
no motion and the camera's, so the overlay detector's test (vectors that read no motion) passes
it by, while the frames' running mean keeps its letters sharp; the moving camera's model drags
the letters over the scene, and they come out as foreground.

*Finding it.* Among the pieces that stay sharp in the running mean (on the frames where the
camera moved), a see-through letter is one

* whose edge holds still in the frame: there the last frame as it was explains the frame
  clearly better than the last frame moved by the camera (a scene's edge along the camera's path
  moves with the camera);
* with the scene streaming past on both sides: near its edge, few pixels are explained better
  by the last frame as it was (a subject the camera follows is opaque);
* whose cells' vectors read off the camera's motion (a mixture of it and none);
* taken by ``SEEN_FINDS`` looks (a moving object's path is taken for a few frames at most),
  and, as a whole piece, streamed through (the median of the two explanations' ratio). Where
  the scene shows through the piece (most of its pixels inside, off the edges, change from
  frame to frame), the ratio is read there: over a dark sky the letters' own edges, which hold
  still by construction, are most of a piece whose letters run together, and would outweigh
  it. The piece's rim (the scene around it) is left out, and a piece with nothing changing
  inside (a logo, a bar's edge) is judged whole.

The tests look at one frame in ``EVERY`` where the camera moved: a watermark stays for the whole
video, and footage without one pays a quarter of their cost.

*Seeing through it.* The scene passes under the overlay as it passes around it, so over the
frames a pixel under it has the temporal mean and spread of the pixels around it, mapped by its
gain and offset. An overlay is one colour laid over the scene at each pixel's own opacity (the
gain is one less the opacity, the offset the opacity times the colour): the ratio of the spreads
reads the colour where the scene varies enough, and the means read each pixel's opacity.
:meth:`SeeThrough.unveil` maps the frame's overlay pixels back to the scene, so that the motion,
the background model and the foreground decision see the scene, and the objects that pass under
the word, not the word.

*As it always looks.* Over a dark star field or a plain sky the scene under the word barely
varies, so the map reads some letters wrong; but there the frames repeat the word as it came,
frame after frame. A sample model of the frames as they came, never warped,
(:meth:`SeeThrough.remember`) says where: :meth:`SeeThrough.discount` lowers the background
score of the overlay's pixels that match it (an object passing under the word does not).
"""

from __future__ import annotations

from typing import Optional, Tuple

import cv2
import numpy as np

from bgsub.background.evidence import cell_index, cells_to_pixels
from bgsub.background.morphology import enclosed, kernel
from bgsub.background.sample import SampleBackground
from bgsub.motion.global_motion import apply_homography

__all__ = ["SeeThrough"]

#: Along a letter's edge, |frame - last frame moved by the camera| is at least this many times
#: |frame - last frame| (averaged over 5 x 5 of the sharp pixels).
FIXED = 1.5
#: Within AROUND px of such an edge, under OPAQUE of the pixels off the edges are explained
#: better by the last frame as it was: the scene streams past on both sides.
AROUND = 7
OPAQUE = 0.2
#: The running mean's edges: its gradient (Sobel, L1) over this; pixels within EDGE_PX (a
#: square's side) of them are the edges' own.
EDGE_GRADIENT = 20.0
EDGE_PX = 5
#: The cells' vectors read, on average, at least this many px off the camera's motion, each
#: capped at CAP_PX (an object's vectors must not outweigh the cell's others).
OFF_CAMERA = 0.3
CAP_PX = 2.0
#: The tests look at one frame in EVERY where the camera moved; their running means forget at
#: LOOK_RATE a frame (at most).
EVERY = 4
LOOK_RATE = 1.0 / 32
#: A pixel joins the overlay once this many looks took it ...
SEEN_FINDS = 2
#: ... and stays in it while the median |frame - moved last| / |frame - last| over its piece is
#: under this.
PIECE_STREAMS = 1.2
#: The frames' temporal mean and spread forget at this rate (at most).
STATS_RATE = 1.0 / 32
#: The scene shows through a piece when the median of |frame - last| (its running mean, gray
#: levels) over its inside (more than INSIDE px from its border: the rim that _letters grows,
#: and one more) off the edges is at least SHOWS, over LEAST_SHOWING pixels or more; its ratio
#: is then read over those pixels where it is.
SHOWS = 1.0
LEAST_SHOWING = 20
INSIDE = 4
#: The pixels around the overlay that stand for the scene under it lie within this many px.
AROUND_SCENE = 15
#: A pixel is mapped back where its gain (1 - its opacity) lies in this range: under it the
#: overlay is opaque there (or an object held still), above it there is no overlay to take out.
GAIN_RANGE = (0.4, 0.95)
#: Below this spread (variance, gray levels squared) around a pixel, no gain can be read.
MIN_VARIANCE = 1.0
#: Where the scene around a pixel is within this many gray levels of the overlay's colour, no
#: opacity can be read from the means.
MIN_CONTRAST = 8.0
#: Whether the scene shows through a pixel is judged from the spread within POOL px of it.
POOL = 2
#: An overlay pixel looks as it always does when 2 of its 20 samples of the frames as they came
#: lie within this many gray levels (the frames' noise is well inside; chosen on the tune half
#: of the overlay scenes: 6 / 8 / 10 / 14 / 20 a plateau, then lower).
AS_SEEN_RADIUS = 6.0


class SeeThrough:
    """Finds semi-transparent overlays in the frames where the camera moved (:meth:`observe`,
    :meth:`find`) and maps them back to the scene they show (:meth:`unveil`). ``cell``: the size
    (px) of the cells the vectors' residuals are averaged over.

    :attr:`region` is the ``(h, w) bool`` overlay found (None while there is none)."""

    def __init__(self, cell: int) -> None:
        self.cell = int(cell)
        self.region: Optional[np.ndarray] = None
        self._moved: Optional[np.ndarray] = None  # (h, w) float32: |frame - moved last|
        self._still: Optional[np.ndarray] = None  # (h, w) float32: |frame - last|
        self._off: Optional[np.ndarray] = None  # (gh, gw) float32: cells' px off the camera
        self._mean: Optional[np.ndarray] = None  # (h, w) float32: the frames' mean ...
        self._square: Optional[np.ndarray] = None  # ... and mean square
        self._frames = 0  # ... over this many frames
        self._looks = 0  # frames where the camera moved, seen by observe
        self._looked = False  # whether the last observe looked
        self._hits: Optional[np.ndarray] = None  # (h, w) float32: finds that took a pixel
        self._map: Optional[_SceneMap] = None
        self._as_seen = SampleBackground(radius=AS_SEEN_RADIUS)  # the frames as they came

    def observe(self, cur: np.ndarray, last: np.ndarray, matrix: np.ndarray,
                points: np.ndarray, disp: np.ndarray, weights: np.ndarray) -> None:
        """Fold in a frame where the camera moved (one in EVERY): ``cur`` and the ``last`` frame
        ((h, w) uint8, blurred), the camera's motion between them ``matrix`` (3, 3) and the
        front end's vectors (``points`` and ``disp`` (N, 2), ``weights`` (N,))."""
        self._looks += 1
        self._looked = (self._looks - 1) % EVERY == 0
        if not self._looked:
            return
        rate = max(EVERY / self._looks, EVERY * LOOK_RATE)  # (a look stands for EVERY frames)
        h, w = cur.shape
        moved = cv2.warpPerspective(last, matrix, (w, h), flags=cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_REPLICATE)
        now = (cv2.absdiff(cur, moved).astype(np.float32),
               cv2.absdiff(cur, last).astype(np.float32))
        if self._moved is None or self._moved.shape != cur.shape:
            self._moved, self._still = now
            self._off = None
        else:
            cv2.accumulateWeighted(now[0], self._moved, rate)
            cv2.accumulateWeighted(now[1], self._still, rate)
        self._observe_cells(matrix, points, disp, weights, cur.shape, rate)

    def take_in(self, gray: np.ndarray) -> None:
        """Fold a frame seen while the camera moved, ``gray`` ((h, w) uint8, as it came), into
        the temporal mean and spread that map the overlay back to the scene."""
        frame = gray.astype(np.float32)
        if self._mean is None or self._mean.shape != frame.shape:
            self._mean, self._square, self._frames = frame, frame * frame, 0
        self._frames += 1
        rate = max(1.0 / self._frames, STATS_RATE)
        cv2.accumulateWeighted(frame, self._mean, rate)
        cv2.accumulateWeighted(frame * frame, self._square, rate)

    def _observe_cells(self, matrix: np.ndarray, points: np.ndarray, disp: np.ndarray,
                       weights: np.ndarray, shape: tuple, rate: float) -> None:
        """Fold each cell's mean residual from the camera's motion into its running mean."""
        pts = np.asarray(points, np.float64)
        camera = apply_homography(np.asarray(matrix, np.float64), pts) - pts
        off = np.minimum(np.hypot(*(np.asarray(disp, np.float64) - camera).T), CAP_PX)
        cells, (gh, gw) = cell_index(pts, shape, self.cell)
        use = np.asarray(weights) > 0
        total = np.bincount(cells[use], off[use], minlength=gh * gw)
        count = np.bincount(cells[use], minlength=gh * gw)
        now = (total / np.maximum(count, 1)).reshape(gh, gw).astype(np.float32)
        if self._off is None:
            self._off = now
            return
        seen = (count > 0).reshape(gh, gw)
        self._off = np.where(seen, self._off + rate * (now - self._off), self._off)

    def find(self, sharp: np.ndarray, gradient: np.ndarray, *, least: int) -> None:
        """On the frames :meth:`observe` looked at: update :attr:`region` and the map back to
        the scene from the pieces of ``sharp`` ((h, w) bool: sharp in the frames' running mean,
        whose gradient is ``gradient``, (h, w) float32) that pass as see-through letters, in
        pieces of ``least`` pixels or more."""
        if not self._looked or self._moved is None or self._moved.shape != sharp.shape:
            return
        near_edge = cv2.dilate((gradient > EDGE_GRADIENT).view(np.uint8),
                               kernel(cv2.MORPH_RECT, EDGE_PX)) > 0
        letters = _letters(self._candidates(sharp, near_edge), least)
        if letters is not None:
            if self._hits is None:
                self._hits = np.zeros(sharp.shape, np.float32)
            self._hits[letters] += 1
            letters &= self._hits >= SEEN_FINDS
        if self.region is not None:
            letters = self.region if letters is None else letters | self.region
        self.region = (None if letters is None or not letters.any() else
                       self._streamed(letters, near_edge))
        self._map = None if self.region is None else _scene_map(self._mean, self._square,
                                                                 self.region)

    def _candidates(self, sharp: np.ndarray, near_edge: np.ndarray) -> np.ndarray:
        """``(h, w) bool``: the ``sharp`` pixels that pass the tests of a see-through letter's
        edge (see the module's docstring); ``near_edge``: the pixels within EDGE_PX of the
        running mean's edges, (h, w) bool."""
        s = sharp.astype(np.float32)
        fixed = cv2.blur(self._moved * s, (5, 5)) >= FIXED * cv2.blur(self._still * s, (5, 5))
        off_edges = (~near_edge).astype(np.float32)
        opaque = ((self._moved > self._still) & ~near_edge).astype(np.float32)
        window = (2 * AROUND + 1, 2 * AROUND + 1)
        around = cv2.blur(off_edges, window)
        share = cv2.blur(opaque, window) / np.maximum(around, np.float32(1e-3))
        found = sharp & fixed & (share < OPAQUE) & (around > 0.05)
        return found & (cells_to_pixels(self._off, sharp.shape, self.cell) >= OFF_CAMERA)

    def _streamed(self, pieces: np.ndarray, near_edge: np.ndarray) -> Optional[np.ndarray]:
        """The ``pieces`` ((h, w) bool) through which the scene streams, each judged as a
        piece (a subject the camera follows, opaque, is not) where it shows the scene
        (:func:`_judged`; ``near_edge``: (h, w) bool, see :meth:`find`); None for none."""
        n, labels, stats, _ = cv2.connectedComponentsWithStats(pieces.view(np.uint8),
                                                               connectivity=8)
        ratio = self._moved / np.maximum(self._still, np.float32(1e-3))
        keep = np.zeros(n, bool)
        for i in range(1, n):
            x, y, w, h = stats[i, :4]
            box = np.s_[y:y + h, x:x + w]
            judged = _judged(labels[box] == i, near_edge[box], self._still[box])
            keep[i] = float(np.median(ratio[box][judged])) < PIECE_STREAMS
        return keep[labels] if keep.any() else None

    def discount(self, score: np.ndarray, gray: np.ndarray, *,
                 also: Optional[np.ndarray] = None) -> None:
        """Lower, in place, the ``(h, w) float32`` background ``score`` of the overlay's pixels
        (and of the ``also`` pixels, (h, w) bool, if given) where the frame ``gray`` ((h, w)
        uint8, as it came) looks as the frames did there (the samples' score, when under 1);
        then :meth:`remember` the frame."""
        model = self._as_seen
        region = self.region
        if also is not None:
            region = also if region is None else region | also
        if region is not None and model.s is not None and model.s.shape[2:] == gray.shape:
            x, y, w, h = cv2.boundingRect(region.view(np.uint8))
            box = np.s_[y:y + h, x:x + w]
            seen = model.score_box(gray, box)
            lower = region[box] & (seen <= 1.0) & (seen < score[box])
            score[box][lower] = seen[lower]
        self.remember(gray)

    def remember(self, gray: np.ndarray) -> None:
        """Fold the frame ``gray`` ((h, w) uint8, as it came) into the samples of the frames
        as they came (each pixel renews one with probability 1/16)."""
        model = self._as_seen
        if model.s is None or model.s.shape[2:] != gray.shape:
            model.reset(gray)
        else:
            model.update(gray)

    def unveil(self, work: np.ndarray, gray: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """``(work, gray)`` (a working-size frame (h, w[, 3]) and its gray image, uint8) with
        the overlay's pixels mapped back to the scene (copies); as they are without one."""
        if self._map is None or self._map.shape != gray.shape[:2]:
            return work, gray
        return self._map(work), self._map(gray)


class _SceneMap:
    """Per pixel of a box of the frame, ``(image - offset) / gain``: the overlay mapped back to
    the scene (``gain`` and ``offset`` (bh, bw) float32, 1 and 0 off the overlay)."""

    def __init__(self, shape: tuple, box: Tuple[slice, slice], gain: np.ndarray,
                 offset: np.ndarray) -> None:
        self.shape, self.box, self.gain, self.offset = shape, box, gain, offset

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """``image`` ((h, w[, 3]) uint8) mapped back to the scene in the box; a copy."""
        g, o = (self.gain, self.offset) if image.ndim == 2 else (self.gain[..., None],
                                                                 self.offset[..., None])
        out = image.copy()
        out[self.box] = np.clip((image[self.box].astype(np.float32) - o) / g, 0, 255
                                ).astype(np.uint8)
        return out


def _scene_map(mean: np.ndarray, square: np.ndarray, region: np.ndarray) -> Optional[_SceneMap]:
    """The map of the ``region`` ((h, w) bool) back to the scene, from the frames' temporal
    ``mean`` and mean ``square`` ((h, w) float32) there and at the pixels around it; None where
    no pixel's opacity can be read.

    An overlay pixel shows ``(1 - a) scene + a colour``: the overlay's one colour at the pixel's
    own opacity ``a`` (a letter's inside, its anti-aliased rim, nothing between the letters).
    Where the scene varies enough, the ratio of the spreads reads the gain ``1 - a``, and those
    pixels give the colour (their median). Each pixel's opacity then follows from the means
    alone, which a sparse scene (a star field, a plain sky) reads far better than its spread."""
    variance = np.maximum(square - mean * mean, 0.0)
    scene_mean, scene_variance = _around(mean, variance, region)
    colour = _colour(mean, variance, scene_mean, scene_variance, region)
    if colour is None:
        return None
    gap = colour - scene_mean
    gap[np.abs(gap) < MIN_CONTRAST] = np.inf  # (opacity 0: the colour is the scene's own)
    opacity = np.clip((mean - scene_mean) / gap, 0.0, 1.0 - GAIN_RANGE[0])
    # Opaque where the scene does not show through: its spread, pooled over (2 POOL + 1)^2
    # pixels (one pixel of a sparse scene may see nothing pass), stays under GAIN_RANGE[0] of
    # the scene's around.
    k = (2 * POOL + 1, 2 * POOL + 1)
    shows = cv2.blur(variance, k) >= GAIN_RANGE[0] ** 2 * scene_variance
    ok = region & shows & (opacity >= 1.0 - GAIN_RANGE[1])
    if not ok.any():
        return None
    x, y, w, h = cv2.boundingRect(ok.view(np.uint8))
    box = np.s_[y:y + h, x:x + w]
    inside = ok[box]
    return _SceneMap(region.shape, box,
                     np.where(inside, 1.0 - opacity[box], 1.0).astype(np.float32),
                     np.where(inside, opacity[box] * colour, 0.0).astype(np.float32))


def _around(mean: np.ndarray, variance: np.ndarray,
            region: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """``(scene_mean, scene_variance)``, (h, w) float32: the temporal ``mean`` and ``variance``
    of the pixels off the ``region`` within AROUND_SCENE px (the variance at least
    MIN_VARIANCE): what the scene under the region shows over the frames."""
    outside = (~region).astype(np.float32)
    k = (2 * AROUND_SCENE + 1, 2 * AROUND_SCENE + 1)
    weight = cv2.blur(outside, k) + np.float32(1e-3)
    scene_mean = cv2.blur(mean * outside, k) / weight
    scene_variance = np.maximum(cv2.blur(variance * outside, k) / weight, MIN_VARIANCE)
    return scene_mean, scene_variance


def _colour(mean: np.ndarray, variance: np.ndarray, scene_mean: np.ndarray,
            scene_variance: np.ndarray, region: np.ndarray) -> Optional[float]:
    """The overlay's colour (a gray level): the median, over the ``region``'s pixels whose
    spread against the scene's reads a gain in GAIN_RANGE, of ``(mean - gain scene_mean) / (1 -
    gain)``; None where no pixel's does."""
    gain = np.sqrt(cv2.blur(variance, (3, 3)) / scene_variance)
    readable = region & (gain >= GAIN_RANGE[0]) & (gain <= GAIN_RANGE[1])
    if not readable.any():
        return None
    g = gain[readable]
    return float(np.median((mean[readable] - g * scene_mean[readable]) / (1.0 - g)))


def _judged(piece: np.ndarray, near_edge: np.ndarray, still: np.ndarray) -> np.ndarray:
    """The pixels a ``piece`` ((bh, bw) bool) is judged by: where the scene shows through it
    (SHOWS), the pixels of its inside off the edges (``near_edge``, (bh, bw) bool) that change
    (``still``: |frame - last|, (bh, bw) float32); else the whole piece."""
    inside = cv2.erode(piece.view(np.uint8), kernel(cv2.MORPH_RECT, 2 * INSIDE + 1),
                       borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0
    off = inside & ~near_edge
    if np.count_nonzero(off) < LEAST_SHOWING or float(np.median(still[off])) < SHOWS:
        return piece
    return off & (still >= SHOWS)


def _letters(found: np.ndarray, least: int) -> Optional[np.ndarray]:
    """The ``found`` pixels ((h, w) bool) in pieces of ``least`` or more, closed, with what they
    enclose filled and grown by 3 px (a letter's rim); None for none."""
    closed = cv2.morphologyEx(found.view(np.uint8), cv2.MORPH_CLOSE, kernel(cv2.MORPH_RECT, 7))
    n, labels, stats, _ = cv2.connectedComponentsWithStats(closed, connectivity=8)
    large = stats[:, cv2.CC_STAT_AREA] >= least
    large[0] = False
    if not large.any():
        return None
    m = large[labels].view(np.uint8)
    return cv2.dilate(m | enclosed(m), kernel(cv2.MORPH_RECT, 7)) > 0
