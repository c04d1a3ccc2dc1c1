"""The foreground decision: motion evidence fused with the background model's difference.

* :func:`flow_violation_map`: local motion vectors (gated-RBM patches, tracked corners) that
  disagree with the motion the camera predicts for their position, splatted to a per-pixel map
  weighted by their reliability.
* :func:`~bgsub.background.evidence.motion_evidence_map`: the frames' own evidence, aware of what
  a patch can tell (flat: nothing; an edge: only motion across it): pixels that the previous
  frame explains clearly better moved by the local vectors, or not moved at all (an object the
  camera follows), than moved by the camera. Combined with the flow violation (the larger of
  the two), it reaches where the vectors cannot: colour-only differences, relative motions
  beyond the readout's range, and pixels too young for the background model.
* :func:`fuse_masks` multiplies the background score by a gain that rises above 1 where local
  motion violates the camera's and falls below 1 where it confirms it, thresholds it and cleans
  the mask (:func:`clean_mask`: morphology, removal of small blobs, filling of enclosed holes).

:class:`Fusion` is that stage as the moving-camera engines run it, with its settings
(:class:`FusionConfig`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from bgsub._util import FieldWarp
from bgsub.background.clamp import at_least
from bgsub.background.edge_holes import fill_edge_holes
from bgsub.background.evidence import (cell_index, cells_to_pixels, frame_evidence,
                                       residual_field)
from bgsub.background.morphology import enclosed, kernel
from bgsub.errors import InputError
from bgsub._util import fast_median
from bgsub.motion.global_motion import apply_homography
from bgsub.settings import check_settings, setting

__all__ = ["FusionConfig", "Fusion", "flow_violation_map", "fuse_masks", "clean_mask",
           "persistent_blobs"]


@dataclass(frozen=True)
class FusionConfig:
    """Settings of the foreground decision (:class:`Fusion`); each field's meaning, default and
    bounds are in its :func:`~bgsub.settings.setting`.

    The defaults are the ``grbm`` engine's. Its flow-violation evidence is dense but noisier
    than tracked corners: weakly textured object patches read the camera's motion and would
    damp true objects, so it leans on violations to boost rather than to damp. How noisy its
    vectors are depends on the footage (sharp BMS-26 against blurred CDnet traffic), so a
    violation is a disagreement of ``violation_threshold`` px or ``violation_noise`` robust
    standard deviations of the frame's disagreements, whichever is larger (docs/BENCHMARKS.md).
    """

    flow_boost: float = setting(1.5, "where local motion violates the camera's, the background "
                                     "difference is multiplied by up to 1 + this", low=0)
    flow_damp: float = setting(0.2, "where local motion agrees with the camera's, it is "
                                    "multiplied by down to 1 - this (0 and flow_boost 0 = "
                                    "background model only)", low=0, high=1)
    violation_threshold: float = setting(0.75, "disagreement with the camera motion (px) that "
                                              "counts as a violation", low=0)
    violation_noise: float = setting(4.0, "a violation is also at least this many robust "
                                          "standard deviations of the local vectors' "
                                          "disagreement, when that is more than "
                                          "violation_threshold (0 = fixed threshold)", low=0)
    image_cue: float = setting(1.0, "weight of the frames' own evidence: the previous frame "
                                    "moved by the local vectors, or not at all (an object the "
                                    "camera follows), explains the current one clearly better "
                                    "than moved by the camera (0 = off)", low=0, high=1)
    threshold: float = setting(1.0, "foreground where the fused score exceeds this (lower = "
                                    "more foreground)", low=0)
    min_area: int = setting(30, "blobs smaller than this (working-size pixels) are dropped",
                            low=0)
    close: int = setting(9, "morphological closing size (0 or 1 = none)", low=0, high=99)
    fill_holes: int = setting(5000, "holes enclosed by a foreground blob, up to this many "
                                    "working-size pixels, are filled (0 = none)", low=0)
    learn_close: int = setting(17, "the mask closed by this size (working px) learns at the "
                                   "foreground rate: the flat inside of an object, missed "
                                   "because it matches the background, is not learnt into the "
                                   "model (0 or 1 = the mask as it is)", low=0, high=99)
    heal_below: float = setting(0.25, "background differences where the local motion agrees "
                                      "with the camera (violation below this) are learnt at "
                                      "the normal rate (ghost healing)", low=0)
    confirm: float = setting(0.5, "a foreground pixel the model never saw as background takes "
                                  "the frame where the camera's motion explains the frames "
                                  "at least this clearly better than no motion (camera "
                                  "evidence, 0-1) and no local motion disputes it: the ghost "
                                  "of an object in the first frame, on textured background "
                                  "(0 = off)", low=0, high=1)
    grow_radius: int = setting(4, "a blob grows over pixels up to this far (working px) "
                                  "whose colour is more likely the last frame's objects' than "
                                  "the background's around them (grow_above): the flat or "
                                  "background-coloured parts of an object (0 = off)", low=0,
                               high=64)
    grow_above: float = setting(0.9, "a pixel joins a blob (grow_radius) where the objects' "
                                     "colours explain it with at least this posterior "
                                     "probability (equal priors)", low=0.5, high=1)
    hole_share: float = setting(0.5, "regions of the frame that the mask and the frame's edges "
                                     "enclose together, up to fill_holes pixels, are filled "
                                     "when the mask holds at least this share of their "
                                     "boundary: the flat inside of an object its outline "
                                     "closes (0 = off)", low=0, high=1)
    persist: int = setting(4, "a blob is kept only if it overlaps the previous frame's mask, "
                              "moved by the camera and grown by this many working-size px "
                              "(0 = off): what flickers for one frame is not an object", low=0,
                           high=64)

    def __post_init__(self) -> None:
        check_settings(self)


#: The default settings, whose values the module's functions take as their defaults.
_DEFAULT = FusionConfig()


class Fusion:
    """The foreground decision of one frame: the motion evidence (:meth:`vector_evidence` and
    :meth:`image_evidence`, which the engine makes in two threads, then :meth:`combined`),
    :meth:`mask` (fused with the background score, cleaned), :meth:`close_by_edges`,
    :meth:`confirmed` and :meth:`learn_slowly` (where the background model should learn at its
    foreground rate)."""

    def __init__(self, config: Optional[FusionConfig] = None) -> None:
        self.config = config or FusionConfig()

    def vector_evidence(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                        matrix: np.ndarray, shape: tuple, *,
                        noise_scale: Optional[float] = None) -> Optional[np.ndarray]:
        """The vectors' evidence that a pixel moves otherwise than the camera (``matrix``, (3,
        3)): the :func:`flow_violation_map` of the ``(N, 2)`` ``points`` / ``disp`` with ``(N,)``
        ``weights``, ``(h, w) float32`` in [0, 1] for a frame of ``shape`` (h, w), 0.5 where no
        vector reports. ``noise_scale`` replaces ``violation_noise`` (0: the vectors are one
        consistent motion, whose spread must not raise the threshold). None when the fusion
        ignores motion evidence."""
        c = self.config
        if c.flow_boost == 0.0 and c.flow_damp == 0.0:
            return None
        noise = c.violation_noise if noise_scale is None else noise_scale
        return flow_violation_map(points, disp, matrix, weights=weights, shape=shape,
                                  threshold=c.violation_threshold, noise_scale=noise)

    def image_evidence(self, points: np.ndarray, disp: np.ndarray, fit_weights: np.ndarray,
                       matrix: np.ndarray, prev: np.ndarray, cur: np.ndarray,
                       parallax: Optional[FieldWarp] = None) -> Optional[tuple]:
        """``(against, along)``, (h, w) float32 each: the frames' own evidence of motion against
        the camera (:func:`~bgsub.background.evidence.motion_evidence_map` of ``prev`` and
        ``cur``, (h, w) or (h, w, 3) uint8, the local vectors weighted by ``fit_weights`` as one
        alternative motion) scaled by ``image_cue``, and their
        :func:`~bgsub.background.evidence.camera_evidence_map` (for :meth:`confirmed`); None
        when that cue is off or the fusion ignores motion evidence."""
        c = self.config
        if c.image_cue == 0 or (c.flow_boost == 0.0 and c.flow_damp == 0.0):
            return None
        # Near 0 where the frames hold no evidence (flat areas, edges moving along
        # themselves, a still camera's background): it never lowers the vectors' opinion.
        local = residual_field(points, disp, fit_weights, matrix, cur.shape[:2])
        against, along = frame_evidence(prev, cur, matrix, residual=local, parallax=parallax)
        against *= np.float32(c.image_cue)
        return against, along

    @staticmethod
    def combined(vectors: Optional[np.ndarray],
                 image: Optional[np.ndarray]) -> Optional[np.ndarray]:
        """The violation map, ``(h, w) float32`` in [0, 1]: the larger of the
        :meth:`vector_evidence` and the ``against`` part of :meth:`image_evidence`, in place in
        ``vectors`` (``vectors`` itself when either is None)."""
        if vectors is None or image is None:
            return vectors
        return np.maximum(vectors, image, out=vectors)

    def mask(self, score: np.ndarray, violation: Optional[np.ndarray]) -> np.ndarray:
        """The ``(h, w) uint8`` 0/255 mask of the background ``score`` ((h, w) float32) and the
        violation map (:meth:`combined`): :func:`fuse_masks` with this stage's settings."""
        c = self.config
        return fuse_masks(score, violation, flow_boost=c.flow_boost, flow_damp=c.flow_damp,
                          threshold=c.threshold, min_area=c.min_area, close=c.close,
                          fill_holes=c.fill_holes)

    def close_by_edges(self, mask: np.ndarray, gray: np.ndarray) -> np.ndarray:
        """``mask`` ((h, w) uint8 0/255) with the holes it and the edges of ``gray`` ((h, w)
        uint8, the frame) enclose filled: :func:`~bgsub.background.edge_holes.fill_edge_holes`
        with ``hole_share``, up to ``fill_holes`` pixels."""
        c = self.config
        return fill_edge_holes(mask, gray, share=c.hole_share, max_area=c.fill_holes)

    def confirmed(self, mask: np.ndarray, violation: Optional[np.ndarray],
                  along: Optional[np.ndarray]) -> Optional[np.ndarray]:
        """``(h, w) bool`` or None: the foreground of ``mask`` that the frames show moving with
        the camera (``along``, the camera evidence of :meth:`image_evidence`, at least
        ``confirm``) and that no local motion disputes (``violation`` below ``heal_below``).
        The background model takes the frame there where it never saw background (the
        ghost of an object in its first frame, :meth:`CompensatedBackground.update`)."""
        if along is None or violation is None or self.config.confirm == 0:
            return None
        return (mask > 0) & (along >= self.config.confirm) & (violation < self.config.heal_below)

    def learn_slowly(self, mask: np.ndarray, violation: Optional[np.ndarray]) -> np.ndarray:
        """``(h, w) bool``: the foreground of ``mask`` ((h, w) uint8 0/255) closed by
        ``learn_close``, less where the local motion confidently agrees with the camera's (there
        a background difference is a ghost, background uncovered since the model learnt an
        object there: it heals at the normal rate). The closing keeps a missed flat panel inside
        an object from being learnt at a young pixel's fast rate, after which it would be
        background the model has seen, beyond the ghost healing's reach, once the object
        moves on."""
        k = self.config.learn_close
        if k > 1:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel(cv2.MORPH_ELLIPSE, k))
        slow = mask > 0
        if violation is not None:
            slow &= ~(violation < self.config.heal_below)
        return slow


def flow_violation_map(
    points: np.ndarray,
    disp: np.ndarray,
    matrix: np.ndarray,
    *,
    weights: np.ndarray,
    shape: tuple,
    threshold: float = _DEFAULT.violation_threshold,
    cell: int = 8,
    radius: int = 1,
    noise_scale: float = _DEFAULT.violation_noise,
) -> np.ndarray:
    """Where local motion disagrees with the camera's.

    Parameters
    ----------
    points : (N, 2) float
        Positions ``(x, y)`` in the *previous* frame.
    disp : (N, 2) float
        Their measured displacements to the current frame.
    matrix : (3, 3) float64
        The camera motion (previous -> current).
    weights : (N,) float
        Reliability of each measurement (0 = ignore); required (``np.ones(N)`` weighs all
        vectors alike).
    shape : (H, W)
        Size of the map, which is in *current*-frame coordinates (points are moved by ``disp``).
    threshold : float
        Disagreement (px) at which a vector counts half as violating (soft step, width 0.5 px).
    cell : int
        Votes are pooled in ``cell`` x ``cell`` cells ...
    radius : int
        ... and each cell also sees its neighbours within this many cells.
    noise_scale : float
        When > 0, the threshold is at least this many robust standard deviations of the
        disagreement (``1.4826 * median``, dominated by the background's vectors): noisy
        vectors (blurred footage) need a larger disagreement to count as motion.

    Returns
    -------
    (H, W) float32 in [0, 1]: weighted fraction of the local vectors that violate; 0.5 (no
    opinion) where no vector reports.

    Raises
    ------
    InputError
        ``points`` and ``disp`` not both ``(N, 2)``, ``weights`` not ``(N,)``, or ``matrix``
        not ``(3, 3)``.
    """
    if weights is None:
        raise InputError("flow_violation_map needs weights, one per vector (np.ones(N) weighs "
                         "them all alike)")
    ps, ds, ws = np.shape(points), np.shape(disp), np.shape(weights)
    if len(ps) != 2 or ps[1] != 2 or ds != ps or ws != ps[:1]:
        raise InputError(f"flow_violation_map needs points and disp of shape (N, 2) and weights "
                         f"of shape (N,), not {ps}, {ds} and {ws}")
    h, w = int(shape[0]), int(shape[1])
    if len(points) == 0:
        return np.full((h, w), 0.5, np.float32)
    pts = np.asarray(points, np.float64)
    d = np.asarray(disp, np.float64)
    predicted = apply_homography(matrix, pts) - pts
    err = np.hypot(*(d - predicted).T)
    wt = np.asarray(weights, np.float64)
    ok = (wt > 0) & np.isfinite(err)
    if noise_scale > 0 and ok.any():
        threshold = max(threshold, noise_scale * 1.4826 * float(fast_median(err[ok])))
    cells, (gh, gw) = cell_index((pts + d)[ok], (h, w), cell)
    # Soft step; the clip keeps exp() finite for wild vectors (err of thousands of px).
    viol = 1.0 / (1.0 + np.exp(-np.clip((err - threshold) / 0.25, -60.0, 60.0)))
    num = np.bincount(cells, (wt * viol)[ok], minlength=gh * gw).reshape(gh, gw).astype(np.float32)
    den = np.bincount(cells, wt[ok], minlength=gh * gw).reshape(gh, gw).astype(np.float32)
    if radius > 0:
        k = (2 * radius + 1, 2 * radius + 1)
        num = cv2.boxFilter(num, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
        den = cv2.boxFilter(den, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
    frac = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.5).astype(np.float32)
    return cells_to_pixels(frac, (h, w), cell)


def clean_mask(mask: np.ndarray, *, min_area: int = _DEFAULT.min_area,
               close: int = _DEFAULT.close, fill_holes: int = _DEFAULT.fill_holes) -> np.ndarray:
    """Tidy a binary mask: 3x3 opening, ``close`` x ``close`` closing, drop small blobs, fill holes.

    Parameters
    ----------
    mask : (H, W) bool or uint8
    min_area : int
        Connected components (8-connected) smaller than this many pixels are removed.
    close : int
        Side of the closing kernel (0 or 1 = no closing).
    fill_holes : int
        Background regions (4-connected) enclosed by foreground and not touching the frame's
        border, of at most this many pixels, become foreground (0 = none). The inside of a
        uniformly coloured object matches the background it covered, once the camera moves
        the model by less than the object's size, so only its outline differs.

    Returns
    -------
    (H, W) uint8, 0/255

    Raises
    ------
    InputError
        ``mask`` is not (H, W) (or (H, W, 1)).
    """
    mask = np.asarray(mask)
    if mask.ndim == 3 and mask.shape[2] == 1:
        mask = mask[:, :, 0]
    elif mask.ndim != 2:
        raise InputError(f"a mask must be (H, W), one value per pixel, not shape {mask.shape}")
    # Work on 0/1 (a bool mask is reinterpreted, not converted) and scale to 0/255 once.
    m = mask.view(np.uint8) if mask.dtype == bool else (mask > 0).view(np.uint8)
    m = cv2.morphologyEx(m, cv2.MORPH_OPEN, kernel(cv2.MORPH_RECT, 3))
    if close > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, kernel(cv2.MORPH_ELLIPSE, close))
    # Blobs and holes lie within the foreground's bounding box: labelled there (a view into m),
    # at a fraction of a whole frame's cost. A hole that reaches the box's edge is open to the
    # frame's border through the empty pixels around the box, as it is in the whole frame.
    x, y, w, h = cv2.boundingRect(m)
    box = m[y:y + h, x:x + w]
    if min_area > 1 and w:
        n, labels, stats, _ = cv2.connectedComponentsWithStats(box, connectivity=8)
        small = stats[:, cv2.CC_STAT_AREA] < min_area
        small[0] = False
        if small.any():
            box[small[labels]] = 0
    if fill_holes > 0 and cv2.countNonZero(box):
        _fill_holes(box, fill_holes)
    m *= 255
    return m


def persistent_blobs(mask: np.ndarray, previous: np.ndarray, matrix: np.ndarray, *,
                     radius: int) -> np.ndarray:
    """The blobs of ``mask`` that overlap ``previous`` moved into this frame.

    Parameters
    ----------
    mask : (H, W) uint8, 0/255
        This frame's mask.
    previous : (H, W) uint8, 0/255
        The previous frame's mask, before this filter (else an object dropped once would be
        dropped for ever).
    matrix : (3, 3) float64
        The camera motion, previous -> current frame.
    radius : int
        ``previous`` is grown by this many pixels: how far an object may move against the
        camera from one frame to the next and still be the same blob.

    Returns
    -------
    (H, W) uint8, 0/255: ``mask`` less its blobs (8-connected) that nothing in ``previous``
    touches. Water glints, a misregistered edge or a ghost's flicker last one frame; an object
    that stays is there in both.
    """
    if not cv2.countNonZero(mask):
        return mask
    h, w = mask.shape
    moved = cv2.warpPerspective(previous, np.asarray(matrix, np.float64), (w, h),
                                flags=cv2.INTER_NEAREST, borderValue=0)
    if radius > 0:
        moved = cv2.dilate(moved, kernel(cv2.MORPH_ELLIPSE, 2 * radius + 1))
    # Labelled within the mask's bounding box: its blobs are all there.
    x, y, bw, bh = cv2.boundingRect(mask)
    box = (slice(y, y + bh), slice(x, x + bw))
    n, labels = cv2.connectedComponents(mask[box], connectivity=8)
    kept = np.zeros(n, bool)
    kept[labels[(moved[box] > 0) & (mask[box] > 0)]] = True
    if kept[1:].all():  # (the usual frame: skip a pass over the labels)
        return mask
    kept[0] = False
    out = mask.copy()
    out[box] = np.where(kept[labels], mask[box], np.uint8(0))
    return out


def _fill_holes(m: np.ndarray, max_area: int) -> None:
    """Set to 1, in place, the 0-regions of the 0/1 ``m`` ((H, W) uint8) that do not reach the
    border (4-connected), each of at most ``max_area`` pixels."""
    # (A flood from the border is cheaper than labelling the background, which only the rare
    # case of more enclosed pixels than max_area in total needs.)
    holes = enclosed(m)
    total = cv2.countNonZero(holes)
    if total == 0:
        return
    if total > max_area:
        _, labels, stats, _ = cv2.connectedComponentsWithStats(holes, connectivity=4)
        small = stats[:, cv2.CC_STAT_AREA] <= max_area
        small[0] = False  # label 0: everything that is not a hole
        holes = small[labels].view(np.uint8)
    np.bitwise_or(m, holes, out=m)


def fuse_masks(
    bg_score: np.ndarray,
    violation: Optional[np.ndarray] = None,
    *,
    flow_boost: float = _DEFAULT.flow_boost,
    flow_damp: float = _DEFAULT.flow_damp,
    threshold: float = _DEFAULT.threshold,
    min_area: int = _DEFAULT.min_area,
    close: int = _DEFAULT.close,
    fill_holes: int = _DEFAULT.fill_holes,
) -> np.ndarray:
    """Fuse background difference and flow violation into a clean 0/255 mask.

    Parameters
    ----------
    bg_score : (H, W) float32
        :meth:`CompensatedBackground.score` (1 = at the background decision threshold).
    violation : (H, W) float32 in [0, 1], optional
        :func:`flow_violation_map` (0.5 = no opinion).
    flow_boost : float
        Where the local motion violates the camera's, the score is multiplied by up to
        ``1 + flow_boost`` (at ``violation == 1``).
    flow_damp : float
        Where it agrees, by down to ``1 - flow_damp`` (at ``violation == 0``): a difference
        the motion explains (a ghost, a misregistered edge) counts less. Both 0 = background
        model only.
    threshold : float
        Foreground where the fused score exceeds this.
    min_area, close, fill_holes : see :func:`clean_mask`.

    Returns
    -------
    (H, W) uint8, 0/255

    Raises
    ------
    InputError
        ``violation`` is not of ``bg_score``'s shape, or ``bg_score`` is not (H, W).
    """
    if violation is not None and np.shape(violation) != np.shape(bg_score):
        raise InputError(f"the flow violation map has shape {np.shape(violation)}, the "
                         f"background score {np.shape(bg_score)}; they must be of one size")
    score = bg_score
    if violation is not None and (flow_boost != 0.0 or flow_damp != 0.0):
        # gain = 1 + boost * max(c, 0) + damp * min(c, 0), c = 2 violation - 1, clipped at 0.
        c = np.asarray(violation, np.float32) * np.float32(2.0)
        c -= np.float32(1.0)
        gain = c * np.where(c > 0, np.float32(flow_boost), np.float32(flow_damp))
        gain += np.float32(1.0)
        at_least(gain, 0.0)
        gain *= bg_score
        score = gain
    return clean_mask(score > threshold, min_area=min_area, close=close, fill_holes=fill_holes)
