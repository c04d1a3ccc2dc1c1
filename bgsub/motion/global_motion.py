"""The camera's global motion: a robust (RANSAC) fit to point correspondences.

Correspondences come from the motion front end (gated-RBM patch displacements or Lucas-Kanade
tracks); many of them are wrong (moving objects, flat or repetitive texture). RANSAC finds the
transform most of the reliable ones agree on; a fit that is degenerate or rests on too little
evidence is reported as not ``ok`` with a reason, so the caller can keep the previous motion and
flag the frame instead of warping with garbage.

Convention (docs/ARCHITECTURE.md): the matrix is ``(3, 3) float64`` and maps homogeneous pixel
coordinates ``(x, y, 1)`` of the previous frame to the current frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from bgsub._util import fast_median, is_affine  # noqa: F401  (re-exported)
from bgsub.errors import InputError

__all__ = [
    "fast_median",
    "GlobalMotion",
    "AUTO",
    "FIT_MODELS",
    "MODELS",
    "MOTION_MODEL_HELP",
    "fit_global_motion",
    "simplest_model",
    "apply_homography",
    "corner_error",
    "is_identity",
    "is_affine",
]

#: Motion models, from the most to the least general.
MODELS = ("homography", "affine", "similarity", "translation")

#: The camera fit's choice per frame: the least general model that explains the
#: correspondences about as well as a homography (:func:`simplest_model`).
AUTO = "auto"
#: What a camera fit may be asked for: :data:`AUTO` or one of :data:`MODELS`.
FIT_MODELS = (AUTO,) + MODELS
#: The meaning of a ``motion_model`` setting (``bgsub methods``).
MOTION_MODEL_HELP = ("camera motion model fitted by RANSAC (auto: a homography or, when it "
                     "explains the vectors about as well, the simplest of affine, similarity, "
                     "translation, chosen per frame by GRIC)")

_MIN_POINTS = {"homography": 4, "affine": 3, "similarity": 2, "translation": 1, AUTO: 4}
#: px: no reading of a patch's motion is more precise than this (the floor of GRIC's scale).
_FINEST_READING = 0.05
#: Free parameters of each model (GRIC's complexity term).
_PARAMETERS = {"homography": 8, "affine": 6, "similarity": 4, "translation": 2}


@dataclass
class GlobalMotion:
    """A fitted camera motion.

    Attributes
    ----------
    matrix : (3, 3) float64
        Previous-frame pixel coordinates -> current-frame pixel coordinates (homogeneous).
    inliers : (N,) bool
        Which of the input correspondences agree with ``matrix`` (all False when not ``ok``).
    ok : bool
        False when the fit was refused; ``matrix`` is then the identity (or the caller's
        fallback) and must not be trusted.
    reason : str
        ``"ok"`` or why the fit was refused (one short phrase, for ``last_status``); for a
        motion read another way, how (``"ok: ..."``, :data:`bgsub.camera.flat_read.FLAT_READ`).
    """

    matrix: np.ndarray
    inliers: np.ndarray
    ok: bool
    reason: str = "ok"

    @classmethod
    def identity(cls, n: int = 0, *, reason: str = "ok", ok: bool = True) -> "GlobalMotion":
        """No motion, for ``n`` correspondences none of which is an inlier."""
        return cls(np.eye(3), np.zeros(n, bool), ok, reason)

    @property
    def n_inliers(self) -> int:
        return int(np.count_nonzero(self.inliers))


def _points(points: np.ndarray, what: str, dtype: type) -> np.ndarray:
    """``points`` as ``(N, 2)`` of ``dtype``; ``InputError`` unless they are ``(N, 2)`` or
    OpenCV's ``(N, 1, 2)`` (a plain reshape would silently pair up the values of other shapes)."""
    pts = np.asarray(points, dtype=dtype)
    if pts.shape[-1:] != (2,) or not (pts.ndim == 2 or (pts.ndim == 3 and pts.shape[1] == 1)):
        raise InputError(f"{what} must be (N, 2) points (x, y), not shape {pts.shape}")
    return pts.reshape(-1, 2)


def _homography(matrix: np.ndarray) -> np.ndarray:
    """``matrix`` as ``(3, 3) float64``; ``InputError`` for another shape (e.g. OpenCV's
    ``(2, 3)`` affine matrix, which needs a ``[0, 0, 1]`` row)."""
    h = np.asarray(matrix, dtype=np.float64)
    if h.shape != (3, 3):
        hint = " (append the row [0, 0, 1] to a 2x3 affine matrix)" if h.shape == (2, 3) else ""
        raise InputError(f"a homography must be a (3, 3) matrix, not shape {h.shape}{hint}")
    return h


def apply_homography(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map ``(N, 2)`` (or OpenCV's ``(N, 1, 2)``) points through a ``(3, 3)`` homography;
    returns ``(N, 2)`` float64. ``InputError`` for other shapes."""
    pts = _points(points, "points", np.float64)
    h = _homography(matrix)
    xyw = pts @ h[:, :2].T + h[:, 2]
    w = xyw[:, 2]
    tiny = np.abs(w) < 1e-12
    if tiny.any():
        w = np.where(tiny, 1e-12, w)
    # Column by column: numpy broadcasts (N, 2) / (N, 1) with an inner loop of 2 elements.
    out = np.empty((len(xyw), 2))
    np.divide(xyw[:, 0], w, out=out[:, 0])
    np.divide(xyw[:, 1], w, out=out[:, 1])
    return out


_EYE = np.eye(3)


def is_identity(matrix: np.ndarray, *, atol: float = 1e-8, rtol: float = 1e-5) -> bool:
    """``np.allclose(matrix, np.eye(3), rtol=rtol, atol=atol)`` for a ``(3, 3)`` matrix, without
    allclose's overhead (called several times per frame)."""
    d = np.abs(np.asarray(matrix, np.float64) - _EYE)
    return bool((d <= atol + rtol * _EYE).all())


def corner_distances(a: np.ndarray, b: np.ndarray, *, width: int, height: int) -> np.ndarray:
    """``(4,) float64``: distance in pixels between where the homographies ``a`` and ``b`` put
    each corner of a ``width`` x ``height`` frame."""
    corners = np.array([[0, 0], [width - 1, 0], [0, height - 1], [width - 1, height - 1]], float)
    diff = apply_homography(a, corners) - apply_homography(b, corners)
    return np.hypot(diff[:, 0], diff[:, 1])


def corner_error(estimate: np.ndarray, truth: np.ndarray, *, width: int, height: int) -> float:
    """Mean distance in pixels between the frame corners mapped by two homographies."""
    return float(np.mean(corner_distances(estimate, truth, width=width, height=height)))


def _select(
    src: np.ndarray, dst: np.ndarray, weights: Optional[np.ndarray], min_weight: float,
    max_points: int,
) -> np.ndarray:
    """Indices of the correspondences handed to RANSAC: weight above ``min_weight``, the best
    ``max_points`` of them (RANSAC's cost grows with the count, its accuracy barely does)."""
    finite = np.isfinite(src).all(axis=1) & np.isfinite(dst).all(axis=1)
    if weights is None:
        idx = np.flatnonzero(finite)
    else:
        w = np.asarray(weights, dtype=np.float64)
        idx = np.flatnonzero(finite & (w > min_weight))
        if len(idx) > max_points:
            idx = idx[np.argsort(-w[idx], kind="stable")[:max_points]]
            idx.sort()
    if weights is None and len(idx) > max_points:
        # Evenly spread subset (deterministic) so every region keeps a say.
        idx = idx[np.linspace(0, len(idx) - 1, max_points).astype(np.intp)]
    return idx


def _sane(matrix: np.ndarray, width: Optional[int], height: Optional[int],
          max_corner_shift: float) -> str:
    """Why ``matrix`` is not a plausible frame-to-frame camera motion, or ``""``."""
    if not np.all(np.isfinite(matrix)):
        return "degenerate fit (non-finite)"
    # Plain float arithmetic on the 3x3 (called several times per frame; numpy's per-call
    # overhead would dominate).
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = matrix.tolist()
    if abs(m22) <= 1e-12:
        return "degenerate fit"
    det = (m00 * m11 - m01 * m10) / (m22 * m22)
    if not 0.5 < det < 2.0:
        return f"degenerate fit (scale change {det:.2f})"
    if width is not None and height is not None:
        largest = 0.0
        for x, y in ((0.0, 0.0), (width - 1.0, 0.0), (0.0, height - 1.0),
                     (width - 1.0, height - 1.0)):
            w = m20 * x + m21 * y + m22
            if w <= 1e-6:
                return "degenerate fit (frame folds over)"
            dx = (m00 * x + m01 * y + m02) / w - x
            dy = (m10 * x + m11 * y + m12) / w - y
            largest = max(largest, math.hypot(dx, dy))
        if largest > max_corner_shift:
            return "degenerate fit (implausibly large motion)"
    return ""


def fit_global_motion(
    src: np.ndarray,
    dst: np.ndarray,
    *,
    weights: Optional[np.ndarray] = None,
    model: str = "homography",
    threshold: float,
    min_weight: float = 0.0,
    min_points: int = 12,
    min_inlier_ratio: float = 0.2,
    max_points: int = 800,
    max_iters: int = 2000,
    confidence: float = 0.995,
    frame_size: Optional[tuple] = None,
    max_corner_shift: float = 0.25,
) -> GlobalMotion:
    """Fit the camera motion ``dst ~ H src`` with RANSAC.

    Parameters
    ----------
    src, dst : (N, 2) float
        Corresponding points ``(x, y)`` in the previous and the current frame (OpenCV's
        ``(N, 1, 2)`` is accepted too).
    weights : (N,) float, optional
        Reliability per correspondence (e.g. confidence x texture). Correspondences with weight
        ``<= min_weight`` are dropped and at most ``max_points`` of the heaviest are used.
    model : {"auto", "homography", "affine", "similarity", "translation"}
        Degrees of freedom: 8, 6, 4 (rotation, uniform scale, shift) or 2; ``"auto"`` fits a
        homography and keeps the least general model that explains its inliers about as well
        (:func:`simplest_model`).
    threshold : float
        RANSAC inlier distance in pixels (of ``dst``), > 0.
    min_weight : float
        Correspondences of this weight or less are not used at all.
    min_points : int
        Fewer usable correspondences than this (or than the model's minimum) -> not ``ok``
        ("too few correspondences").
    min_inlier_ratio : float
        Fewer inliers than this fraction of the usable correspondences, or fewer than
        ``min_points`` -> not ``ok`` ("too few inliers"). RANSAC needs the camera's motion to
        be the largest consistent group, not a majority: 0.2 tolerates 80 % outliers.
    max_points, max_iters, confidence : RANSAC budget.
    frame_size : (width, height), optional
        Enables the plausibility check of the corner displacements.
    max_corner_shift : float
        Largest corner displacement accepted, as a fraction of the frame diagonal.

    Raises
    ------
    InputError
        An unknown ``model``, ``threshold <= 0``, points of another shape or ``weights`` of
        another length.

    Returns
    -------
    GlobalMotion
        ``inliers`` is over all N input correspondences. When not ``ok`` the matrix is the
        identity; callers usually substitute the previous frame's motion.
    """
    src, dst = _checked(src, dst, weights, model=model, threshold=threshold)
    n = len(src)
    idx = _select(src, dst, weights, min_weight, max_points)
    need = max(min_points, _MIN_POINTS[model])
    if len(idx) < need:
        return GlobalMotion.identity(n, ok=False, reason="too few correspondences")
    general = "homography" if model == AUTO else model
    matrix, mask = _ransac(src[idx], dst[idx], model=general, threshold=threshold,
                           max_iters=max_iters, confidence=confidence)
    if matrix is None or mask is None:
        return GlobalMotion.identity(n, ok=False, reason="degenerate fit")
    matrix = np.asarray(matrix, dtype=np.float64)
    matrix = matrix / matrix[2, 2] if abs(matrix[2, 2]) > 1e-12 else matrix
    inl = np.zeros(n, bool)
    inl[idx] = mask.ravel().astype(bool)
    n_in = int(inl.sum())
    if n_in < need or n_in < min_inlier_ratio * len(idx):
        return GlobalMotion(np.eye(3), np.zeros(n, bool), False, "too few inliers")
    if frame_size is not None:
        w, h = frame_size
        why = _sane(matrix, w, h, max_corner_shift * float(np.hypot(w, h)))
    else:
        why = _sane(matrix, None, None, np.inf)
    if why:
        return GlobalMotion(np.eye(3), np.zeros(n, bool), False, why)
    if model == AUTO:
        _, matrix = simplest_model(src[idx], dst[idx], matrix, inl[idx])
        inl[idx] = _within(*(dst[idx] - apply_homography(matrix, src[idx])).T, threshold)
    return GlobalMotion(matrix, inl, True, "ok")


def simplest_model(src: np.ndarray, dst: np.ndarray, homography: np.ndarray,
                   inliers: np.ndarray) -> tuple:
    """The least general motion model that explains the correspondences about as well as
    ``homography``, by Torr's geometric robust information criterion (GRIC).

    A homography's eight parameters fit the reading noise of correspondences that cover the
    frame unevenly (a tower and a rocket against a blank sky): the zoom and perspective it
    invents move the frame's corners by a pixel while the camera is still or panning slowly.
    Each simpler model is fitted by least squares to the homography's inliers, and each model
    scores ``sum(min(e^2 / sigma^2, 4)) + ln(4 n) k`` over all ``n`` correspondences (``e``:
    its residual; ``k``: its parameters; ``sigma``: the homography inliers' robust residual
    scale; the cap and the penalty are GRIC's for a 2D-to-2D map, not tuned here).

    Parameters
    ----------
    src, dst : (N, 2) float
        Correspondences (previous frame -> current frame), N >= 4.
    homography : (3, 3) float64
        RANSAC's homography.
    inliers : (N,) bool
        Its inliers (at least one).

    Returns
    -------
    (name, matrix): one of :data:`MODELS` and its ``(3, 3) float64`` matrix.
    """
    s = np.asarray(src, np.float64).reshape(-1, 2)
    d = np.asarray(dst, np.float64).reshape(-1, 2)
    inl = np.asarray(inliers, bool)
    fits = {"homography": np.asarray(homography, np.float64),
            **_least_squares_fits(s[inl], d[inl])}
    names = list(fits)
    errors = _squared_residuals(np.stack([fits[name] for name in names]), s, d)
    # Median of a 2D Gaussian residual's squared length: 2 ln 2 sigma^2.
    typical = fast_median(errors[inl, :1])[0]
    sigma2 = max(typical / (2.0 * math.log(2.0)), _FINEST_READING ** 2)
    penalty = math.log(4.0 * len(s))
    capped = np.minimum(errors, 4.0 * sigma2).sum(axis=0) / sigma2
    scores = {name: float(c) + penalty * _PARAMETERS[name] for name, c in zip(names, capped)}
    best = min(names, key=lambda name: (scores[name], _PARAMETERS[name]))
    return best, fits[best]


def _least_squares_fits(s: np.ndarray, d: np.ndarray) -> dict:
    """Affine, similarity and translation least-squares fits ``(3, 3) float64`` of the
    ``(K, 2) float64`` correspondences ``s -> d``, K >= 1 (affine from points that span an
    area, similarity from 2 distinct ones; translation, the median shift, from 1)."""
    k = len(s)
    z = np.column_stack([s, d])
    mean = z.mean(axis=0)
    zc = z - mean
    # Centred second moments of (x, y, x', y'): all the two fits need, in one product.
    (xx, xy, xu, xv), (_, yy, yu, yv) = (zc.T @ zc)[:2].tolist()
    ms, md = mean[:2], mean[2:]
    fits = {}
    det = xx * yy - xy * xy
    if k >= 3 and det > 1e-9 * (xx + yy) ** 2:  # (the points span an area)
        linear = np.array([[xu * yy - yu * xy, yu * xx - xu * xy],
                           [xv * yy - yv * xy, yv * xx - xv * xy]]) / det
        fits["affine"] = _matrix(linear, md - linear @ ms)
    if xx + yy > 0:
        # x' = a x - b y + tx, y' = b x + a y + ty: closed form about the centroids.
        a, b = (xu + yv) / (xx + yy), (xv - yu) / (xx + yy)
        linear = np.array([[a, -b], [b, a]])
        fits["similarity"] = _matrix(linear, md - linear @ ms)
    fits["translation"] = _matrix(np.eye(2), fast_median(d - s))
    return fits


def _matrix(linear: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """The ``(3, 3) float64`` matrix of ``x -> linear x + shift``."""
    m = np.eye(3)
    m[:2, :2] = linear
    m[:2, 2] = shift
    return m


def _squared_residuals(matrices: np.ndarray, s: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(K, M) float64: squared distance of each of ``d`` ``(K, 2)`` from its ``s`` ``(K, 2)``
    moved by each of the ``(M, 3, 3)`` ``matrices`` (one product for all of them)."""
    moved = (s @ matrices[:, :, :2].reshape(-1, 2).T + matrices[:, :, 2].reshape(-1))
    moved = moved.reshape(len(s), -1, 3)
    e = d[:, None, :] - moved[:, :, :2] / moved[:, :, 2:]
    return np.einsum("kmi,kmi->km", e, e)


def _checked(src: np.ndarray, dst: np.ndarray, weights: Optional[np.ndarray], *, model: str,
             threshold: float) -> tuple:
    """``(src, dst)`` as ``(N, 2) float32``; :class:`InputError` for what
    :func:`fit_global_motion` cannot take."""
    if model not in FIT_MODELS:
        raise InputError(f"motion model must be one of {', '.join(FIT_MODELS)}, not "
                         f"{model!r}")
    if not threshold > 0:  # (also refuses NaN)
        raise InputError(f"the RANSAC threshold must be a distance > 0 px, not {threshold}")
    src = _points(src, "src", np.float32)
    dst = _points(dst, "dst", np.float32)
    if src.shape != dst.shape:
        raise InputError(f"src and dst differ in shape: {src.shape} and {dst.shape}")
    if weights is not None and np.shape(weights) != (len(src),):
        raise InputError(f"weights must be ({len(src)},), one per correspondence, not shape "
                         f"{np.shape(weights)}")
    return src, dst


def _ransac(s: np.ndarray, d: np.ndarray, *, model: str, threshold: float, max_iters: int,
            confidence: float) -> tuple:
    """RANSAC fit of ``model`` to ``(K, 2) float32`` points ``s -> d``: ``(matrix, mask)``, the
    ``(3, 3)`` matrix (not normalised) and the ``(K, 1) uint8`` inlier mask, or ``(None,
    None)`` when OpenCV finds no fit."""
    if model == "translation":
        return _fit_translation(s, d, threshold)
    try:
        if model == "homography":
            matrix, mask = cv2.findHomography(s, d, cv2.RANSAC, threshold,
                                              maxIters=max_iters, confidence=confidence)
        elif model == "affine":
            matrix, mask = cv2.estimateAffine2D(s, d, method=cv2.RANSAC,
                                                ransacReprojThreshold=threshold,
                                                maxIters=max_iters, confidence=confidence)
        else:
            matrix, mask = cv2.estimateAffinePartial2D(s, d, method=cv2.RANSAC,
                                                       ransacReprojThreshold=threshold,
                                                       maxIters=max_iters,
                                                       confidence=confidence)
    except cv2.error:
        return None, None
    if matrix is not None and matrix.shape == (2, 3):
        matrix = np.vstack([matrix, [0.0, 0.0, 1.0]])
    return matrix, mask


def _fit_translation(s: np.ndarray, d: np.ndarray, threshold: float) -> tuple:
    """Translation by consensus: every correspondence is a hypothesis (cheap, exhaustive on a
    subsample), refined as the median shift of the inliers of the best one."""
    shifts = (d - s).astype(np.float64)
    cand = shifts[:: max(1, len(shifts) // 200)]
    near = _within(shifts[None, :, 0] - cand[:, None, 0], shifts[None, :, 1] - cand[:, None, 1],
                   threshold)
    mask = near[np.argmax(near.sum(axis=1))]
    t = fast_median(shifts[mask])
    mask = np.hypot(*(shifts - t).T) < threshold
    matrix = np.array([[1.0, 0.0, t[0]], [0.0, 1.0, t[1]], [0.0, 0.0, 1.0]])
    return matrix, mask.astype(np.uint8)


def _within(dx: np.ndarray, dy: np.ndarray, threshold: float) -> np.ndarray:
    """``np.hypot(dx, dy) < threshold`` (float64 arrays of one shape), the same decisions at a
    fraction of the cost: the squared length decides all but the pairs within a relative 1e-9
    of the threshold, far beyond both computations' rounding, and ``hypot`` decides those."""
    sq = dx * dx
    sq += dy * dy
    limit = threshold * threshold
    near = sq < limit * (1.0 - 1e-9)
    unsure = np.abs(sq - limit) <= limit * 1e-9
    if unsure.any():
        near[unsure] = np.hypot(dx[unsure], dy[unsure]) < threshold
    return near
