"""A sample-based background model for a still camera: :class:`SampleBackground`."""

from __future__ import annotations

from typing import Optional, Tuple

import cv2
import numpy as np

from bgsub.errors import InputError, describe_shape

__all__ = ["SampleBackground"]


class SampleBackground:
    """A sample-based background model for a still camera (ViBe's kind, as in SuBSENSE).

    Each pixel keeps ``samples`` past values; it is background when ``min_matches`` of them lie
    within ``radius`` gray levels (the largest channel difference). Water, foam and leaves take
    many values at one pixel: a mean and a variance describe them badly, a set of samples well.
    The model is never warped, so it serves only while the camera is still (the engines decide
    when: :class:`bgsub.background.still_switch.StillCameraSwitch`). Updates are conservative and
    random: a background pixel replaces one of its samples with probability ``1 / subsample``
    and, as often, one of a neighbour's (ViBe's diffusion, which lets a ghost fade from its
    border).

    Usage per frame: :meth:`score` the frame, then :meth:`update` with the decided mask.
    """

    def __init__(self, *, samples: int = 20, radius: float = 20.0, min_matches: int = 2,
                 subsample: int = 16, seed: int = 0, radius_min: Optional[float] = None,
                 radius_gain: float = 0.0, adapt: float = 0.05) -> None:
        if not 1 <= min_matches <= samples:
            raise InputError(f"min_matches must be between 1 and samples ({samples}), "
                             f"not {min_matches}")
        self.n, self.radius = int(samples), float(radius)
        self.min_matches, self.subsample = int(min_matches), int(subsample)
        self.rng = np.random.default_rng(seed)
        self.s: Optional[np.ndarray] = None  # (N, C, H, W) uint8, one plane per channel
        self.radius_min = self.radius if radius_min is None else float(radius_min)
        self.radius_gain, self.adapt = float(radius_gain), float(adapt)
        self.spread: Optional[np.ndarray] = None  # (H, W) float32: each pixel's usual distance
        self._seen = 0
        self._last: Optional[np.ndarray] = None  # (H, W) uint8: the last score's distances

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
        pad = np.pad(f, ((0, 0), (1, 1), (1, 1)), mode="edge").reshape(c, -1)
        # Flat indices into the padded planes: one gather per sample, not a 2-D fancy index.
        ys, xs = np.mgrid[1:h + 1, 1:w + 1]
        centre = ys * (w + 2) + xs
        s = np.empty((self.n, c, h, w), np.uint8)
        s[0] = f
        for k in range(1, self.n):
            dy = self.rng.integers(-1, 2, (h, w))
            dx = self.rng.integers(-1, 2, (h, w))
            np.take(pad, centre + dy * (w + 2) + dx, axis=1, out=s[k])
        self.s = s
        self.spread, self._seen, self._last = None, 0, None

    def radii(self) -> Optional[np.ndarray]:
        """``(H, W) float32``: each pixel's radius, ``radius_min`` plus ``radius_gain`` times
        its usual distance to its samples (a running mean over the frames where it was
        background), at most ``radius``; None while the radius is one for all pixels."""
        if self.radius_min >= self.radius or self.spread is None:
            return None
        r = self.spread * np.float32(self.radius_gain) + np.float32(self.radius_min)
        return np.minimum(r, np.float32(self.radius), out=r)

    def score(self, frame: np.ndarray) -> np.ndarray:
        """``(H, W) float32``: the ``min_matches``-th smallest sample distance / ``radius`` (1 =
        at the decision threshold, as :meth:`CompensatedBackground.score`); zeros before the
        first frame."""
        f = self._planes(frame)
        if self.s is None:
            return np.zeros(f.shape[1:], np.float32)
        self._check(f)
        kth = self._kth(self.s, f)
        self._last = kth
        radii = self.radii()
        if radii is None:
            return kth.astype(np.float32) * np.float32(1.0 / self.radius)
        return kth.astype(np.float32) / radii

    def score_box(self, frame: np.ndarray, box: Tuple[slice, slice]) -> np.ndarray:
        """:meth:`score` of the ``box`` (a ``(rows, columns)`` pair of slices) of ``frame``
        alone, ``(bh, bw) float32``, at the one radius (``radius``); the model has a frame."""
        f = self._planes(frame)
        self._check(f)
        rows, cols = box
        kth = self._kth(self.s[:, :, rows, cols], f[:, rows, cols])
        return kth.astype(np.float32) * np.float32(1.0 / self.radius)

    def _kth(self, samples: np.ndarray, f: np.ndarray) -> np.ndarray:
        """``(H, W) uint8``: the ``min_matches``-th smallest distance of the ``(C, H, W)``
        planes ``f`` to the ``(N, C, H, W)`` ``samples``."""
        # The k smallest distances, kept sorted while the samples stream past: 2k whole-frame
        # min/max per sample instead of a partition along the sample axis, which is far slower.
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
        self._learn_spread(learn)
        at = self._draw(h * w, p, learn)
        self._put(f, at, at)
        at = self._draw(h * w, p, learn)
        ys, xs = np.divmod(at, w)
        ny = np.clip(ys + self.rng.integers(-1, 2, at.size), 0, h - 1)
        nx = np.clip(xs + self.rng.integers(-1, 2, at.size), 0, w - 1)
        self._put(f, at, ny * w + nx)

    def _learn_spread(self, learn: Optional[np.ndarray]) -> None:
        """Fold the last score's distances into each background pixel's usual distance: a
        running mean that becomes an average over the last ``1 / adapt`` frames. A frame the
        model did not score (the camera was moving) adds nothing, and no score counts twice."""
        if self._last is None or self.radius_min >= self.radius:
            return
        d, self._last = self._last.astype(np.float32), None
        self._seen += 1
        if self.spread is None:
            self.spread = d
            return
        a = np.float32(max(self.adapt, 1.0 / self._seen))
        new = self.spread + a * (d - self.spread)
        self.spread = new if learn is None else np.where(learn, new, self.spread)

    def _put(self, f: np.ndarray, source: np.ndarray, target: np.ndarray) -> None:
        """Each pixel of ``f`` ((C, H, W) uint8) at the flat positions ``source`` ((K,) int)
        replaces a random one of the samples at ``target``: one flat scatter per channel, cheaper
        than an index that mixes a slice with arrays."""
        _, c, h, w = self.s.shape
        at = self.rng.integers(0, self.n, source.size) * (c * h * w) + target
        flat, planes = self.s.reshape(-1), f.reshape(c, -1)
        for ch in range(c):
            flat[at + ch * h * w] = planes[ch, source]

    def _draw(self, size: int, p: float, learn: Optional[np.ndarray]) -> np.ndarray:
        """``(K,) int64``: the flat positions, among ``size`` pixels, of those that learn: each
        with probability ``p`` where ``learn`` (all when None). Drawn as a binomial count of
        positions, not one random number per pixel (a tenth of the time at ``p = 1/16``)."""
        at = self.rng.integers(0, size, self.rng.binomial(size, p))
        return at if learn is None else at[learn.ravel()[at]]

    def background_image(self) -> Optional[np.ndarray]:
        """The samples' median as uint8 ((H, W, 3) or (H, W)), or None before the first
        frame."""
        if self.s is None:
            return None
        img = np.median(self.s, axis=0).astype(np.uint8)
        return img[0] if img.shape[0] == 1 else np.ascontiguousarray(img.transpose(1, 2, 0))

