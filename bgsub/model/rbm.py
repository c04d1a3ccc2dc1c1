"""The factored gated (three-way) RBM of Memisevic & Hinton (2010).

The model is conditional: given a patch ``x`` (frame ``t``) it defines ``p(y, h | x)`` over the
patch ``y`` (frame ``t+1``) and binary mapping units ``h``. The three-way weight tensor
``W[i, j, k] = sum_f wxf[i, f] * wyf[j, f] * whf[k, f]`` is never formed; everything goes
through the factor projections ``Fx = x @ wxf``, ``Fy = y @ wyf``, ``Fh = h @ whf``::

    p(h = 1 | x, y) = sigmoid((Fx * Fy) @ whf.T + bh)
    p(y = 1 | x, h) = sigmoid((Fx * Fh) @ wyf.T + by)      binary output units
    E[y | x, h]     =         (Fx * Fh) @ wyf.T + by       Gaussian output units (unit variance)

Patches are flattened row-major (``p * p`` values). Raw patches are gray values in [0, 1] (what
:mod:`bgsub.model.tiling` cuts); :meth:`GatedRBM.prepare` turns them into model inputs (per-patch mean
removal and a contrast scale shared by ``x`` and ``y`` for real images, nothing for random dots)
and flags patches too flat to carry motion. A model trained on PCA-whitened inputs has the
whitening folded into its filters, so its inputs are always (normalised) pixels.

Model files are ``.npz`` archives read with ``allow_pickle=False``; anything malformed raises
:class:`~bgsub.errors.ModelError`. Their format lives in :mod:`bgsub.model.model_file`;
:meth:`GatedRBM.save`, :meth:`GatedRBM.load` and :func:`load_model` here call into it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from bgsub.errors import InputError, ModelError
from bgsub.model import model_file
from bgsub.model.model_file import ARRAY_NAMES as _ARRAYS
from bgsub.model.model_file import FORMAT_VERSION, RANGE_KEYS, SHIPPED_MODELS, load_model

__all__ = [
    "FORMAT_VERSION",
    "RANGE_KEYS",
    "SHIPPED_MODELS",
    "GatedRBM",
    "load_model",
    "sigmoid",
]

OUTPUT_UNITS = ("binary", "gaussian")
NORMALIZATIONS = ("none", "contrast")

#: Smallest patch side a model may have: a patch of 1 or 2 pixels has no centre pixel with a
#: neighbour on each side, so it shows no motion (and the patch grids assume a centre).
MIN_PATCH_SIZE = 3


def sigmoid(a: np.ndarray) -> np.ndarray:
    """Logistic function, float32 in and out, without overflow warnings."""
    # Clipping keeps exp() finite; sigmoid(+-60) is 0 or 1 to float32 precision anyway.
    out = np.clip(a, -60.0, 60.0)
    np.negative(out, out=out)
    np.exp(out, out=out)
    out += 1.0
    np.reciprocal(out, out=out)
    return out


@dataclass
class GatedRBM:
    """A factored gated RBM over ``patch_size`` x ``patch_size`` patches.

    Attributes
    ----------
    wxf : (n_in, F) float32
        Input (frame ``t``) filters.
    wyf : (n_out, F) float32
        Output (frame ``t+1``) filters, used to infer ``h``.
    whf : (K, F) float32
        Mapping-unit to factor weights.
    bh : (K,) float32
        Mapping-unit biases.
    by : (n_out,) float32
        Output biases.
    patch_size : int
        ``p`` (at least :data:`MIN_PATCH_SIZE`); ``n_in == n_out == p * p``.
    output_units : {"binary", "gaussian"}
        Binary (random dots) or unit-variance Gaussian (normalised real images).
    normalization : {"none", "contrast"}
        ``"none"``: patches are used as they are (binary dots). ``"contrast"``: each patch loses
        its mean and a pair shares one contrast scale, at least ``contrast_floor``.
    contrast_floor : float
        Pairs whose RMS contrast (of gray values in [0, 1]) is below this (above 0) are flagged
        flat.
    wyf_gen : (n_out, F) float32 or None
        Output filters used to *generate* ``y`` when they differ from ``wyf`` (a whitened model
        folded back to pixels); ``None`` means ``wyf``.
    meta : dict
        JSON-serialisable record: training settings, data, measured accuracy.
    """

    wxf: np.ndarray
    wyf: np.ndarray
    whf: np.ndarray
    bh: np.ndarray
    by: np.ndarray
    patch_size: int
    output_units: str = "binary"
    normalization: str = "none"
    contrast_floor: float = 0.02
    wyf_gen: Optional[np.ndarray] = None
    meta: Dict[str, Any] = field(default_factory=dict)
    # Per-model caches of the readouts (see bgsub.model.readout); cleared by `invalidate()`.
    _cache: Dict[Any, Any] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in _ARRAYS:
            setattr(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.float32))
        if self.wyf_gen is not None:
            self.wyf_gen = np.ascontiguousarray(self.wyf_gen, dtype=np.float32)
        self.patch_size = int(self.patch_size)
        self.contrast_floor = float(self.contrast_floor)
        problem = self._shape_problem()
        if problem:
            raise ModelError(f"inconsistent gated RBM: {problem}")

    # ------------------------------------------------------------------ construction

    @classmethod
    def create(
        cls,
        *,
        patch_size: int = 13,
        n_factors: int = 200,
        n_hidden: int = 100,
        output_units: str = "binary",
        normalization: str = "none",
        contrast_floor: float = 0.02,
        init_scale: float = 0.01,
        rng: Optional[np.random.Generator] = None,
    ) -> "GatedRBM":
        """A fresh model with small random filters and zero biases.

        Parameters
        ----------
        patch_size, n_factors, n_hidden : int
        output_units : {"binary", "gaussian"}
        normalization : {"none", "contrast"}
        contrast_floor : float
        init_scale : float
            Standard deviation of the initial filters.
        rng : numpy.random.Generator, optional
            Seeded generator (default: seed 0, so creation is reproducible).
        """
        rng = rng if rng is not None else np.random.default_rng(0)
        n = patch_size * patch_size
        return cls(
            wxf=rng.normal(0.0, init_scale, (n, n_factors)).astype(np.float32),
            wyf=rng.normal(0.0, init_scale, (n, n_factors)).astype(np.float32),
            whf=rng.normal(0.0, init_scale, (n_hidden, n_factors)).astype(np.float32),
            bh=np.zeros(n_hidden, np.float32),
            by=np.zeros(n, np.float32),
            patch_size=patch_size,
            output_units=output_units,
            normalization=normalization,
            contrast_floor=contrast_floor,
        )

    # ------------------------------------------------------------------ sizes

    @property
    def n_in(self) -> int:
        return self.wxf.shape[0]

    @property
    def n_out(self) -> int:
        return self.wyf.shape[0]

    @property
    def n_factors(self) -> int:
        return self.wxf.shape[1]

    @property
    def n_hidden(self) -> int:
        return self.whf.shape[0]

    def invalidate(self) -> None:
        """Forget cached readout matrices; call after changing the weights in place."""
        self._cache.clear()

    # ------------------------------------------------------------------ inputs

    def prepare(self, x_raw: np.ndarray, y_raw: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Raw patch pairs -> model inputs.

        Parameters
        ----------
        x_raw, y_raw : (N, p*p) float32
            Patches of frames ``t`` and ``t+1``, gray values in [0, 1] (binary 0/1 for dots).

        Raises
        ------
        InputError
            Unless ``x_raw`` and ``y_raw`` are both ``(N, p*p)``.

        Returns
        -------
        x, y : (N, p*p) float32
            Model inputs. For ``normalization="contrast"`` each patch has zero mean and the pair
            is divided by one shared scale ``max(rms, contrast_floor)`` so a brightness or
            contrast change between the frames is not mistaken for motion.
        flat : (N,) bool
            Pairs that carry no usable motion signal (constant patch, or RMS contrast below
            ``contrast_floor``). Their inputs are still returned, but readouts on them are noise.
        """
        x = np.asarray(x_raw, dtype=np.float32)
        y = np.asarray(y_raw, dtype=np.float32)
        self._check_pair(x, y, "raw patches")
        if self.normalization == "none":
            flat = (np.ptp(x, axis=1) <= 1e-6) | (np.ptp(y, axis=1) <= 1e-6)
            return x.copy(), y.copy(), flat
        x = x - x.mean(axis=1, keepdims=True)
        y = y - y.mean(axis=1, keepdims=True)
        rms = np.sqrt(0.5 * (np.mean(x * x, axis=1) + np.mean(y * y, axis=1)))
        flat = rms < self.contrast_floor
        scale = np.maximum(rms, np.float32(self.contrast_floor))[:, None]
        return (x / scale).astype(np.float32), (y / scale).astype(np.float32), flat

    def _check_pair(self, x: np.ndarray, y: np.ndarray, what: str) -> None:
        """``InputError`` unless ``x`` is ``(N, n_in)`` and ``y`` is ``(N, n_out)`` (shapes
        only: called once per batch)."""
        xs, ys = np.shape(x), np.shape(y)
        if (len(xs) != 2 or len(ys) != 2 or xs[0] != ys[0] or xs[1] != self.n_in
                or ys[1] != self.n_out):
            p = self.patch_size
            raise InputError(f"{what} x and y must both be (N, {self.n_in}): N patches of "
                             f"{p}x{p} pixels (the model's size), not {xs} and {ys}")

    # ------------------------------------------------------------------ inference

    def hidden_probs(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``p(h = 1 | x, y)``.

        Parameters
        ----------
        x, y : (N, n_in), (N, n_out) float32 model inputs (see :meth:`prepare`)

        Returns
        -------
        (N, K) float32

        Raises
        ------
        InputError
            Unless ``x`` and ``y`` are ``(N, p*p)`` with the same ``N``.
        """
        self._check_pair(x, y, "model inputs")
        fx = x @ self.wxf
        fx *= y @ self.wyf
        return sigmoid(fx @ self.whf.T + self.bh)

    def output_activation(self, x: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Total input to the output units, ``(Fx * Fh) @ wyf.T + by``: ``(N, n_out) float32``."""
        w = self.wyf if self.wyf_gen is None else self.wyf_gen
        f = x @ self.wxf
        f *= h @ self.whf
        return f @ w.T + self.by

    def output_probs(self, x: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Expected output ``E[y | x, h]``.

        Parameters
        ----------
        x : (N, n_in) float32 model inputs
        h : (N, K) float32 mapping-unit states or probabilities

        Returns
        -------
        (N, n_out) float32: probabilities (binary units) or means (Gaussian units).
        """
        a = self.output_activation(x, h)
        return sigmoid(a) if self.output_units == "binary" else a

    def factor_gains(self, h: np.ndarray) -> np.ndarray:
        """``h @ whf``: how strongly each factor is switched on, ``(N, F) float32``."""
        return np.asarray(h, np.float32) @ self.whf

    # ------------------------------------------------------------------ checks and files

    def _shape_problem(self) -> str:
        if self.patch_size < MIN_PATCH_SIZE:
            return (f"patch_size must be at least {MIN_PATCH_SIZE} (smaller patches cannot show "
                    f"motion), not {self.patch_size}")
        if not (np.isfinite(self.contrast_floor) and self.contrast_floor > 0):
            return f"contrast_floor must be a number above 0, not {self.contrast_floor!r}"
        n_f = self.wxf.shape[1] if self.wxf.ndim == 2 else -1
        expect = {
            "wxf": (self.patch_size**2, n_f),
            "wyf": (self.patch_size**2, n_f),
            "whf": (self.whf.shape[0] if self.whf.ndim == 2 else -1, n_f),
        }
        for name in ("wxf", "wyf", "whf"):
            arr = getattr(self, name)
            if arr.ndim != 2 or arr.shape != expect[name]:
                return f"{name} has shape {arr.shape}, expected {expect[name]} for {self.patch_size}x{self.patch_size} patches"
        if n_f < 1 or self.whf.shape[0] < 1:
            return (f"it needs at least one factor and one mapping unit, not {n_f} and "
                    f"{self.whf.shape[0]}")
        if self.bh.shape != (self.whf.shape[0],):
            return f"bh has shape {self.bh.shape}, expected ({self.whf.shape[0]},)"
        if self.by.shape != (self.wyf.shape[0],):
            return f"by has shape {self.by.shape}, expected ({self.wyf.shape[0]},)"
        if self.wyf_gen is not None and self.wyf_gen.shape != self.wyf.shape:
            return f"wyf_gen has shape {self.wyf_gen.shape}, expected {self.wyf.shape}"
        if self.output_units not in OUTPUT_UNITS:
            return f"unknown output units {self.output_units!r} (expected one of {', '.join(OUTPUT_UNITS)})"
        if self.normalization not in NORMALIZATIONS:
            return f"unknown normalization {self.normalization!r} (expected one of {', '.join(NORMALIZATIONS)})"
        for name in _ARRAYS + (("wyf_gen",) if self.wyf_gen is not None else ()):
            if not np.all(np.isfinite(getattr(self, name))):
                return f"{name} holds non-finite values"
        return ""

    def save(self, path: Union[str, Path], *, overwrite: bool = True) -> Path:
        """Write the model as an ``.npz`` archive (float32 arrays + a JSON header); see
        :func:`bgsub.model.model_file.write_model`.

        Parameters
        ----------
        path : str or Path
        overwrite : bool
            Refuse (``OutputError``) to replace an existing file when false.

        Returns
        -------
        Path written.
        """
        return model_file.write_model(self, path, overwrite=overwrite)

    @classmethod
    def load(cls, path: Union[str, Path]) -> "GatedRBM":
        """Read a model written by :meth:`save`; :class:`ModelError` if it is not a valid one."""
        return model_file.read_model(path, model_class=cls)
