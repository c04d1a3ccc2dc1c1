"""Layer 1 of the Object Semantic Hierarchy: what does not move with the camera is foreground.

Three pieces of evidence, fused into one clean mask:

* :class:`CompensatedBackground`: per-pixel colour statistics (running mean and variance) kept in
  the *current* frame's coordinates: every frame the model is warped by the camera motion before
  it is compared and updated. Each pixel has an age (frames of history); pixels that scroll in at
  the border start at age 0 and, until they have ``min_age`` frames of history, are not called
  foreground on a background difference (they score ``young_score``, below the threshold): only
  motion evidence can make them foreground (their statistics start from the current frame). Young pixels learn fast
  (rate ``1 / (age + 1)``, a plain average), old ones at ``alpha``. The comparison is against the
  background's local min/max envelope (``envelope`` px), so the sub-pixel misregistration that
  every warp leaves on strong edges does not light up as foreground.
* :func:`flow_violation_map`: local motion vectors (gated-RBM patches or tracked corners) that
  disagree with the motion the camera predicts for their position, splatted to a per-pixel map
  weighted by their reliability.
* :func:`still_in_image_map`: pixels that the previous frame explains better unmoved than moved
  by the camera: an object the camera follows stays put in the image. Combined with the flow
  violation (the larger of the two), it reaches where patch motion cannot: relative motions
  beyond the motion readout's range, and pixels too young for the background model.

:func:`fuse_masks` combines them and thresholds, and cleans the mask (morphology, removal of blobs
below ``min_area`` pixels, filling of the holes they enclose).
The fused score is ``bg_score`` times a gain that rises above 1 where local motion violates the
camera's and falls below 1 where it confirms it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from bgsub.errors import InputError, describe_shape
from bgsub.motion.global_motion import apply_homography, is_affine, is_identity

__all__ = [
    "BackgroundParams",
    "CompensatedBackground",
    "SampleBackground",
    "flow_violation_map",
    "still_in_image_map",
    "fuse_masks",
    "clean_mask",
]


@dataclass
class BackgroundParams:
    """Parameters of :class:`CompensatedBackground` (gray levels are 0-255).

    Attributes
    ----------
    alpha : float
        Learning rate of pixels with a long history (the floor of ``1 / (age + 1)``).
    fg_alpha : float
        Learning rate of pixels called foreground: small, so an object is not learnt into the
        background while it moves, but not zero, so a ghost (background uncovered by an object
        that was there when the model started) fades.
    k_sigma : float
        A pixel differs from the background when its envelope distance exceeds ``k_sigma``
        standard deviations ...
    min_diff : float
        ... and ``min_diff`` gray levels (guards low-variance pixels against noise).
    init_std : float
        Scale of the variance update: a squared residual counts at most ``(4 init_std)^2``, so
        a passing object cannot blind the model. Also the spread of the very first frame of a
        model that was never :meth:`~CompensatedBackground.reset`; a pixel without history
        otherwise takes the (clipped) residual of its first frame, and a model that is
        :meth:`~CompensatedBackground.reset` and then updated with the same frame (as the
        engines restart) starts at ``min_std`` (giving new pixels ``init_std`` instead measured
        0.624 against 0.630 on the real set, issue 4).
    min_std : float
        The floor of the learnt standard deviation.
    envelope : int
        Side of the neighbourhood whose background min/max brackets a pixel (1 = the pixel
        only); 3 tolerates a one-pixel misregistration.
    min_age : int
        Frames of history a pixel needs before a background difference can make it
        foreground (younger pixels score ``young_score``).
    max_age : int
        Ages are capped here (only ``1 / (age + 1)`` depends on them).
    young_score : float
        The score of pixels younger than ``min_age``, which have no history to differ from.
        Below 1, so they are foreground only where the local motion evidence boosts them
        (:func:`fuse_masks`): an object standing where the background scrolls in is found by
        its motion alone.
    """

    alpha: float = 0.1
    fg_alpha: float = 0.01
    k_sigma: float = 2.0
    min_diff: float = 10.0
    init_std: float = 12.0
    min_std: float = 6.0
    envelope: int = 1
    min_age: int = 1
    max_age: int = 255
    young_score: float = 0.6


class CompensatedBackground:
    """A per-pixel colour background model that moves with the camera.

    Usage per frame: :meth:`warp` by the camera motion (previous -> current frame), then
    :meth:`score` the current frame, then :meth:`update` with the decided mask.
    """

    def __init__(self, params: Optional[BackgroundParams] = None) -> None:
        self.params = params or BackgroundParams()
        self.mean: Optional[np.ndarray] = None  # (H, W, C) float32, 0-255
        self.var: Optional[np.ndarray] = None  # (H, W, C) float32
        self.age: Optional[np.ndarray] = None  # (H, W) float32
        # (frame, frame as float, frame - mean, its square or None) from the last score(),
        # reused by update() when it is given the same frame object and the model has not
        # changed since.
        self._diff: Optional[tuple] = None

    @staticmethod
    def _as_float(frame: np.ndarray) -> np.ndarray:
        f = np.asarray(frame, dtype=np.float32)
        return f[:, :, None] if f.ndim == 2 else f

    def _check(self, frame: np.ndarray) -> None:
        """``InputError`` unless ``frame`` is (H, W) or (H, W, C) and, once the model exists,
        of its size and channel count (shapes only: called every frame)."""
        shape = _frame_shape(frame)
        if self.mean is not None:
            h, w, c = self.mean.shape
            if shape[:2] != (h, w) or (shape[2] if len(shape) == 3 else 1) != c:
                raise InputError(f"the frame is {describe_shape(shape)}, the background model "
                                 f"{describe_shape((h, w, c))} (reset() it for another stream)")

    def reset(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` ((H, W, C) or (H, W) uint8): every pixel age 0."""
        _frame_shape(frame)
        f = self._as_float(frame)
        self.mean = f.copy()
        self.var = np.full_like(f, self.params.init_std**2)
        self.age = np.zeros(f.shape[:2], np.float32)
        self._diff = None

    def warp(self, matrix: np.ndarray, *, sharp: bool = False) -> None:
        """Move the model into the current frame's coordinates.

        Parameters
        ----------
        matrix : (3, 3) float64
            Previous-frame -> current-frame pixel coordinates.
        sharp : bool
            Resample the mean and variance with a Lanczos kernel instead of bilinearly: about
            twice the cost, but for a model that is not learning (``learning_rate=0``) the
            bilinear blur adds up frame after frame (a fine texture loses half its contrast
            within ten frames of a pan) and becomes false foreground.

        Pixels of the current frame that the previous one did not see get age 0 (their mean and
        variance are then replaced by the current frame in :meth:`update`).
        """
        if self.mean is None or is_identity(matrix, atol=1e-9):
            return
        h, w = self.age.shape
        flags = cv2.INTER_LANCZOS4 if sharp else cv2.INTER_LINEAR
        self._diff = None
        self.mean = _warp(self.mean, matrix, (w, h), flags, cv2.BORDER_REPLICATE)
        self.var = _warp(self.var, matrix, (w, h), flags, cv2.BORDER_REPLICATE)
        if sharp:
            # Lanczos rings: keep the values in the range they can take.
            np.clip(self.mean, 0.0, 255.0, out=self.mean)
            np.maximum(self.var, np.float32(self.params.min_std ** 2), out=self.var)
        # Age with a zero border: uncovered pixels have no history. Linear interpolation lets
        # a pixel half-inside inherit a lower age, which is the cautious side.
        self.age = _warp(self.age, matrix, (w, h), cv2.INTER_LINEAR, cv2.BORDER_CONSTANT)

    def score(self, frame: np.ndarray) -> np.ndarray:
        """How far ``frame`` is from the background, in units of the decision threshold.

        Parameters
        ----------
        frame : (H, W, C) or (H, W) uint8, same channels as at :meth:`reset`

        Returns
        -------
        (H, W) float32 >= 0; values > 1 differ by more than ``k_sigma`` std devs and
        ``min_diff`` gray levels (the larger of the two ratios' minimum). ``young_score``
        where the pixel is younger than ``min_age``. All 0 before the model's first
        :meth:`reset` or :meth:`update` (no background yet: nothing differs from it, as
        OpenCV's subtractors answer their first frame).

        Raises
        ------
        InputError
            ``frame`` is not of the model's size and channel count.
        """
        self._check(frame)
        p = self.params
        f = self._as_float(frame)
        if self.mean is None:
            return np.zeros(f.shape[:2], np.float32)
        signed = f - self.mean
        if p.envelope > 1:
            k = np.ones((p.envelope, p.envelope), np.uint8)
            lo = _channels(cv2.erode(self.mean, k), f.shape[2])
            hi = _channels(cv2.dilate(self.mean, k), f.shape[2])
            diff = np.maximum(np.maximum(f - hi, lo - f), 0.0)
            sq = np.multiply(diff, diff, out=diff)
            self._diff = (frame, f, signed, None)
        else:
            sq = signed * signed
            self._diff = (frame, f, signed, sq)  # update() reuses both
        # diff / max(k * std, min_diff) == min(diff / (k std), diff / min_diff); compared in
        # squares (no abs, no sqrt of the variance) and the root taken of the channel maximum.
        floor = max(p.min_diff, p.k_sigma * p.min_std)
        denom = self.var * np.float32(p.k_sigma * p.k_sigma)
        np.maximum(denom, np.float32(floor * floor), out=denom)
        ratio = np.divide(sq, denom, out=denom)
        if ratio.shape[2] == 1:
            out = np.array(ratio[:, :, 0], dtype=np.float32)  # own contiguous copy
        else:
            out = np.maximum(ratio[:, :, 0], ratio[:, :, 1])
            for c in range(2, ratio.shape[2]):
                np.maximum(out, ratio[:, :, c], out=out)
        np.sqrt(out, out=out)
        out[self.age < p.min_age] = p.young_score
        return out

    def update(self, frame: np.ndarray, fgmask: Optional[np.ndarray] = None,
               learning_rate: float = -1.0) -> None:
        """Blend ``frame`` into the model.

        Parameters
        ----------
        frame : (H, W, C) or (H, W) uint8
        fgmask : (H, W) uint8/bool, optional
            Pixels called foreground learn at ``fg_alpha`` instead (automatic rate only).
        learning_rate : float
            OpenCV's convention. Negative: the model's own rates (``1 / (age + 1)`` for young
            pixels, ``alpha``, ``fg_alpha`` under ``fgmask``). In [0, 1]: every pixel with a
            history learns at this rate, foreground or not; 0 leaves them unchanged and 1
            restarts the model from ``frame`` (which may then be of another size, as with
            :meth:`reset`). Pixels without history (uncovered at the border) take the frame
            whatever the rate: there is nothing else to put there.

        Raises
        ------
        InputError
            ``learning_rate`` above 1; ``frame`` not of the model's size and channel count (but
            for a restart), or ``fgmask`` not of the frame's size.
        """
        p = self.params
        if not learning_rate <= 1.0:  # (also refuses NaN)
            raise InputError(f"the learning rate must be at most 1 (negative = automatic), "
                             f"not {learning_rate}")
        if fgmask is not None and np.shape(fgmask) != np.shape(frame)[:2]:
            raise InputError(f"the foreground mask has shape {np.shape(fgmask)}, the frame "
                             f"{np.shape(frame)}: the mask must be (H, W) of the frame's size")
        if learning_rate >= 1.0 or self.mean is None:
            self.reset(frame)
            self.age[:] = 1.0
            return
        self._check(frame)
        cached, self._diff = self._diff, None
        sq = None
        if cached is not None and cached[0] is frame and self.mean is not None:
            # score() of this frame: d = f - mean (and its square), still current.
            f, d, sq = cached[1], cached[2], cached[3]
        else:
            f = self._as_float(frame)
            d = None
        if d is None:
            d = f - self.mean
        # rate = max(1 / (age + 1), alpha), in place (these are whole-frame float32 arrays).
        rate = self.age + np.float32(1.0)
        np.reciprocal(rate, out=rate)
        if learning_rate >= 0.0:
            # The caller's rate for every pixel with a history (age >= 1).
            np.copyto(rate, np.float32(learning_rate), where=self.age >= 1.0)
        else:
            np.maximum(rate, np.float32(p.alpha), out=rate)
            if fgmask is not None:
                fg = np.asarray(fgmask).astype(bool)
                np.copyto(rate, np.float32(p.fg_alpha), where=fg & (self.age >= p.min_age))
        r = _per_channel(rate, d.shape[2])
        d2 = np.multiply(d, d) if sq is None else sq
        d *= r
        self.mean += d
        # Variance of background pixels only (with the clipped residual): a passing object must
        # not inflate the spread and blind the model.
        np.minimum(d2, np.float32((4.0 * p.init_std) ** 2), out=d2)
        d2 -= self.var
        d2 *= r
        self.var += d2
        np.maximum(self.var, np.float32(p.min_std**2), out=self.var)
        self.age += np.float32(1.0)
        np.minimum(self.age, np.float32(p.max_age), out=self.age)

    def background_image(self) -> Optional[np.ndarray]:
        """The mean as uint8 ((H, W, 3) or (H, W)), or None before the first frame."""
        if self.mean is None:
            return None
        img = np.clip(self.mean + 0.5, 0, 255).astype(np.uint8)
        return img[:, :, 0] if img.shape[2] == 1 else img


class SampleBackground:
    """A sample-based background model for a still camera (ViBe's kind, as in SuBSENSE).

    Each pixel keeps ``samples`` past values; it is background when ``min_matches`` of them lie
    within ``radius`` gray levels (the largest channel difference). Water, foam and leaves take
    many values at one pixel: a mean and a variance describe them badly, a set of samples well.
    The model is never warped, so it serves only while the camera is still (the engines decide
    when, see :class:`bgsub.engines.moving.MovingCameraEngine`). Updates are conservative and random:
    a background pixel replaces one of its samples with probability ``1 / subsample`` and, as
    often, one of a neighbour's (ViBe's diffusion, which lets a ghost fade from its border).

    Usage per frame: :meth:`score` the frame, then :meth:`update` with the decided mask.
    """

    def __init__(self, *, samples: int = 20, radius: float = 20.0, min_matches: int = 2,
                 subsample: int = 16, seed: int = 0) -> None:
        if not 1 <= min_matches <= samples:
            raise InputError(f"min_matches must be between 1 and samples ({samples}), "
                             f"not {min_matches}")
        self.n, self.radius = int(samples), float(radius)
        self.min_matches, self.subsample = int(min_matches), int(subsample)
        self.rng = np.random.default_rng(seed)
        self.s: Optional[np.ndarray] = None  # (N, C, H, W) uint8, one plane per channel

    @staticmethod
    def _planes(frame: np.ndarray) -> np.ndarray:
        """(C, H, W) uint8 of an (H, W) or (H, W, C) frame."""
        f = np.asarray(frame, np.uint8)
        return f[None] if f.ndim == 2 else np.ascontiguousarray(f.transpose(2, 0, 1))

    def _check(self, planes: np.ndarray) -> None:
        if self.s is not None and planes.shape != self.s.shape[1:]:
            c, h, w = self.s.shape[1:]
            raise InputError(f"the frame is {describe_shape(planes.shape[1:] + planes.shape[:1])}"
                             f", the background model {describe_shape((h, w, c))} (reset() it "
                             f"for another stream)")

    def reset(self, frame: np.ndarray) -> None:
        """Start from one frame: each pixel's samples are drawn from its 3x3 neighbourhood
        (ViBe's one-frame start), the first being the pixel itself."""
        f = self._planes(frame)
        c, h, w = f.shape
        pad = np.pad(f, ((0, 0), (1, 1), (1, 1)), mode="edge")
        ys, xs = np.mgrid[0:h, 0:w]
        s = np.empty((self.n, c, h, w), np.uint8)
        s[0] = f
        for k in range(1, self.n):
            s[k] = pad[:, ys + 1 + self.rng.integers(-1, 2, (h, w)),
                       xs + 1 + self.rng.integers(-1, 2, (h, w))]
        self.s = s

    def score(self, frame: np.ndarray) -> np.ndarray:
        """``(H, W) float32``: the ``min_matches``-th smallest sample distance / ``radius`` (1 =
        at the decision threshold, as :meth:`CompensatedBackground.score`); zeros before the
        first frame."""
        f = self._planes(frame)
        if self.s is None:
            return np.zeros(f.shape[1:], np.float32)
        self._check(f)
        return self._kth(self.s, f).astype(np.float32) * np.float32(1.0 / self.radius)

    def _kth(self, samples: np.ndarray, f: np.ndarray) -> np.ndarray:
        """``(H, W) uint8``: the ``min_matches``-th smallest distance of the ``(C, H, W)``
        planes ``f`` to the ``(N, C, H, W)`` ``samples``."""
        # The k smallest distances, kept sorted while the samples stream past: 2k whole-frame
        # min/max per sample instead of a partition along the sample axis (~70x slower).
        best = [np.full(f.shape[1:], 255, np.uint8) for _ in range(self.min_matches)]
        d = np.empty(f.shape[1:], np.uint8)
        tmp = np.empty_like(d)
        for sample in samples:
            cv2.absdiff(sample[0], f[0], dst=d)
            for ch in range(1, f.shape[0]):
                cv2.max(d, cv2.absdiff(sample[ch], f[ch], dst=tmp), dst=d)
            for m in best:
                cv2.min(m, d, dst=tmp)
                cv2.max(m, d, dst=d)
                m[...] = tmp
        return best[-1]

    def update(self, frame: np.ndarray, fgmask: Optional[np.ndarray] = None,
               learning_rate: float = -1.0) -> None:
        """Learn ``frame`` (conventions of :meth:`CompensatedBackground.update`): negative
        ``learning_rate``: background pixels (not ``fgmask``) renew a sample with probability
        ``1 / subsample``; in [0, 1): every pixel with that probability; 0: nothing; 1 or no
        model yet: :meth:`reset`."""
        if not learning_rate <= 1.0:
            raise InputError(f"the learning rate must be at most 1 (negative = automatic), "
                             f"not {learning_rate}")
        if learning_rate >= 1.0 or self.s is None:
            self.reset(frame)
            return
        f = self._planes(frame)
        self._check(f)
        if learning_rate == 0.0:
            return
        c, h, w = f.shape
        p = 1.0 / self.subsample if learning_rate < 0 else learning_rate
        learn = None
        if fgmask is not None and learning_rate < 0:
            learn = ~np.asarray(fgmask, bool)
        ys, xs = self._draw(h, w, p, learn)
        self.s[self.rng.integers(0, self.n, ys.size), :, ys, xs] = f[:, ys, xs].T
        ys, xs = self._draw(h, w, p, learn)
        ny = np.clip(ys + self.rng.integers(-1, 2, ys.size), 0, h - 1)
        nx = np.clip(xs + self.rng.integers(-1, 2, xs.size), 0, w - 1)
        self.s[self.rng.integers(0, self.n, ys.size), :, ny, nx] = f[:, ys, xs].T

    def _draw(self, h: int, w: int, p: float, learn: Optional[np.ndarray]) -> tuple:
        """Rows and columns of the pixels that learn: each with probability ``p`` where
        ``learn`` (all when None). Drawn as a binomial count of positions, not one random
        number per pixel (a tenth of the time at ``p = 1/16``)."""
        idx = self.rng.integers(0, h * w, self.rng.binomial(h * w, p))
        if learn is not None:
            idx = idx[learn.ravel()[idx]]
        return np.divmod(idx, w)

    def background_image(self) -> Optional[np.ndarray]:
        """The samples' median as uint8 ((H, W, 3) or (H, W)), or None before the first
        frame."""
        if self.s is None:
            return None
        img = np.median(self.s, axis=0).astype(np.uint8)
        return img[0] if img.shape[0] == 1 else np.ascontiguousarray(img.transpose(1, 2, 0))


def _frame_shape(frame: np.ndarray) -> tuple:
    """The shape of a background-model frame; ``InputError`` unless (H, W) or (H, W, C)."""
    shape = np.shape(frame)
    if len(shape) not in (2, 3):
        raise InputError(f"a background-model frame must be (H, W) or (H, W, C), not shape "
                         f"{shape}")
    return shape


def _channels(a: np.ndarray, c: int) -> np.ndarray:
    return a[:, :, None] if a.ndim == 2 and c == 1 else a


def _per_channel(a: np.ndarray, c: int) -> np.ndarray:
    """The ``(H, W)`` float32 ``a`` as an ``(H, W, c)`` factor for ``(H, W, c)`` arrays.

    For ``c > 1`` it is repeated into its own contiguous array: numpy broadcasts an
    ``(H, W, 1)`` operand with an inner loop of only ``c`` elements, which made each of
    :meth:`CompensatedBackground.update`'s two multiplications ~3x slower than the copy costs
    (same values either way)."""
    return a[:, :, None] if c == 1 else cv2.merge([a] * c)


def _warp(img: np.ndarray, matrix: np.ndarray, size: tuple, flags: int, border: int) -> np.ndarray:
    if img.ndim == 3 and img.shape[2] == 3:
        # OpenCV's 4-channel bilinear warp is much faster than its 3-channel one and gives the
        # same values per channel: go through BGRA.
        out = _warp(cv2.cvtColor(img, cv2.COLOR_BGR2BGRA), matrix, size, flags, border)
        return cv2.cvtColor(out, cv2.COLOR_BGRA2BGR)
    m = np.asarray(matrix, np.float64)
    if is_affine(m):
        # An affine motion (translation, similarity, affine): warpAffine is the same map, cheaper.
        out = cv2.warpAffine(img, m[:2] / m[2, 2], size, flags=flags, borderMode=border,
                             borderValue=0.0)
    else:
        out = cv2.warpPerspective(img, m, size, flags=flags, borderMode=border, borderValue=0.0)
    return _channels(out, img.shape[2] if img.ndim == 3 else 1) if img.ndim == 3 else out


def still_in_image_map(
    prev: np.ndarray,
    cur: np.ndarray,
    matrix: np.ndarray,
    *,
    window: int = 7,
    centre: float = 0.3,
    width: float = 0.1,
) -> np.ndarray:
    """Where the current frame is better explained by *no* motion than by the camera's.

    An object the camera follows stays put in the image while its background moves with the
    camera. Per pixel, the mean absolute difference over a ``window`` square between ``cur``
    and ``prev`` warped by the camera motion (``r_cam``) and between ``cur`` and ``prev`` as it
    is (``r_id``) give ``s = (r_cam - r_id) / (r_cam + r_id + 4)`` in (-1, 1); the map is a
    soft step of ``s`` at ``centre``. Where the camera barely moves the two agree and ``s`` is
    near 0: the map is near 0 (no evidence).

    Parameters
    ----------
    prev, cur : (H, W) uint8
        Consecutive gray frames.
    matrix : (3, 3) float64
        The camera motion (previous -> current).
    window : int
        Side of the square over which the absolute differences are averaged (px).
    centre, width : float
        The soft step: ``1 / (1 + exp(-(s - centre) / width))``, 0.5 at ``s = centre``.

    Returns
    -------
    (H, W) float32 in [0, 1]

    Raises
    ------
    InputError
        ``prev`` and ``cur`` are not (H, W) uint8 of one size.
    """
    for name, image in (("prev", prev), ("cur", cur)):
        if getattr(image, "dtype", None) != np.uint8 or image.ndim != 2:
            raise InputError(f"still_in_image_map takes (H, W) uint8 gray frames; {name} is "
                             f"{getattr(image, 'dtype', type(image).__name__)} of shape "
                             f"{np.shape(image)}")
    if prev.shape != cur.shape:
        raise InputError(f"still_in_image_map: prev and cur differ in size, {prev.shape} and "
                         f"{cur.shape}")
    h, w = cur.shape
    warped = _warp(prev, matrix, (w, h), cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)
    k = (int(window), int(window))
    r_cam = cv2.blur(cv2.absdiff(cur, warped), k).astype(np.float32)
    r_id = cv2.blur(cv2.absdiff(cur, prev), k).astype(np.float32)
    # The 4 gray levels are a noise floor: on flat areas both differences are a few levels of
    # noise, and their ratio alone would swing from -1 to 1.
    s = (r_cam - r_id) / (r_cam + r_id + np.float32(4.0))
    # The soft step 1 / (1 + exp(-(s - centre) / width)), in place.
    s -= np.float32(centre)
    s *= np.float32(-1.0 / width)
    np.exp(np.clip(s, -60.0, 60.0), out=s)
    s += np.float32(1.0)
    return np.reciprocal(s, out=s)


def flow_violation_map(
    points: np.ndarray,
    disp: np.ndarray,
    matrix: np.ndarray,
    *,
    weights: np.ndarray,
    shape: tuple,
    threshold: float = 1.5,
    cell: int = 8,
    radius: int = 1,
    noise_scale: float = 0.0,
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
        threshold = max(threshold, noise_scale * 1.4826 * float(np.median(err[ok])))
    cur = pts + d
    gw, gh = (w + cell - 1) // cell, (h + cell - 1) // cell
    gx = np.clip((cur[:, 0] // cell).astype(np.intp), 0, gw - 1)
    gy = np.clip((cur[:, 1] // cell).astype(np.intp), 0, gh - 1)
    # Soft step; the clip keeps exp() finite for wild vectors (err of thousands of px).
    viol = 1.0 / (1.0 + np.exp(-np.clip((err - threshold) / 0.25, -60.0, 60.0)))
    cells = gy[ok] * gw + gx[ok]
    num = np.bincount(cells, (wt * viol)[ok], minlength=gh * gw).reshape(gh, gw).astype(np.float32)
    den = np.bincount(cells, wt[ok], minlength=gh * gw).reshape(gh, gw).astype(np.float32)
    if radius > 0:
        k = (2 * radius + 1, 2 * radius + 1)
        num = cv2.boxFilter(num, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
        den = cv2.boxFilter(den, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
    frac = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.5).astype(np.float32)
    up = cv2.resize(frac, (gw * cell, gh * cell), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(up[:h, :w])


def clean_mask(mask: np.ndarray, *, min_area: int = 30, close: int = 5,
               fill_holes: int = 0) -> np.ndarray:
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
    m = cv2.morphologyEx(m, cv2.MORPH_OPEN, _kernel(cv2.MORPH_RECT, 3))
    if close > 1:
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, _kernel(cv2.MORPH_ELLIPSE, close))
    if min_area > 1 and cv2.countNonZero(m):
        n, labels, stats, _ = cv2.connectedComponentsWithStats(m, connectivity=8)
        small = stats[:, cv2.CC_STAT_AREA] < min_area
        small[0] = False
        if small.any():
            m[small[labels]] = 0
    if fill_holes > 0 and cv2.countNonZero(m):
        _fill_holes(m, fill_holes)
    m *= 255
    return m


def _fill_holes(m: np.ndarray, max_area: int) -> None:
    """Set to 1, in place, the 0-regions of the 0/1 ``m`` ((H, W) uint8) that do not reach the
    border (4-connected), each of at most ``max_area`` pixels."""
    # Flood the background from a one-pixel frame around the image: what stays 0 is enclosed.
    # (Three times cheaper than labelling the background, which only the rare case of more
    # enclosed pixels than max_area in total needs.)
    flooded = cv2.copyMakeBorder(m, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    cv2.floodFill(flooded, None, (0, 0), 1)
    holes = 1 - flooded[1:-1, 1:-1]
    total = cv2.countNonZero(holes)
    if total == 0:
        return
    if total > max_area:
        _, labels, stats, _ = cv2.connectedComponentsWithStats(holes, connectivity=4)
        small = stats[:, cv2.CC_STAT_AREA] <= max_area
        small[0] = False  # label 0: everything that is not a hole
        holes = small[labels].view(np.uint8)
    np.bitwise_or(m, holes, out=m)


_KERNELS: dict = {}


def _kernel(shape: int, size: int) -> np.ndarray:
    """A cached structuring element."""
    key = (shape, size)
    if key not in _KERNELS:
        _KERNELS[key] = cv2.getStructuringElement(shape, (size, size))
    return _KERNELS[key]


def fuse_masks(
    bg_score: np.ndarray,
    violation: Optional[np.ndarray] = None,
    *,
    flow_boost: float = 0.0,
    flow_damp: float = 0.0,
    threshold: float = 1.0,
    min_area: int = 30,
    close: int = 5,
    fill_holes: int = 0,
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
        np.maximum(gain, np.float32(0.0), out=gain)
        gain *= bg_score
        score = gain
    return clean_mask(score > threshold, min_area=min_area, close=close, fill_holes=fill_holes)
