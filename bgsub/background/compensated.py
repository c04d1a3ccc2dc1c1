"""The camera-compensated background model: per-pixel colour statistics kept in the current
frame's coordinates (:class:`CompensatedBackground`) and its settings (:class:`BackgroundConfig`).

Every frame the model is warped by the camera motion before it is compared and updated. Each
pixel has an age (frames of history); pixels that scroll in at the border start at age 0 and,
until they have ``min_age`` frames of history, are not called foreground on a background
difference (they score ``young_score``, below the threshold): only motion evidence can make
them foreground. Young pixels learn fast (rate ``1 / (age + 1)``, a plain average), old ones at
``alpha``. The comparison is against the background's local min/max envelope (``envelope``
px), so the sub-pixel misregistration that every warp leaves on strong edges does not light up
as foreground.

Pixels called foreground learn slowly, so an object does not fade into the background while it
moves. An object present when the model began leaves a ghost that slow learning would keep for
a long time. The model therefore remembers which pixels it has ever learnt as background
(:attr:`CompensatedBackground.seen`). A pixel it has never seen as background, whose current
colour the model of a background pixel within ``ghost_radius`` explains, takes that colour: a
ghost heals from its edges inward, up to ``ghost_radius`` px per frame. An object that arrives
over background the model has seen is never healed this way, whatever its colour.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from bgsub.background.clamp import at_least, at_most
from bgsub._util import FieldWarp, fast_median, through_bgra, warp_image  # noqa: F401  (re-exported)
from bgsub.errors import InputError, describe_shape
from bgsub.motion.global_motion import is_identity
from bgsub.settings import check_settings, setting

__all__ = ["BackgroundConfig", "CompensatedBackground", "through_bgra", "warp_image"]


@dataclass(frozen=True)
class BackgroundConfig:
    """Settings of :class:`CompensatedBackground` (gray levels are 0-255); each field's
    meaning, default and bounds are in its :func:`~bgsub.settings.setting`.

    ``fg_alpha`` is small, so an object is not learnt into the background while it moves, but
    not zero, so a ghost (background uncovered by an object that was there when the model
    started) fades. ``init_std`` caps the variance update (a squared residual counts at most
    ``(4 init_std)^2``, so a passing object cannot blind the model) and is the spread of the
    very first frame of a model that was never :meth:`~CompensatedBackground.reset`; a model
    that is reset and then updated with the same frame (as the engines restart) starts at
    ``min_std``.
    """

    alpha: float = setting(0.1, "background learning rate of pixels with a long history",
                           low=0, high=1)
    fg_alpha: float = setting(0.01, "learning rate of pixels called foreground (lets ghosts "
                                    "fade)", low=0, high=1)
    k_sigma: float = setting(2.0, "foreground beyond this many background standard deviations "
                                  "(and min_diff gray levels)", low=0)
    min_diff: float = setting(10.0, "foreground needs a difference of at least this many gray "
                                    "levels (0-255) as well as k_sigma standard deviations",
                              low=0)
    init_std: float = setting(12.0, "standard deviation (gray levels) of a model's first frame; "
                                    "a squared residual counts at most (4 init_std)^2 in the "
                                    "variance update, so a passing object cannot blind the "
                                    "model", above=0)
    min_std: float = setting(6.0, "floor of the learnt standard deviation (gray levels)",
                             above=0)
    envelope: int = setting(1, "a pixel is compared with the background's min/max over this "
                               "neighbourhood (3 tolerates a 1-px misregistration)",
                            low=1, high=31)
    min_age: int = setting(1, "frames of history a pixel needs before a background difference "
                              "can make it foreground (see young_score)", low=0)
    max_age: int = setting(255, "ages are capped here (only the young pixels' rate 1 / (age + "
                                "1) depends on them)", low=1)
    young_score: float = setting(0.6, "score of pixels younger than min_age (below 1: "
                                      "foreground only where local motion evidence boosts it; "
                                      "0 = never)", low=0, high=1)
    ghost_radius: int = setting(6, "a pixel called foreground that the model has never seen "
                                   "as background takes the current colour where the model "
                                   "of a background pixel within this many px explains it: "
                                   "the ghost of an object present when the model began "
                                   "heals from its edges (0 = off)", low=0, high=31)

    def __post_init__(self) -> None:
        check_settings(self)


class CompensatedBackground:
    """A per-pixel colour background model that moves with the camera.

    Usage per frame: :meth:`warp` by the camera motion (previous -> current frame), then
    :meth:`score` the current frame, then :meth:`update` with the decided mask.
    """

    def __init__(self, config: Optional[BackgroundConfig] = None) -> None:
        self.config = config or BackgroundConfig()
        self.mean: Optional[np.ndarray] = None  # (H, W, C) float32, 0-255
        self.var: Optional[np.ndarray] = None  # (H, W, C) float32
        self.age: Optional[np.ndarray] = None  # (H, W) float32
        # (H, W) float32, 1 where the model has learnt the pixel at least once under a mask
        # that called it background (below 1 at the edges of such areas after a warp).
        self.seen: Optional[np.ndarray] = None
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
        self.var = np.full_like(f, self.config.init_std**2)
        self.age = np.zeros(f.shape[:2], np.float32)
        self.seen = np.zeros(f.shape[:2], np.float32)
        self._diff = None

    def restart(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` and learn it once (a new shot; the engine's restart)."""
        self.reset(frame)
        self.update(frame)

    def warp(self, matrix: np.ndarray, *, sharp: bool = False,
             parallax: Optional[FieldWarp] = None) -> None:
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
        move = parallax or (lambda img, how, border: warp_image(img, matrix, (w, h), how, border))
        self.mean = move(self.mean, flags, cv2.BORDER_REPLICATE)
        self.var = move(self.var, flags, cv2.BORDER_REPLICATE)
        if sharp:
            # Lanczos rings: keep the values in the range they can take.
            np.clip(self.mean, 0.0, 255.0, out=self.mean)
            at_least(self.var, self.config.min_std ** 2)
        # Age with a zero border: uncovered pixels have no history. Linear interpolation lets
        # a pixel half-inside inherit a lower age, which is the cautious side.
        self.age = move(self.age, cv2.INTER_LINEAR, cv2.BORDER_CONSTANT)
        self.seen = move(self.seen, cv2.INTER_LINEAR, cv2.BORDER_CONSTANT)

    def warped_copy(self, matrix: np.ndarray,
                    parallax: Optional[FieldWarp] = None) -> "CompensatedBackground":
        """A copy of the model moved by ``matrix`` (3, 3) and ``parallax`` as :meth:`warp`
        would move it (bilinearly), this model left as it is."""
        other = copy.copy(self)  # warp() replaces the arrays, it does not write into them
        other.warp(matrix, parallax=parallax)
        return other

    def adopt(self, others: list, where: list) -> None:
        """Take the model of each of ``others`` (models of this one's size, as
        :meth:`warped_copy` makes them) at its ``where`` ((H, W) uint8, nonzero: take it),
        in place (in the arrays the last :meth:`warp` made)."""
        for other, mask in zip(others, where):
            for name in ("mean", "var", "age", "seen"):
                cv2.copyTo(getattr(other, name), mask, getattr(self, name))
        self._diff = None

    def forget_partly_seen(self, matrix: np.ndarray) -> None:
        """After a frozen model's :meth:`warp` by ``matrix`` (3, 3): pixels that the previous
        frame saw only in part (their source lies beyond its border, filled by replicating the
        edge) lose their history, so that :meth:`update` gives them this frame.

        The warp interpolates the age, so a pixel half beyond the border inherits half of its
        neighbour's: at 1 or more it would count as learnt, and a frozen model would keep the
        replicated edge (streaks along the border the camera moves towards).
        """
        if self.age is None or np.array_equal(matrix, np.eye(3)):
            return
        h, w = self.age.shape
        inside = cv2.warpPerspective(np.ones((h, w), np.float32), matrix, (w, h),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                     borderValue=0)
        self.age[inside < 0.999] = 0.0

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
        p = self.config
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
        at_least(denom, floor * floor)
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
               learning_rate: float = -1.0, *, exposure: float = 1.0,
               confirmed: Optional[np.ndarray] = None) -> None:
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
        exposure : float
            The gain ``frame`` was divided by to bring it to the model's exposure
            (:meth:`exposure_gain`). The whole mean then follows the camera's exposure at
            ``alpha`` (or ``learning_rate``) like any other change, so an error of the gain's
            estimate stays that frame's instead of accumulating from frame to frame.
        confirmed : (H, W) bool, optional
            Pixels the frames' motion shows to be background (:meth:`Fusion.confirmed`). Where
            the model has never seen them as background, its mean takes the frame (automatic
            rate only): what it holds there is an object of its first frame.

        Raises
        ------
        InputError
            ``learning_rate`` above 1; ``frame`` not of the model's size and channel count (but
            for a restart), or ``fgmask`` not of the frame's size.
        """
        p = self.config
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
        f, d, sq = self._difference(frame)
        fg = None if fgmask is None else np.asarray(fgmask).astype(bool)
        rate = self._rate(learning_rate, fg)
        # Judged on the model before this frame's update.
        ghost = self._ghost(f, fg) if learning_rate < 0.0 and fg is not None else None
        take = None
        if confirmed is not None and learning_rate < 0.0:
            take = np.asarray(confirmed, bool) & (self.seen < 0.5)
        r = _per_channel(rate, d.shape[2])
        d2 = np.multiply(d, d) if sq is None else sq
        d *= r
        self.mean += d
        if exposure != 1.0:
            follow = p.alpha if learning_rate < 0.0 else learning_rate
            self.mean *= np.float32(1.0 + follow * (exposure - 1.0))
        if ghost is not None:
            # The mean takes the frame; the spread learns as foreground (the old content's
            # difference would inflate it and blind the pixel).
            y0, x0, heal = ghost
            crop = self.mean[y0:y0 + heal.shape[0], x0:x0 + heal.shape[1]]
            crop[heal] = f[y0:y0 + heal.shape[0], x0:x0 + heal.shape[1]][heal]
        if take is not None:
            self.mean[take] = f[take]
        # Variance of background pixels only (with the clipped residual): a passing object must
        # not inflate the spread and blind the model.
        at_most(d2, (4.0 * p.init_std) ** 2)
        d2 -= self.var
        d2 *= r
        self.var += d2
        at_least(self.var, p.min_std**2)
        if learning_rate < 0.0 and fg is not None:
            # Only a mask's verdict counts: a frame learnt without one (the first) is unjudged.
            np.maximum(self.seen, np.float32(1.0), out=self.seen, where=~fg)
        self.age += np.float32(1.0)
        at_most(self.age, p.max_age)

    def _difference(self, frame: np.ndarray) -> tuple:
        """``(f, d, sq)``: ``frame`` as (H, W, C) float32, ``d = f - mean`` and ``d * d``, as
        :meth:`score` of this frame left them (``sq`` None when it did not)."""
        cached, self._diff = self._diff, None
        if cached is not None and cached[0] is frame:
            return cached[1], cached[2], cached[3]
        f = self._as_float(frame)
        return f, f - self.mean, None

    def _rate(self, learning_rate: float, fg: Optional[np.ndarray]) -> np.ndarray:
        """(H, W) float32 rate of each pixel: with ``learning_rate`` negative, max(1 / (age +
        1), ``alpha``) and ``fg_alpha`` on the (H, W) bool ``fg`` pixels of age ``min_age`` or
        more; else ``learning_rate`` wherever there is a history (age 1 or more)."""
        p = self.config
        rate = self.age + np.float32(1.0)
        np.reciprocal(rate, out=rate)
        if learning_rate >= 0.0:
            np.copyto(rate, np.float32(learning_rate), where=self.age >= 1.0)
            return rate
        at_least(rate, p.alpha)
        if fg is not None:
            np.copyto(rate, np.float32(p.fg_alpha), where=fg & (self.age >= p.min_age))
        return rate

    def _ghost(self, f: np.ndarray, fg: np.ndarray) -> Optional[tuple]:
        """``(y0, x0, heal)`` or None for none: ``heal``, a bool window of the frame at
        (``y0``, ``x0``), marks the pixels of the ``(H, W)`` bool ``fg`` that the model has
        never seen as background and whose colour in ``f`` ((H, W, C) float32) lies, in every
        channel, within the decision floor of the range of the background pixels' means (those
        outside ``fg``) within ``ghost_radius`` px."""
        p = self.config
        if p.ghost_radius == 0:
            return None
        candidates = fg & (self.seen < 0.5) & (self.age >= p.min_age)
        rows, cols = np.any(candidates, axis=1), np.any(candidates, axis=0)
        if not rows.any():
            return None  # the usual frame, once the start's ghosts have healed
        # Only the candidates' box, grown by the radius, takes part.
        r = p.ghost_radius
        (y0, y1), (x0, x1) = (np.flatnonzero(rows)[[0, -1]], np.flatnonzero(cols)[[0, -1]])
        y0, x0 = max(y0 - r, 0), max(x0 - r, 0)
        box = (slice(y0, y1 + r + 1), slice(x0, x1 + r + 1))
        mean, outside, here = self.mean[box], (~fg[box]).view(np.uint8), f[box]
        k = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
        floor = np.float32(max(p.min_diff, p.k_sigma * p.min_std))
        # Foreground pixels take no part in the range: far out of it, min and max skip them.
        lo = cv2.copyTo(mean, outside, np.full_like(mean, 1e6))
        lo = cv2.erode(lo, k)
        lo -= floor
        hi = cv2.copyTo(mean, outside, np.full_like(mean, -1e6))
        hi = cv2.dilate(hi, k)
        hi += floor
        inside = cv2.inRange(here, lo, hi) > 0  # every channel within its bounds
        return y0, x0, candidates[box] & inside

    def forget(self, where: np.ndarray) -> None:
        """Drop the history of the ``(H, W) bool`` pixels ``where`` (age 0): the next update
        takes the frame there, and a warp carries no memory of them into their neighbours."""
        if self.age is not None:
            self.age[where] = 0.0

    def exposure_gain(self, frame: np.ndarray, *, step: int = 8) -> float:
        """``frame``'s brightness relative to the model (warped to it): the median of ``frame /
        mean`` over every ``step``-th pixel and channel with a history (age 1 or more) where
        neither is near black or saturated (model 20-235, frame 5-250 gray levels). A median,
        so foreground and the background's own changes, a minority of the pixels, do not move
        it. 1.0 before the first frame, for another size or with 100 values or fewer."""
        if self.mean is None or self.mean.shape[:2] != np.shape(frame)[:2]:
            return 1.0
        f = np.asarray(frame)[::step, ::step].reshape(-1).astype(np.float32)
        m = self.mean[::step, ::step].reshape(-1)
        if f.size != m.size:
            return 1.0
        age = self.age[::step, ::step].reshape(-1)
        ok = np.repeat(age >= 1.0, m.size // age.size)  # (one per channel, as mean is laid out)
        ok &= (m > 20) & (m < 235) & (f > 5) & (f < 250)
        if np.count_nonzero(ok) <= 100:
            return 1.0
        return float(fast_median(f[ok] / m[ok]))

    def sensitive(self, *, within: float) -> np.ndarray:
        """``(H, W) bool``: pixels whose decision threshold (``k_sigma`` standard deviations, at
        least ``min_diff``, in every channel) is at most ``within`` gray levels, all False
        before the first frame. Where the spread is wider (water, flicker) the model is blind
        to what differs by less."""
        if self.var is None:
            return np.zeros((0, 0), bool)
        p = self.config
        if max(p.min_diff, p.k_sigma * p.min_std) > within:
            return np.zeros(self.var.shape[:2], bool)
        widest = self.var.max(axis=2) if self.var.shape[2] > 1 else self.var[:, :, 0]
        return widest * np.float32(p.k_sigma * p.k_sigma) <= np.float32(within * within)

    def background_image(self) -> Optional[np.ndarray]:
        """The mean as uint8 ((H, W, 3) or (H, W)), or None before the first frame."""
        if self.mean is None:
            return None
        img = np.clip(self.mean + 0.5, 0, 255).astype(np.uint8)
        return img[:, :, 0] if img.shape[2] == 1 else img



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
    ``(H, W, 1)`` operand with an inner loop of only ``c`` elements, which slows each of
    :meth:`CompensatedBackground.update`'s two multiplications by more than the copy costs
    (same values either way)."""
    return a[:, :, None] if c == 1 else cv2.merge([a] * c)
