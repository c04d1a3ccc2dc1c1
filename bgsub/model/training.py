"""Training data and the CD-k trainer for the factored gated RBM.

A *pair source* is any callable ``source(rng, n, epoch) -> (X, Y)`` returning ``n`` raw patch
pairs as two ``(n, p*p) float32`` arrays (gray values in [0, 1]); ``epoch`` (0-based) lets a
source run a curriculum. This module ships random-dot sources (:class:`TranslatedDots`,
:class:`RotatedDots`); :mod:`bgsub.model.imagedata` provides photographs and video frames.

:func:`train` runs contrastive divergence (CD-k) with momentum, weight decay and a sparsity
target on the mapping units, all as float32 matmuls over whole minibatches: one pass over
10,000 13x13 pairs with the paper's sizes costs about 0.1 s on one core. It watches for
divergence and stops with a :class:`~bgsub.errors.ProcessingError` rather than train into
garbage. Ctrl-C after the first epoch raises :class:`TrainingInterrupted`, which carries the model
as it was after the last finished epoch, so a long run is not lost.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from bgsub.errors import InputError, ProcessingError
from bgsub.model.rbm import MIN_PATCH_SIZE, GatedRBM, sigmoid

__all__ = [
    "PairSource",
    "Curriculum",
    "TranslatedDots",
    "RotatedDots",
    "FixedPairs",
    "TrainConfig",
    "TrainResult",
    "TrainingInterrupted",
    "train",
    "evaluate_translation",
    "evaluate_rotation",
    "evaluate_shifted",
]

PairSource = Callable[[np.random.Generator, int, int], Tuple[np.ndarray, np.ndarray]]


# ---------------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Curriculum:
    """A range that grows with the epoch: ``stages = ((until_epoch, limit), ...)``.

    Before epoch ``until_epoch`` of the first stage whose bound is not passed yet, the limit is
    that stage's ``limit``; after the last stage it is the source's full range. Parsed from
    text like ``"100:1,200:2"`` (|d| <= 1 for epochs 0-99, <= 2 for 100-199, then all).
    """

    stages: Tuple[Tuple[int, float], ...] = ()

    @classmethod
    def parse(cls, text: Optional[str]) -> "Curriculum":
        if not text:
            return cls()
        stages = []
        for part in text.split(","):
            until, sep, limit = part.partition(":")
            try:
                stages.append((int(until), float(limit)))
            except ValueError:
                raise InputError(
                    f"--curriculum takes EPOCH:LIMIT,EPOCH:LIMIT,... (e.g. 100:1,200:2), not {text!r}"
                ) from None
            if not sep:
                raise InputError(f"--curriculum takes EPOCH:LIMIT pairs, not {part!r}")
            # A NaN or negative limit would reach the samplers as an impossible range.
            if not 0 <= stages[-1][1] < math.inf:
                raise InputError(f"--curriculum limits must be numbers >= 0, not {limit!r} in {text!r}")
        if [u for u, _ in stages] != sorted(u for u, _ in stages):
            raise InputError(f"--curriculum epochs must increase: {text!r}")
        return cls(tuple(stages))

    def limit(self, epoch: int, full: float) -> float:
        for until, limit in self.stages:
            if epoch < until:
                return min(limit, full)
        return full

    def scaled(self, factor: float, *, epochs: Optional[int] = None) -> "Curriculum":
        """The same stages over ``factor`` times as many epochs (bounds rounded half up).

        Only stages that still get an epoch of their own are kept: bounds above 0, above the
        bound before them, and below ``epochs`` when given (so that the full range is trained
        last). E.g. ``100:1,200:2`` scaled by ``3 / 400`` for 3 epochs is ``1:1,2:2``.
        """
        if not 0 < factor < math.inf:
            raise InputError(f"a curriculum is scaled by a number > 0, not {factor!r}")
        stages = []
        previous = 0
        for until, limit in self.stages:
            bound = int(math.floor(until * factor + 0.5))
            if bound <= previous or (epochs is not None and bound >= epochs):
                continue
            stages.append((bound, limit))
            previous = bound
        return Curriculum(tuple(stages))

    def unreached(self, epochs: int,
                  full: float) -> Tuple[Tuple[Tuple[int, float], ...], Optional[float]]:
        """What a run of ``epochs`` epochs never gets to: ``(idle, last)``.

        ``idle`` are the stages that start at or after ``epochs`` (they never run); ``last`` is
        the limit still in force at the final epoch when that is below ``full`` (the full range
        is never trained), else None.
        """
        idle = []
        last: Optional[float] = None
        start = 0
        for until, limit in self.stages:
            if start >= epochs:
                idle.append((until, limit))
            elif until >= epochs and min(limit, full) < full:
                last = min(limit, full)
            start = max(start, until)
        return tuple(idle), last

    def __str__(self) -> str:
        return ",".join(f"{u}:{l:g}" for u, l in self.stages)


def _dots(rng: np.random.Generator, shape: Tuple[int, ...], density: float) -> np.ndarray:
    return (rng.random(shape, dtype=np.float32) < density).astype(np.float32)


class _LabelledPairs:
    """A pair source that also knows the true motion of each pair (``sample`` returns it); as
    the trainer's source (``source(rng, n, epoch) -> (X, Y)``) it drops the labels."""

    def __call__(self, rng: np.random.Generator, n: int, epoch: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        x, y, _ = self.sample(rng, n, epoch)
        return x, y


@dataclass
class TranslatedDots(_LabelledPairs):
    """Random dots (``density`` of pixels on) and the same dots shifted by an integer ``(dx, dy)``.

    Each pair is cut from one larger random image as two windows ``(dx, dy)`` apart, so content
    enters at the border as it does in video (no wrap-around). Shifts are uniform over
    ``|dx|, |dy| <= max_shift`` (``max_shift=1``: the paper's 9 classes), narrowed by the
    curriculum in early epochs.
    """

    patch_size: int = 13
    max_shift: int = 1
    density: float = 0.1
    curriculum: Curriculum = field(default_factory=Curriculum)

    def sample(
        self, rng: np.random.Generator, n: int, epoch: Optional[int] = None
    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``n`` pairs and their shifts.

        Returns
        -------
        x, y : (n, p*p) float32 in {0, 1}
        shifts : (n, 2) int64 ``[dx, dy]``: ``y[r + dy, c + dx] == x[r, c]``
        """
        p, r = self.patch_size, int(self.max_shift)
        lim = r if epoch is None else int(self.curriculum.limit(epoch, r))
        shifts = rng.integers(-lim, lim + 1, size=(n, 2))
        big = _dots(rng, (n, p + 2 * r, p + 2 * r), self.density)
        idx = np.arange(p)
        rows = np.arange(n)[:, None, None]
        x = big[:, r : r + p, r : r + p]
        # y[u, v] = x[u - dy, v - dx] = big[r + u - dy, r + v - dx]
        yr = (r - shifts[:, 1])[:, None, None] + idx[None, :, None]
        yc = (r - shifts[:, 0])[:, None, None] + idx[None, None, :]
        y = big[rows, yr, yc]
        return x.reshape(n, p * p).copy(), y.reshape(n, p * p), shifts


@dataclass
class RotatedDots(_LabelledPairs):
    """Random dots and the same dots rotated about the patch centre by an angle in degrees.

    The angle is uniform in ``[-max_angle, max_angle]`` (narrowed by the curriculum early on).
    A pixel at ``q`` (``(x, y)`` relative to the centre) moves to ``R(angle) q`` with
    ``R = [[cos, -sin], [sin, cos]]`` in image coordinates (y down, so positive angles turn
    clockwise on screen). Both patches are cut from a larger random image and the rotated one is
    sampled with nearest neighbours, so it stays binary.
    """

    patch_size: int = 13
    max_angle: float = 30.0
    density: float = 0.1
    curriculum: Curriculum = field(default_factory=Curriculum)

    def sample(
        self, rng: np.random.Generator, n: int, epoch: Optional[int] = None
    ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``n`` pairs and their angles: ``x, y (n, p*p) float32``, ``angles (n,) float64`` degrees."""
        lim = self.max_angle if epoch is None else self.curriculum.limit(epoch, self.max_angle)
        angles = rng.uniform(-lim, lim, size=n)
        x, y = self.rotate(rng, angles)
        return x, y, angles

    def rotate(self, rng: np.random.Generator, angles: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Fresh random dots rotated by the given ``angles`` (degrees): ``x, y (n, p*p) float32``."""
        angles = np.asarray(angles, dtype=np.float64)
        n = len(angles)
        p = self.patch_size
        side = int(math.ceil(p * math.sqrt(2.0))) + 2
        side += (side - p) % 2  # same parity as p, so both share the centre pixel
        big = _dots(rng, (n, side, side), self.density)
        off = (side - p) // 2
        centre = (p - 1) / 2.0
        v, u = np.meshgrid(np.arange(p) - centre, np.arange(p) - centre)  # v: x offset, u: y offset
        t = np.deg2rad(angles)[:, None, None]
        cos, sin = np.cos(t), np.sin(t)
        # Output pixel q' comes from source q = R(-angle) q'.
        src_x = cos * v + sin * u + centre + off
        src_y = -sin * v + cos * u + centre + off
        ix = np.clip(np.rint(src_x).astype(np.int64), 0, side - 1)
        iy = np.clip(np.rint(src_y).astype(np.int64), 0, side - 1)
        y = big[np.arange(n)[:, None, None], iy, ix]
        x = big[:, off : off + p, off : off + p]
        return x.reshape(n, p * p).copy(), y.reshape(n, p * p)


@dataclass
class FixedPairs:
    """A fixed training set (the paper's setup: the same pairs every epoch)."""

    x: np.ndarray
    y: np.ndarray

    def __call__(self, rng: np.random.Generator, n: int, epoch: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        return self.x[:n], self.y[:n]


# ---------------------------------------------------------------------------------- trainer


@dataclass
class TrainConfig:
    """Model size and CD-k settings (defaults: the paper's, with a faster learning rate).

    Attributes
    ----------
    patch_size, n_factors, n_hidden : int
    output_units : {"binary", "gaussian"}
    normalization : {"none", "contrast"}
        ``"contrast"`` for real images (see :meth:`GatedRBM.prepare`), ``"none"`` for dots.
    contrast_floor : float
    whiten : bool
        Train on PCA-whitened patches (real images); folded into the filters afterwards.
    whiten_variance : float
        Fraction of the variance the kept principal components explain.
    epochs, n_pairs, batch_size, cd_k : int
        ``n_pairs`` pairs per epoch, in minibatches of ``batch_size`` (20 diverges; 100 is safe).
    lr, momentum, weight_decay : float
    lr_schedule : {"constant", "linear"}
        ``"linear"``: constant for the first half, then down to ``lr / 10`` at the end.
    sparsity_target, sparsity_cost : float
        Each step moves the mapping-unit biases by ``lr * sparsity_cost * (target - mean h)``.
        With 1 the mean activity settles near the target; 0.1 shortens the initial plateau
        (useful for small models) but leaves the activity at ~0.06-0.1 and made the 3-px
        curriculum diverge once (measured).
    fresh_pairs : bool
        Draw new pairs every epoch (needed for large ranges) instead of a fixed set.
    init_scale : float
        Standard deviation of the initial filters.
    normalize_filters : bool
        Rescale the input and output filters to a common norm after each step (stabilises
        Gaussian units on real images).
    max_error : float
        Divergence guard: stop when the mean squared reconstruction error per pixel exceeds this
        (or anything turns non-finite).
    seed : int
    """

    patch_size: int = 13
    n_factors: int = 200
    n_hidden: int = 100
    output_units: str = "binary"
    normalization: str = "none"
    contrast_floor: float = 0.02
    whiten: bool = False
    whiten_variance: float = 0.99
    epochs: int = 200
    n_pairs: int = 10_000
    batch_size: int = 100
    cd_k: int = 1
    lr: float = 0.05
    momentum: float = 0.9
    weight_decay: float = 1e-4
    lr_schedule: str = "constant"
    sparsity_target: float = 0.02
    sparsity_cost: float = 1.0
    fresh_pairs: bool = True
    init_scale: float = 0.01
    normalize_filters: bool = False
    max_error: float = 1e3
    seed: int = 0

    def check(self) -> None:
        """Raise :class:`InputError` for settings that cannot work."""
        if int(self.patch_size) < MIN_PATCH_SIZE:
            raise InputError(f"patch-size must be at least {MIN_PATCH_SIZE} (smaller patches "
                             f"cannot show motion), not {self.patch_size}")
        positive = ("n_factors", "n_hidden", "epochs", "n_pairs", "batch_size", "cd_k")
        for name in positive:
            if int(getattr(self, name)) < 1:
                raise InputError(f"{name.replace('_', '-')} must be at least 1, not {getattr(self, name)}")
        needed = self.memory_bytes()
        if needed > TRAIN_MEMORY:
            raise InputError(
                f"patch-size {self.patch_size} with {self.n_pairs} pairs and {self.n_factors} "
                f"factors needs about {needed / 2**30:.1f} GiB to train, more than the "
                f"{TRAIN_MEMORY // 2**30} GiB allowed: lower the patch size or the number of pairs")
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise InputError(f"learning rate must be positive, not {self.lr}")
        # NaN would otherwise surface much later as a misleading "training diverged".
        for name in ("weight_decay", "sparsity_cost"):
            if not 0 <= getattr(self, name) < math.inf:
                raise InputError(f"{name.replace('_', ' ')} must be a number >= 0, not {getattr(self, name)}")
        if int(self.seed) < 0:
            raise InputError(f"seed must be a whole number >= 0, not {self.seed}")  # numpy refuses < 0
        if not 0 <= self.momentum < 1:
            raise InputError(f"momentum must be in [0, 1), not {self.momentum}")
        if not 0 < self.sparsity_target < 1:
            raise InputError(f"sparsity target must be in (0, 1), not {self.sparsity_target}")
        if self.output_units not in ("binary", "gaussian"):
            raise InputError(f"output units must be binary or gaussian, not {self.output_units!r}")
        if self.lr_schedule not in ("constant", "linear"):
            raise InputError(f"lr schedule must be constant or linear, not {self.lr_schedule!r}")


    def memory_bytes(self) -> int:
        """A rough peak of what :func:`train` holds (bytes): an epoch's pairs (float32, with the
        larger images the dots are cut from), the weights with their velocities and gradients,
        and the whitening's covariance and eigenvectors (float64)."""
        n_in = int(self.patch_size) ** 2
        pairs = 4 * 2 * int(self.n_pairs) * n_in * 2
        weights = 4 * 3 * (2 * n_in + int(self.n_hidden)) * int(self.n_factors)
        whitening = 8 * 2 * n_in * n_in if self.whiten else 0
        return pairs + weights + whitening


#: Most memory :meth:`TrainConfig.check` lets a training take (bytes): a patch size far
#: beyond any motion model (1000: about 150 GiB) is refused before data is drawn.
TRAIN_MEMORY = 4 * 2**30


@dataclass
class TrainResult:
    """What :func:`train` returns: the model and a per-epoch record."""

    model: GatedRBM
    errors: List[float]
    seconds: float
    epochs_run: int
    stopped_early: bool = False


class TrainingInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`train` after at least one finished epoch.

    ``result`` holds the model as it was after the last finished epoch (``result.epochs_run``
    of them; ``meta["interrupted"]`` is true). Being a :class:`KeyboardInterrupt`, it stops
    callers that do not know about it just like a plain Ctrl-C.
    """

    def __init__(self, result: TrainResult) -> None:
        super().__init__(f"interrupted after {result.epochs_run} epochs")
        self.result = result


@dataclass
class _Params:
    wxf: np.ndarray
    wyf: np.ndarray
    whf: np.ndarray
    bh: np.ndarray
    by: np.ndarray

    def arrays(self) -> Tuple[np.ndarray, ...]:
        return (self.wxf, self.wyf, self.whf, self.bh, self.by)


@dataclass
class _Whitening:
    """PCA whitening ``x_w = x @ forward`` and its inverse ``x ~ x_w @ backward``."""

    forward: np.ndarray  # (D, C)
    backward: np.ndarray  # (C, D)


def _fit_whitening(x: np.ndarray, y: np.ndarray, variance: float) -> _Whitening:
    data = np.concatenate([x, y]).astype(np.float64)
    cov = data.T @ data / len(data)  # patches are zero-mean already (per-patch mean removal)
    vals, vecs = np.linalg.eigh(cov)
    order = np.argsort(vals)[::-1]
    vals, vecs = np.maximum(vals[order], 0.0), vecs[:, order]
    keep = int(np.searchsorted(np.cumsum(vals) / max(vals.sum(), 1e-12), variance) + 1)
    keep = min(keep, len(vals))
    vals, vecs = vals[:keep], vecs[:, :keep]
    eps = 1e-2 * vals.mean()
    return _Whitening(
        forward=(vecs / np.sqrt(vals + eps)).astype(np.float32),
        backward=(np.sqrt(vals + eps)[:, None] * vecs.T).astype(np.float32),
    )


def _cd_step(
    p: _Params,
    inc: _Params,
    x: np.ndarray,
    y: np.ndarray,
    *,
    cfg: TrainConfig,
    lr: float,
    rng: np.random.Generator,
) -> float:
    """One CD-k update on a minibatch; returns the summed squared reconstruction error."""
    n = x.shape[0]
    fx = x @ p.wxf
    fy = y @ p.wyf
    h_pos = sigmoid((fx * fy) @ p.whf.T + p.bh)
    fh_pos = h_pos @ p.whf

    h = h_pos
    y_neg = y
    for _ in range(cfg.cd_k):
        h_sample = (rng.random(h.shape, dtype=np.float32) < h).astype(np.float32)
        act = (fx * (h_sample @ p.whf)) @ p.wyf.T + p.by
        y_neg = sigmoid(act) if cfg.output_units == "binary" else act
        fy_neg = y_neg @ p.wyf
        h = sigmoid((fx * fy_neg) @ p.whf.T + p.bh)
    h_neg = h
    fh_neg = h_neg @ p.whf

    # Positive minus negative statistics of -dE/dW, each as one matmul over the minibatch.
    g_wxf = x.T @ (fy * fh_pos - fy_neg * fh_neg)
    g_wyf = y.T @ (fx * fh_pos) - y_neg.T @ (fx * fh_neg)
    g_whf = h_pos.T @ (fx * fy) - h_neg.T @ (fx * fy_neg)
    g_bh = h_pos.sum(0) - h_neg.sum(0)
    g_by = y.sum(0) - y_neg.sum(0)

    scale = np.float32(lr / n)
    mom = np.float32(cfg.momentum)
    wd = np.float32(cfg.weight_decay)
    sparsity = np.float32(lr * cfg.sparsity_cost) * (np.float32(cfg.sparsity_target) - h_pos.mean(0))
    for name, grad in (("wxf", g_wxf), ("wyf", g_wyf), ("whf", g_whf)):
        w, v = getattr(p, name), getattr(inc, name)
        v *= mom
        v += scale * grad - np.float32(lr) * wd * w
        w += v
    inc.bh *= mom
    inc.bh += scale * g_bh
    p.bh += inc.bh + sparsity
    inc.by *= mom
    inc.by += scale * g_by
    p.by += inc.by
    if cfg.normalize_filters:
        for w in (p.wxf, p.wyf):
            norms = np.linalg.norm(w, axis=0)
            w *= (norms.mean() / np.maximum(norms, 1e-12))[None, :]
    diff = y - y_neg
    return float(np.einsum("ij,ij->", diff, diff))


def _to_model(p: _Params, cfg: TrainConfig, whitening: Optional[_Whitening], meta: dict) -> GatedRBM:
    if whitening is None:
        return GatedRBM(
            wxf=p.wxf.copy(), wyf=p.wyf.copy(), whf=p.whf.copy(), bh=p.bh.copy(), by=p.by.copy(),
            patch_size=cfg.patch_size, output_units=cfg.output_units,
            normalization=cfg.normalization, contrast_floor=cfg.contrast_floor, meta=dict(meta),
        )
    # Fold the whitening into the filters: x_w @ wxf == x @ (forward @ wxf). Generating y in
    # pixels needs the inverse map on the output side.
    return GatedRBM(
        wxf=whitening.forward @ p.wxf,
        wyf=whitening.forward @ p.wyf,
        whf=p.whf.copy(),
        bh=p.bh.copy(),
        by=p.by @ whitening.backward,
        wyf_gen=whitening.backward.T @ p.wyf,
        patch_size=cfg.patch_size, output_units=cfg.output_units,
        normalization=cfg.normalization, contrast_floor=cfg.contrast_floor, meta=dict(meta),
    )


EpochCallback = Callable[[int, float, Callable[[], GatedRBM]], Optional[bool]]
BatchCallback = Callable[[int, int], None]


def _draw_pairs(source: PairSource, rng: np.random.Generator, epoch: int, *, cfg: TrainConfig,
                template: GatedRBM, whitening: Optional[_Whitening]) -> Tuple[np.ndarray, np.ndarray]:
    """One epoch's training pairs: ``source``'s raw pairs checked, prepared like the model's
    inputs, flat pairs dropped, whitened when ``whitening`` is given; two ``(N, D) float32``."""
    d = cfg.patch_size * cfg.patch_size
    x_raw, y_raw = source(rng, cfg.n_pairs, epoch)
    x_raw = np.asarray(x_raw, np.float32)
    y_raw = np.asarray(y_raw, np.float32)
    if x_raw.ndim != 2 or x_raw.shape != y_raw.shape or x_raw.shape[1] != d:
        raise ProcessingError(
            f"training data must be two (N, {d}) arrays of {cfg.patch_size}x{cfg.patch_size} "
            f"patches, got {x_raw.shape} and {y_raw.shape}"
        )
    x, y, flat = template.prepare(x_raw, y_raw)
    x, y = x[~flat], y[~flat]
    if len(x) < cfg.batch_size:
        raise ProcessingError(
            f"only {len(x)} of {len(flat)} training pairs have enough contrast "
            f"(need at least one batch of {cfg.batch_size})"
        )
    if whitening is not None:
        x, y = x @ whitening.forward, y @ whitening.forward
    return np.ascontiguousarray(x), np.ascontiguousarray(y)


def _initial_params(cfg: TrainConfig, n_vis: int) -> _Params:
    """Small random filters (from ``seed + 1``, apart from the data's generator), zero biases."""
    init = np.random.default_rng(cfg.seed + 1)
    return _Params(
        wxf=init.normal(0, cfg.init_scale, (n_vis, cfg.n_factors)).astype(np.float32),
        wyf=init.normal(0, cfg.init_scale, (n_vis, cfg.n_factors)).astype(np.float32),
        whf=init.normal(0, cfg.init_scale, (cfg.n_hidden, cfg.n_factors)).astype(np.float32),
        bh=np.zeros(cfg.n_hidden, np.float32),
        by=np.zeros(n_vis, np.float32),
    )


def _epoch_lr(cfg: TrainConfig, epoch: int) -> float:
    """The learning rate of ``epoch``: constant, or (``"linear"``) decaying to a tenth over the
    second half of the run."""
    if cfg.lr_schedule == "linear" and epoch >= cfg.epochs // 2:
        frac = (epoch - cfg.epochs // 2) / max(1, cfg.epochs - cfg.epochs // 2)
        return cfg.lr * (1.0 - 0.9 * frac)
    return cfg.lr


def _run_epoch(p: _Params, inc: _Params, x: np.ndarray, y: np.ndarray, *, cfg: TrainConfig,
               epoch: int, rng: np.random.Generator, on_batch: Optional[BatchCallback]) -> float:
    """One pass of CD-k updates over shuffled minibatches of ``x, y`` (``(N, D) float32``);
    returns the mean squared reconstruction error per pixel (non-finite if training blew up)."""
    lr = _epoch_lr(cfg, epoch)
    order = rng.permutation(len(x))
    total = 0.0
    n_used = 0
    for batch, b in enumerate(range(0, len(x) - cfg.batch_size + 1, cfg.batch_size)):
        sel = order[b : b + cfg.batch_size]
        # Overflow is caught by the divergence guard; numpy's warnings would only clutter the
        # progress bar.
        with np.errstate(over="ignore", invalid="ignore"):
            total += _cd_step(p, inc, x[sel], y[sel], cfg=cfg, lr=lr, rng=rng)
        n_used += len(sel)
        if on_batch is not None:
            on_batch(epoch, batch)
        if not math.isfinite(total):
            break  # no point finishing the epoch
    return total / (n_used * x.shape[1])


def _check_diverged(p: _Params, err: float, *, cfg: TrainConfig, epoch: int) -> None:
    """``ProcessingError`` if the epoch's error or the weights show that training diverged."""
    if not math.isfinite(err) or err > cfg.max_error or not all(np.all(np.isfinite(a)) for a in p.arrays()):
        raise ProcessingError(
            f"training diverged at epoch {epoch + 1} (reconstruction error {err:.3g}); "
            f"lower the learning rate (now {cfg.lr:g})"
            + ("" if cfg.whiten or cfg.output_units == "binary" else " or use --whiten")
        )


def train(
    source: PairSource,
    config: Optional[TrainConfig] = None,
    *,
    on_epoch: Optional[EpochCallback] = None,
    on_batch: Optional[BatchCallback] = None,
    data_description: str = "",
) -> TrainResult:
    """Train a gated RBM with CD-k on pairs from ``source``.

    Parameters
    ----------
    source : callable ``(rng, n, epoch) -> (X, Y)``
        Raw pairs, ``(n, p*p) float32`` each. Called once per epoch with ``fresh_pairs``, else
        once. Pairs :meth:`GatedRBM.prepare` flags as flat are dropped.
    config : TrainConfig
    on_epoch : callable ``(epoch, error, get_model) -> stop``, optional
        Called after every epoch with the mean squared reconstruction error per pixel and a
        function building the current model (cheap; only call it when needed). Returning
        ``True`` stops training.
    on_batch : callable ``(epoch, batch)``, optional
        Called after every minibatch update (both 0-based), e.g. for a finer progress display.
        A ``KeyboardInterrupt`` raised here is treated like Ctrl-C.
    data_description : str
        Recorded in the model's ``meta``.

    Returns
    -------
    TrainResult

    Raises
    ------
    ProcessingError
        Training diverged (non-finite or exploding reconstruction error or weights), or the
        source yields no usable pairs.
    TrainingInterrupted
        Ctrl-C after at least one finished epoch (before that: a plain KeyboardInterrupt).
    """
    cfg = config or TrainConfig()
    cfg.check()
    rng = np.random.default_rng(cfg.seed)
    template = GatedRBM.create(
        patch_size=cfg.patch_size, n_factors=1, n_hidden=1, output_units=cfg.output_units,
        normalization=cfg.normalization, contrast_floor=cfg.contrast_floor,
    )
    whitening: Optional[_Whitening] = None
    x, y = _draw_pairs(source, rng, 0, cfg=cfg, template=template, whitening=None)
    if cfg.whiten:
        whitening = _fit_whitening(x, y, cfg.whiten_variance)
        x, y = x @ whitening.forward, y @ whitening.forward
    p = _initial_params(cfg, x.shape[1])
    inc = _Params(*(np.zeros_like(a) for a in p.arrays()))
    meta = {
        "data": data_description,
        "training": asdict(cfg),
        "whitened_components": None if whitening is None else int(whitening.forward.shape[1]),
    }
    errors: List[float] = []
    start = time.perf_counter()

    def result(params: _Params, epochs_run: int, stopped_early: bool) -> TrainResult:
        seconds = time.perf_counter() - start
        meta["epochs"] = epochs_run
        meta["train_seconds"] = round(seconds, 2)
        meta["final_error"] = errors[epochs_run - 1] if epochs_run else None
        return TrainResult(model=_to_model(params, cfg, whitening, meta), errors=errors[:epochs_run],
                           seconds=seconds, epochs_run=epochs_run, stopped_early=stopped_early)

    # The weights after the last finished epoch: Ctrl-C mid-epoch (even mid-update) keeps these,
    # which passed the divergence guard. Copying them costs far less than an epoch.
    finished: Optional[_Params] = None
    done = 0  # epochs finished
    stopped = False
    epoch = -1
    try:
        for epoch in range(cfg.epochs):
            if epoch > 0 and cfg.fresh_pairs:
                x, y = _draw_pairs(source, rng, epoch, cfg=cfg, template=template, whitening=whitening)
            err = _run_epoch(p, inc, x, y, cfg=cfg, epoch=epoch, rng=rng, on_batch=on_batch)
            errors.append(err)
            _check_diverged(p, err, cfg=cfg, epoch=epoch)
            finished, done = _Params(*(a.copy() for a in p.arrays())), epoch + 1
            if on_epoch is not None:
                meta["epochs"] = epoch + 1
                if on_epoch(epoch, err, lambda: _to_model(p, cfg, whitening, meta)):
                    stopped = True
                    break
    except KeyboardInterrupt:
        if finished is None:
            raise  # nothing worth keeping yet
        meta["interrupted"] = True
        raise TrainingInterrupted(result(finished, done, True)) from None
    return result(p, epoch + 1, stopped)


# ---------------------------------------------------------------------------------- evaluation


def evaluate_translation(
    model: GatedRBM,
    *,
    max_shift: int = 1,
    n: int = 1000,
    seed: int = 12345,
    density: float = 0.1,
    radius: Optional[int] = None,
) -> Dict[str, float]:
    """Accuracy on ``n`` fresh translated-dot pairs.

    Returns
    -------
    dict with
        ``patch_accuracy``: fraction of pairs whose :func:`~bgsub.model.readout.patch_displacements`
        (integer, ``max_disp=max_shift``) equals the true shift;
        ``pixel_accuracy``: fraction of 'on' input pixels at least ``max_shift`` from the border
        whose max-flow target (full field, or windowed with ``radius``) is the true shift.
    """
    from bgsub.model.readout import max_flow_field, patch_displacements

    rng = np.random.default_rng(seed)
    src = TranslatedDots(patch_size=model.patch_size, max_shift=max_shift, density=density)
    xr, yr, shifts = src.sample(rng, n)
    x, y, flat = model.prepare(xr, yr)
    h = model.hidden_probs(x, y)
    disp, _ = patch_displacements(model, x, y, max_disp=max_shift, subpixel=False, h=h)
    patch_ok = np.all(disp == shifts, axis=1)
    flow = max_flow_field(model, x, h=h, radius=radius)
    p = model.patch_size
    inner = np.zeros((p, p), bool)
    inner[max_shift : p - max_shift, max_shift : p - max_shift] = True
    on = (x.reshape(n, p, p) > 0.5) & inner[None]
    pix_ok = np.all(flow == shifts[:, None, None, :], axis=3)
    return {
        "patch_accuracy": float(patch_ok.mean()),
        "pixel_accuracy": float(pix_ok[on].mean()) if on.any() else float("nan"),
        "n_pairs": int(n),
        "n_flat": int(flat.sum()),
    }


def evaluate_rotation(
    model: GatedRBM,
    *,
    max_angle: float = 30.0,
    n: int = 1000,
    seed: int = 12345,
    density: float = 0.1,
    radius: Optional[int] = None,
) -> Dict[str, float]:
    """Angle recovery on ``n`` fresh rotated-dot pairs.

    The max-flow vectors of the 'on' input pixels are fitted with a RANSAC similarity
    (:func:`cv2.estimateAffinePartial2D`), whose rotation is compared with the true angle.

    Returns
    -------
    dict with ``median_angle_error`` and ``mean_angle_error`` (degrees, over pairs with a fit),
    ``within_5deg`` (fraction of all pairs), ``n_fitted``.
    """
    import cv2

    from bgsub.model.readout import max_flow_field

    rng = np.random.default_rng(seed)
    src = RotatedDots(patch_size=model.patch_size, max_angle=max_angle, density=density)
    xr, yr, angles = src.sample(rng, n)
    x, y, _ = model.prepare(xr, yr)
    flow = max_flow_field(model, x, y, radius=radius)
    p = model.patch_size
    gy, gx = np.mgrid[0:p, 0:p].astype(np.float32)
    errs = np.full(n, np.nan)
    on_all = x.reshape(n, p, p) > 0.5
    for k in range(n):  # one small RANSAC per pair; evaluation only
        on = on_all[k]
        if on.sum() < 3:
            continue
        src_pts = np.stack([gx[on], gy[on]], axis=1)
        dst_pts = src_pts + flow[k][on]
        m, _ = cv2.estimateAffinePartial2D(src_pts, dst_pts, method=cv2.RANSAC, ransacReprojThreshold=1.0)
        if m is None:
            continue
        est = math.degrees(math.atan2(m[1, 0], m[0, 0]))
        errs[k] = abs((est - angles[k] + 180.0) % 360.0 - 180.0)
    ok = np.isfinite(errs)
    return {
        "median_angle_error": float(np.median(errs[ok])) if ok.any() else float("nan"),
        "mean_angle_error": float(np.mean(errs[ok])) if ok.any() else float("nan"),
        "within_5deg": float(np.mean(np.where(ok, errs, np.inf) <= 5.0)),
        "n_fitted": int(ok.sum()),
        "n_pairs": int(n),
    }


def evaluate_shifted(model: GatedRBM, source, *, n: int = 1000, seed: int = 12345, max_disp: int = 3) -> Dict[str, float]:
    """Patch displacements on ``n`` pairs with known motion (e.g. held-out shifted photos).

    Parameters
    ----------
    source : object with ``sample(rng, n) -> s`` where ``s.x, s.y`` are raw ``(n, p*p)`` patches
        and ``s.disp`` the true ``(n, 2)`` displacement (:class:`bgsub.model.imagedata.ShiftedImagePairs`).

    Returns
    -------
    dict with ``within_1px`` (fraction of all pairs whose sub-pixel estimate is within 1 px,
    Euclidean, of the truth; flat pairs count as misses), ``median_error_px`` and ``flat``.
    """
    from bgsub.model.readout import patch_displacements

    sample = source.sample(np.random.default_rng(seed), n)
    x, y, flat = model.prepare(sample.x, sample.y)
    disp, _ = patch_displacements(model, x, y, max_disp=max_disp)
    err = np.linalg.norm(disp - np.asarray(sample.disp, np.float32), axis=1)
    err[flat] = np.inf
    return {
        "within_1px": float(np.mean(err <= 1.0)),
        "median_error_px": float(np.median(err)),
        "flat": float(flat.mean()),
    }
