"""Frame-fixed overlays: a broadcaster's logo, a watermark, a timestamp, letterbox bars.

They are pixels fixed in image coordinates while the camera moves: background, whatever the
camera does, but a trap for a moving-camera engine. Their motion vectors read "no motion" and
can outvote the scene's in the camera fit (a logo over a flat sky), the model warped by the
camera drags their imprint over the scene, and the frames' own evidence sees a thing that does
not move with the camera.

:class:`OverlayDetector` finds them on the frames where the scene's textured pixels mostly
changed and the vectors elsewhere agree on one motion (a camera that moves, not water or a crowd):
a textured pixel that is the same (within ``overlay_noise`` gray levels) as ``overlay_lag``
frames before in at least ``overlay`` of such frames, or whose edge stays sharp in their running
mean (a semi-transparent watermark), where the vectors read no motion at all (a subject the
camera follows reads its wander). Black bars along the frame's edges (letterbox, pillarbox) are
flat, with no textured pixel: :class:`~bgsub.background.bars.BlackBars` finds them by their black
rows and columns, in every frame where the camera moved. The engine then leaves the overlay's
vectors out of the fit and the evidence, calls no foreground there and keeps no history of it in
the model (``CompensatedBackground.forget``).

A semi-transparent overlay (a watermark word) is not left out: the scene and the objects that
pass under it show through it. :class:`~bgsub.background.see_through.SeeThrough` finds it among
the pieces sharp in the running mean, and :meth:`OverlayDetector.unveil` maps its pixels back to
the scene in each frame before the engine looks at it; :meth:`OverlayDetector.discount` lowers
the background score where the frames repeat it, there and at the repeating pixels that do not
move at all (:class:`~bgsub.background.held_still.HeldStill`: a word under a shaking camera).
"""

from __future__ import annotations

import collections
from dataclasses import dataclass
from typing import Any, Optional, Tuple

import cv2
import numpy as np

from bgsub.background.bars import BlackBars
from bgsub.background.evidence import cell_index, cells_to_pixels
from bgsub.background.morphology import enclosed, kernel
from bgsub.background.held_still import HeldStill
from bgsub.background.see_through import SeeThrough
from bgsub.settings import check_settings, setting

__all__ = ["OverlayConfig", "OverlayDetector"]


@dataclass(frozen=True)
class OverlayConfig:
    """Settings of the frame-fixed overlay detection (:class:`OverlayDetector`)."""

    overlay: float = setting(0.8, "a textured pixel that stays fixed in the image in at least "
                                  "this share of the frames where the camera visibly moves is "
                                  "a frame-fixed overlay (logo, watermark, timestamp, "
                                  "letterbox): background, left out of the camera fit (0 = "
                                  "off; a region of interest, roi, also turns it off)",
                             low=0, high=1)
    overlay_frames: int = setting(8, "how many such frames a pixel must be seen in before it "
                                     "can be called an overlay", low=1)
    overlay_lag: int = setting(4, "a pixel counts as fixed when it matches the frame this many "
                                  "frames before (a small lag misses slow pans)", low=1, high=30)
    overlay_noise: float = setting(6.0, "... within this many gray levels (after a 3x3 blur)",
                                   above=0)
    see_through: int = setting(1, "1 = a semi-transparent overlay (a watermark word) is found "
                                  "and taken out of each frame, so that the scene and the "
                                  "objects under it are watched, and it is background where "
                                  "the frames repeat it (as are repeating pixels that do not "
                                  "move at all: a word under a shaking camera); 0 = left in "
                                  "the frames",
                               low=0, high=1)

    def __post_init__(self) -> None:
        check_settings(self)


#: Gradient magnitude (Sobel on the blurred gray frame) above which a pixel is textured: only
#: there can a fixed pixel be told from a moving one.
TEXTURED = 40.0
#: A frame informs the detector when at least this share of its textured pixels changed over
#: the lag (the scene moved) ...
CHANGED_SHARE = 0.3
#: ... and at least this share of the vectors off the fixed pixels lie within COHERENT_PX of
#: their median motion, which moves at least MOVING_PX (one rigid motion: a camera).
COHERENT_SHARE = 0.5
COHERENT_PX = 1.0
MOVING_PX = 0.4
#: The vectors looked at are those of patches (PATCH px wide, around their point) with at
#: least PATCH_MOVED of their pixels textured and changed.
PATCH = 13
PATCH_MOVED = 0.15
#: The running mean of the frames forgets at this rate (at most): a semi-transparent overlay
#: is where the mean's gradient keeps SHARP_RATIO of the frames' mean gradient.
MEAN_RATE = 1.0 / 32
SHARP_RATIO = 0.7
#: ... once the camera has moved this far over the frames averaged.
TRAVELLED_PX = 48.0
#: Overlay pixels lie in CELL x CELL cells whose vectors read, on average over the frames
#: where the camera moved (at CELL_RATE at least), under STILL_PX of motion.
CELL = 8
CELL_RATE = 1.0 / 16
STILL_PX = 0.1
#: Pieces of overlay smaller than this (connected pixels) are left out: speckles of a scene
#: that happened to hold still.
MIN_PIECE = 40
#: Overlays are closed and their enclosed flat parts (a logo box's inside) filled up to this
#: share of the frame, then grown by GROW_PX: their edges blur into the scene around them.
FILL_SHARE = 0.05
GROW_PX = 3


class OverlayDetector:
    """Finds frame-fixed overlays in a stream of working-size gray frames.

    Per frame: :meth:`observe` the frame and its motion vectors; :attr:`mask` is then the
    ``(h, w) bool`` overlay found so far (None while there is none). :meth:`reset` starts
    over; the engine keeps what it found across a scene cut (a broadcaster's logo outlives
    the shot)."""

    def __init__(self, config: Optional[OverlayConfig] = None) -> None:
        self.config = config or OverlayConfig()
        self.mask: Optional[np.ndarray] = None
        self.reset()

    def reset(self) -> None:
        self._history: collections.deque = collections.deque(maxlen=self.config.overlay_lag)
        self._fixed: Optional[np.ndarray] = None  # (h, w) float32: fixed frames per pixel
        self._seen: Optional[np.ndarray] = None  # (h, w) float32: informative frames
        self._mean: Optional[np.ndarray] = None  # (h, w) float32: the frames' running mean
        self._edges: Optional[np.ndarray] = None  # (h, w) float32: ... of their gradients
        self._frames = 0  # informative frames
        self._travelled = 0.0  # px the camera moved over them
        self._still: Optional[np.ndarray] = None  # (gh, gw) float32: cells' vector motion
        self._found: Optional[np.ndarray] = None  # (h, w) bool: the textured overlays
        self._bars = BlackBars()  # letterbox and pillarbox bars (flat: no pixel is textured)
        self._see_through = SeeThrough(CELL)  # semi-transparent ones (a watermark word)
        self._held = HeldStill()  # repeating pixels that do not move at all (burnt in)
        self._shown: tuple = (None, None)  # the bars and found overlays self.mask is of
        self.mask = None

    @property
    def enabled(self) -> bool:
        return self.config.overlay > 0

    def observe(self, gray: np.ndarray, points: np.ndarray, disp: np.ndarray,
                weights: np.ndarray, *, camera_still: bool = False,
                matrix: Optional[np.ndarray] = None) -> None:
        """Take in the working-size frame ``gray`` ((h, w) uint8, as it came: before
        :meth:`unveil`) and the front end's vectors (``points`` and ``disp`` (N, 2), ``weights``
        (N,); previous-frame positions). ``camera_still``: the engine takes the camera as still
        (a flock of birds before a still camera moves as one, yet the background holding still
        is no overlay). ``matrix``: the camera's motion from the last frame ((3, 3), working
        px) when it was fitted; without it no semi-transparent overlay is looked for."""
        if not self.enabled:
            return
        blurred = cv2.blur(gray, (3, 3))
        if len(self._history) == self._history.maxlen and not camera_still:
            moved = self._learn(blurred, self._history[0], points, disp, weights)
            if moved and self.config.see_through:
                self._held.update(self._repeating(), blurred, self._history[-1])
            if moved and matrix is not None and self.config.see_through:
                self._see_through.observe(blurred, self._history[-1], matrix, points, disp,
                                          weights)
        if matrix is not None and not camera_still and self.config.see_through:
            self._see_through.take_in(gray)
        self._history.append(blurred)
        if not camera_still:  # (as the textured ones: a still camera drags nothing)
            self._bars.observe(gray)
        bars = self._bars.mask(gray.shape, frames=self.config.overlay_frames, grow=GROW_PX)
        shown_bars, shown_found = self._shown
        if bars is not shown_bars or self._found is not shown_found:
            # (a new mask only when a part changed: the engine remakes its region then)
            self._shown = (bars, self._found)
            self.mask = self._found if bars is None else (
                bars if self._found is None else bars | self._found)

    def _learn(self, cur: np.ndarray, old: np.ndarray, points: np.ndarray, disp: np.ndarray,
               weights: np.ndarray) -> bool:
        """Learn from the blurred frame ``cur`` and ``old``, ``overlay_lag`` frames before it;
        whether the frame informed (its scene moved as one: a moving camera)."""
        c = self.config
        gradient = _gradient(cur)
        textured = gradient > TEXTURED
        n_textured = int(np.count_nonzero(textured))
        if n_textured == 0:
            return False
        fixed = (cv2.absdiff(cur, old) <= c.overlay_noise) & textured
        changed = 1.0 - np.count_nonzero(fixed) / n_textured
        moved = textured & ~fixed
        if changed < CHANGED_SHARE:
            return False
        step = _coherent_motion(points, disp, weights, moved)
        if step == 0.0:
            return False
        self._travelled += step
        if self._fixed is None:
            self._fixed = np.zeros(cur.shape, np.float32)
            self._seen = np.zeros(cur.shape, np.float32)
            self._mean = cur.astype(np.float32)
            self._edges = gradient
        self._fixed += fixed
        self._seen += textured
        self._learn_cells(points, disp, weights, cur.shape)
        self._frames += 1
        rate = max(1.0 / self._frames, MEAN_RATE)
        cv2.accumulateWeighted(cur, self._mean, rate)
        cv2.accumulateWeighted(gradient, self._edges, rate)
        found = (self._seen >= c.overlay_frames) & (self._fixed >= c.overlay * self._seen)
        if self._travelled >= TRAVELLED_PX:
            mean_gradient = _gradient(self._mean)
            sharp = self._sharp_in_mean(mean_gradient)
            found |= sharp
            self._see_through.find(sharp, mean_gradient, least=MIN_PIECE)
        found &= self._motionless(cur.shape)
        grown = _grown(found) if found.any() else None
        self._found = grown if grown is not None and grown.any() else None
        return True

    def _repeating(self) -> np.ndarray:
        """``(h, w) bool``: the textured pixels that matched the frame ``overlay_lag`` frames
        before in ``overlay`` of at least ``overlay_frames`` frames where the camera moved (the
        opaque overlays' test without its vectors')."""
        c = self.config
        return (self._seen >= c.overlay_frames) & (self._fixed >= c.overlay * self._seen)

    def _learn_cells(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                     shape: tuple) -> None:
        """Fold the vectors' lengths (capped at 1 px) into each CELL x CELL cell's running
        mean: an overlay's patches read no motion at all, a subject the camera follows reads
        its wander about its place in the image."""
        cells, (gh, gw) = cell_index(np.asarray(points, np.float64), shape, CELL)
        use = np.asarray(weights) > 0
        length = np.minimum(np.hypot(*np.asarray(disp, np.float64).T), 1.0)
        total = np.bincount(cells[use], length[use], minlength=gh * gw)
        count = np.bincount(cells[use], minlength=gh * gw)
        seen = count > 0
        now = np.where(seen, total / np.maximum(count, 1), 0.0).reshape(gh, gw)
        if self._still is None:
            self._still = np.full((gh, gw), 1.0, np.float32)
        rate = max(1.0 / self._frames if self._frames else 1.0, CELL_RATE)
        upd = self._still + rate * (now - self._still)
        self._still = np.where(seen.reshape(gh, gw), upd, self._still).astype(np.float32)

    def _motionless(self, shape: tuple) -> np.ndarray:
        """``(h, w) bool``: the pixels whose cell's vectors (or those of a cell up to two
        away) read almost no motion on the frames where the camera moved: a patch that straddles
        an overlay's edge reads the scene's motion."""
        still = cv2.erode(self._still, np.ones((5, 5), np.uint8))  # (the cells' minimum)
        return cells_to_pixels((still < STILL_PX).astype(np.float32), shape[:2], CELL) > 0

    def _sharp_in_mean(self, sharp: np.ndarray) -> np.ndarray:
        """``(h, w) bool``: the edges that the moving camera's frames, averaged, keep sharp
        (``sharp``: the gradient of their running mean, (h, w) float32): a semi-transparent
        overlay's (the scene under it blurs in the mean)."""
        return (sharp >= SHARP_RATIO * self._edges) & (sharp > TEXTURED)

    def unveil(self, work: np.ndarray, gray: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """``(work, gray)``, a working-size frame (h, w[, 3]) and its gray image (uint8),
        with the semi-transparent overlays found mapped back to the scene they show; as they
        are while none is found."""
        if not self.enabled:
            return work, gray
        return self._see_through.unveil(work, gray)

    def discount(self, score: np.ndarray, gray: np.ndarray) -> None:
        """Lower, in place, the ``(h, w) float32`` background ``score`` of the
        semi-transparent overlay's pixels, and of the repeating pixels that hold still
        (:class:`~bgsub.background.held_still.HeldStill`: a word the see-through tests miss
        under a shaking camera), where the frame ``gray`` ((h, w) uint8, as it came, before
        :meth:`unveil`) looks as the frames always did there
        (:meth:`~bgsub.background.see_through.SeeThrough.discount`)."""
        if self.enabled and self.config.see_through:
            self._see_through.discount(score, gray, also=self._held.mask)

    def forget_in(self, model: Any) -> None:
        """Drop the history of the overlay pixels in ``model`` (a
        :class:`~bgsub.background.compensated.CompensatedBackground`), if any are found."""
        if self.mask is not None:
            model.forget(self.mask)

    def box(self) -> Optional[Tuple[int, int, int, int]]:
        """``(x, y, w, h)`` around the overlay in working-size pixels, or None."""
        return _box(self.mask)

    def see_through_box(self) -> Optional[Tuple[int, int, int, int]]:
        """``(x, y, w, h)`` around the semi-transparent overlay (working-size pixels) that
        :meth:`unveil` maps back to the scene, or None."""
        return _box(self._see_through.region)


def _box(mask: Optional[np.ndarray]) -> Optional[Tuple[int, int, int, int]]:
    """``(x, y, w, h)`` around the ``(h, w) bool`` ``mask``, or None."""
    if mask is None:
        return None
    return tuple(int(v) for v in cv2.boundingRect(mask.view(np.uint8)))


def _gradient(gray: np.ndarray) -> np.ndarray:
    """``(h, w) float32``: the Sobel gradient magnitude (L1) of ``gray``."""
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3)
    return cv2.add(cv2.absdiff(gx, 0), cv2.absdiff(gy, 0))


def _coherent_motion(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                     moved: np.ndarray) -> float:
    """How far (px) the vectors of the patches where textured pixels ``moved`` ((h, w) bool)
    mostly moved together, if at least ``MOVING_PX``: a moving camera, not water, snow or a
    crowd before a still one; else 0."""
    if not len(points):
        return 0.0
    h, w = moved.shape
    # (in uint8, 255 = all: a float box filter costs several times more)
    share = cv2.blur(moved.view(np.uint8) * np.uint8(255), (PATCH, PATCH))
    xy = np.rint(np.asarray(points, np.float64)).astype(np.intp)
    ok = (np.asarray(weights) > 0) & (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0)
    ok &= xy[:, 1] < h
    ok[ok] = share[xy[ok, 1], xy[ok, 0]] >= 255 * PATCH_MOVED
    d = np.asarray(disp, np.float64)[ok]
    if len(d) < 8:
        return 0.0
    centre = np.median(d, axis=0)
    step = float(np.hypot(*centre))
    if step < MOVING_PX:
        return 0.0
    near = np.hypot(*(d - centre).T) <= COHERENT_PX
    return step if float(np.mean(near)) >= COHERENT_SHARE else 0.0


def _grown(found: np.ndarray) -> np.ndarray:
    """The overlay pixels ``found`` ((h, w) bool) closed, with what they enclose (up to
    ``FILL_SHARE`` of the frame) filled, and grown by ``GROW_PX``."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(found.view(np.uint8), connectivity=8)
    large = stats[:, cv2.CC_STAT_AREA] >= MIN_PIECE
    large[0] = False
    m = large[labels].view(np.uint8)
    m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, kernel(cv2.MORPH_RECT, 7))
    holes = enclosed(m)
    if cv2.countNonZero(holes) <= FILL_SHARE * m.size:
        m |= holes
    m = cv2.dilate(m, kernel(cv2.MORPH_ELLIPSE, 2 * GROW_PX + 1))
    return m > 0
