"""Reading motion out of a gated RBM: max-flow fields, patch displacements, analogies.

Given the mapping units ``h`` inferred from a patch pair, the model's three-way tensor collapses
to a matrix from input pixel ``i`` to output pixel ``j``::

    M[i, j] = sum_f wxf[i, f] * wyf[j, f] * g[f],      g = h @ whf

* The **max-flow field** (paper, Algorithm 2) sends every input pixel to ``argmax_j M[i, j]``.
  The *windowed* variant only looks at targets within ``radius`` pixels (Chebyshev distance) of
  ``i``; for translations it gives the same answer and is several times cheaper.
* The **patch displacement** is ``argmax_d sum_i M[i, i + d]`` over displacements ``d`` with
  ``|dx|, |dy| <= max_disp``. Because the sum over ``i`` does not depend on ``h``, it is folded
  once per model into ``C[d, f] = sum_i wxf[i, f] * wyf[i + d, f]``, and further into
  ``whf @ C.T``, so the scores of all patches are one small matmul ``h @ (whf @ C.T)``.
* :func:`raw_patch_motion` is the fast path the motion front end uses: the contrast
  normalisation is folded into the projections (:func:`patch_features`), so raw patches go
  straight to displacements with three matmuls.
* An **analogy** (paper, Figure 7) infers ``h`` from ``(x, y)`` and applies it to a new ``x2``.

All functions take model inputs (see :meth:`bgsub.model.rbm.GatedRBM.prepare`) as ``(N, p*p) float32``
and work on all patches at once. Displacements follow the package convention: ``(dx, dy)`` is
where a pixel of ``x`` went in ``y``.
"""

from __future__ import annotations

import contextlib
import threading
from typing import Optional, Tuple

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.model.rbm import GatedRBM

__all__ = [
    "displacement_offsets",
    "displacement_scores",
    "patch_displacements",
    "PatchFeatures",
    "patch_features",
    "raw_patch_motion",
    "precompute",
    "max_flow_field",
    "max_flow_image",
    "analogy",
    "analogy_images",
]

# Patches per chunk in the per-pixel readouts, to bound the (chunk, p*p, targets) score array.
_CHUNK = 256


def displacement_offsets(max_disp: int) -> np.ndarray:
    """All integer displacements with ``|dx|, |dy| <= max_disp``.

    Returns
    -------
    (D, 2) int64 ``[dx, dy]``, ``D = (2 * max_disp + 1) ** 2``, row-major over ``(dy, dx)``
    (so index ``(dy + r) * (2r + 1) + (dx + r)``).
    """
    r = int(max_disp)
    if r < 0:
        raise ValueError(f"max_disp must be >= 0, not {max_disp}")
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    return np.stack([dx.ravel(), dy.ravel()], axis=1)


def _hidden(model: GatedRBM, x: np.ndarray, y: Optional[np.ndarray], h: Optional[np.ndarray]) -> np.ndarray:
    if h is None:
        if y is None:
            raise ValueError("give y (to infer h) or h")
        h = model.hidden_probs(x, y)
    return np.asarray(h, dtype=np.float32)


def _pair_products(model: GatedRBM, radius: int) -> Tuple[np.ndarray, np.ndarray]:
    """``T[i, o, f] = wxf[i, f] * wyf[i + offset_o, f]`` (zero where ``i + offset`` leaves the patch).

    Returns ``T`` as ``(p*p * O, F) float32`` and a ``(p*p, O) bool`` validity mask. Cached.
    """
    key = ("pairs", int(radius))
    if key not in model._cache:
        p = model.patch_size
        offsets = displacement_offsets(radius)
        wx = model.wxf.reshape(p, p, -1)
        wy = model.wyf.reshape(p, p, -1)
        n_f = wx.shape[2]
        out = np.zeros((p, p, len(offsets), n_f), np.float32)
        valid = np.zeros((p, p, len(offsets)), bool)
        for o, (dx, dy) in enumerate(offsets):  # once per model and radius
            ys = slice(max(0, -dy), min(p, p - dy))
            xs = slice(max(0, -dx), min(p, p - dx))
            yt = slice(ys.start + dy, ys.stop + dy)
            xt = slice(xs.start + dx, xs.stop + dx)
            out[ys, xs, o] = wx[ys, xs] * wy[yt, xt]
            valid[ys, xs, o] = True
        model._cache[key] = (out.reshape(p * p * len(offsets), n_f), valid.reshape(p * p, -1))
    return model._cache[key]


def _masked_pair_products(model: GatedRBM, radius: int) -> np.ndarray:
    """:func:`_pair_products` with one extra column: 0 for valid targets, -1e30 for targets
    outside the patch. Multiplied by gains with an extra 1, the matmul itself rules them out."""
    key = ("pairs-masked", int(radius))
    if key not in model._cache:
        pairs, valid = _pair_products(model, radius)
        penalty = np.where(valid.reshape(-1, 1), 0.0, -1e30).astype(np.float32)
        model._cache[key] = np.ascontiguousarray(np.hstack([pairs, penalty]))
    return model._cache[key]


def _displacement_filters(model: GatedRBM, max_disp: int) -> np.ndarray:
    """``C[d, f] = sum_i wxf[i, f] * wyf[i + d, f]`` over valid ``i``: ``(D, F) float32``. Cached."""
    key = ("disp", int(max_disp))
    if key not in model._cache:
        pairs, _ = _pair_products(model, max_disp)
        p2 = model.patch_size**2
        model._cache[key] = np.ascontiguousarray(
            pairs.reshape(p2, -1, pairs.shape[1]).sum(axis=0, dtype=np.float64).astype(np.float32)
        )
    return model._cache[key]


def displacement_scores(
    model: GatedRBM,
    x: np.ndarray,
    y: Optional[np.ndarray] = None,
    *,
    max_disp: int,
    h: Optional[np.ndarray] = None,
) -> np.ndarray:
    """``S[n, d] = sum_i M_n[i, i + d]`` for every displacement of :func:`displacement_offsets`.

    Parameters
    ----------
    model : GatedRBM
    x, y : (N, p*p) float32 model inputs (``y`` may be omitted when ``h`` is given)
    max_disp : int
    h : (N, K) float32, optional; inferred from ``(x, y)`` when omitted

    Returns
    -------
    (N, D) float32
    """
    h = _hidden(model, x, y, h)
    return h @ _hidden_displacement_filters(model, max_disp)


def _hidden_displacement_filters(model: GatedRBM, max_disp: int) -> np.ndarray:
    """``whf @ C.T``: scores straight from the mapping units, ``S = h @ (whf @ C.T)``
    (``(K, D) float32``, cached). Folding ``whf`` in saves the ``(N, F)`` factor gains."""
    key = ("disp-h", int(max_disp))
    if key not in model._cache:
        c = _displacement_filters(model, max_disp).astype(np.float64)
        model._cache[key] = np.ascontiguousarray((model.whf.astype(np.float64) @ c.T).astype(np.float32))
    return model._cache[key]


def patch_displacements(
    model: GatedRBM,
    x: np.ndarray,
    y: np.ndarray,
    *,
    max_disp: int,
    subpixel: bool = True,
    h: Optional[np.ndarray] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """One displacement per patch pair: ``argmax_d sum_i M[i, i + d]``.

    Parameters
    ----------
    model : GatedRBM
    x, y : (N, p*p) float32
        Model inputs from :meth:`GatedRBM.prepare`.
    max_disp : int
        Largest ``|dx|`` and ``|dy|`` considered.
    subpixel : bool
        Refine the integer peak by a parabola through it and its two neighbours along each axis
        (only where both neighbours exist; the shift is clipped to half a pixel).
    h : (N, K) float32, optional
        Mapping units when already inferred.

    Returns
    -------
    disp : (N, 2) float32
        ``[dx, dy]`` of each patch.
    confidence : (N,) float32
        In [0, 1]: how far the peak stands above the best score that is not adjacent to it,
        relative to the peak's height above the mean score. 0 means a rival peak as strong
        elsewhere (ambiguous patch), 1 a single clear peak. Neighbours of the peak are excluded
        so a true half-pixel motion (two equal neighbouring scores) is not called ambiguous.

    Raises
    ------
    InputError
        ``x`` and ``y`` (when ``h`` is inferred from them) are not both ``(N, p*p)``.
    """
    scores = displacement_scores(model, x, y, max_disp=max_disp, h=h)
    return _peaks(scores, int(max_disp), subpixel=subpixel)


def _peak_tables(r: int) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-displacement lookup tables for :func:`_peaks` (cached per ``r``): the offsets
    ``(D, 2) float32``, the indices of the left/right/up/down neighbours ``(D, 4) intp`` (both
    the index itself along an axis where ``d`` is on the window's edge), and the indices of the
    3x3 neighbourhood of ``d`` ``(D, 9) intp`` (neighbours outside the window replaced by ``d``
    itself)."""
    if r not in _PEAK_TABLES:
        offsets = displacement_offsets(r)
        side = 2 * r + 1
        idx = np.arange(side * side)
        row, col = np.divmod(idx, side)
        # A peak on the window's edge along an axis gets no sub-pixel shift along it: both its
        # neighbours there are itself (zero curvature).
        inx = (col > 0) & (col < side - 1)
        iny = (row > 0) & (row < side - 1)
        nb = np.stack([np.where(inx, idx - 1, idx), np.where(inx, idx + 1, idx),
                       np.where(iny, idx - side, idx), np.where(iny, idx + side, idx)], axis=1)
        block = []
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                ok = (row + dy >= 0) & (row + dy < side) & (col + dx >= 0) & (col + dx < side)
                block.append(np.where(ok, idx + dy * side + dx, idx))
        _PEAK_TABLES[r] = (offsets.astype(np.float32), nb.astype(np.intp),
                           np.stack(block, axis=1).astype(np.intp))
    return _PEAK_TABLES[r]


_PEAK_TABLES: dict = {}


def _peaks(scores: np.ndarray, r: int, *, subpixel: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """Displacement and confidence from ``(N, D)`` displacement scores (see
    :func:`patch_displacements`). Table lookups keep this to a few passes over the scores."""
    n, n_d = scores.shape
    offsets, nb, block = _peak_tables(int(r))
    best = np.argmax(scores, axis=1)
    base = np.arange(n) * n_d
    flat_scores = scores.reshape(-1)
    peak = flat_scores[base + best]
    disp = offsets[best]  # a copy (fancy indexing)

    if subpixel and r > 0:
        # Neighbours (left, right, up, down) of each peak (see _peak_tables); columns 0: dx
        # (left/right), 1: dy (up/down).
        lrud = flat_scores[base[:, None] + nb[best]]
        lo, hi = lrud[:, 0::2], lrud[:, 1::2]
        curv = lo - 2.0 * peak[:, None] + hi
        ok = curv < 0
        shift = np.zeros((n, 2), np.float32)
        shift[ok] = 0.5 * (lo[ok] - hi[ok]) / curv[ok]
        disp += np.clip(shift, -0.5, 0.5)

    # The strongest rival: the best score outside the 3x3 neighbourhood of the peak (or, when
    # the window has nothing outside it, the second-best score). Masked in a transposed copy:
    # a maximum over its rows is a few whole-row passes, over the short rows of scores a slow
    # reduction per row.
    masked = cv2.transpose(scores)
    masked.reshape(-1)[block[best] * n + np.arange(n)[:, None]] = -np.inf  # 9 writes per row
    rival = masked.max(axis=0)
    lone = ~np.isfinite(rival)
    if n_d > 1 and lone.any():
        rival[lone] = np.partition(scores[lone], -2, axis=1)[:, -2]
    height = peak - scores.mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        conf = np.where(height > 1e-12, (peak - rival) / height, 0.0)
    return disp, np.clip(conf, 0.0, 1.0).astype(np.float32)


class PatchFeatures:
    """One frame's side of a batch of raw patches, projected onto the model's filters once so
    it can be paired with several other batches (e.g. the first frame's patches against every
    pre-warp of the second).

    Attributes
    ----------
    proj : (N, F) float32
        ``prepared_patch @ filters`` before the pair's shared contrast scale (mean removed for
        ``normalization="contrast"``).
    energy : (N,) float32
        Mean squared (mean-removed) value per patch (``"contrast"``), else zeros.
    const : (N,) bool
        The patch is constant (``"none"``: flat-pair test).
    """

    __slots__ = ("proj", "energy", "const")

    def __init__(self, proj: np.ndarray, energy: np.ndarray, const: np.ndarray) -> None:
        self.proj, self.energy, self.const = proj, energy, const

    def take(self, index: np.ndarray) -> "PatchFeatures":
        """The features of the patches ``index`` (e.g. ``np.tile``-like repetition)."""
        return PatchFeatures(self.proj[index], self.energy[index], self.const[index])


def patch_features(model: GatedRBM, raw: np.ndarray, *, side: str) -> PatchFeatures:
    """Project raw patches onto the model's input (``side="x"``) or output (``"y"``) filters.

    Parameters
    ----------
    model : GatedRBM
    raw : (N, p*p) float32 raw patches in [0, 1]
    side : {"x", "y"}

    Returns
    -------
    PatchFeatures

    Notes
    -----
    The contrast normalisation of :meth:`GatedRBM.prepare` is linear per patch: removing the
    mean is projecting onto column-centred filters, and the pair's shared scale divides the
    factor product by ``scale**2``. So the raw patches are projected once (one matmul) and
    never copied into normalised form.
    """
    raw = np.ascontiguousarray(raw, dtype=np.float32)
    n = raw.shape[0]
    if model.normalization == "contrast":
        proj = raw @ _centred_filters(model, side)
        d = np.float32(raw.shape[1])
        mean = raw.sum(axis=1) / d
        energy = np.einsum("ij,ij->i", raw, raw) / d - mean * mean
        np.maximum(energy, 0.0, out=energy)
        const = np.zeros(n, bool)
    else:
        proj = raw @ (model.wxf if side == "x" else model.wyf)
        energy = np.zeros(n, np.float32)
        const = np.ptp(raw, axis=1) <= 1e-6 if n else np.zeros(0, bool)
    return PatchFeatures(proj, energy.astype(np.float32, copy=False), const)


def _centred_filters(model: GatedRBM, side: str) -> np.ndarray:
    """``W - colsum(W) / n``: ``(x - mean(x)) @ W == x @ (W - colsum(W) / n)``, so the mean
    removal of the contrast normalisation is folded into the filters. ``(n, F) float32``,
    cached."""
    key = ("centred", side)
    if key not in model._cache:
        w = (model.wxf if side == "x" else model.wyf).astype(np.float64)
        model._cache[key] = np.ascontiguousarray((w - w.mean(axis=0)).astype(np.float32))
    return model._cache[key]


def _half_hidden_weights(model: GatedRBM) -> Tuple[np.ndarray, np.ndarray]:
    """``(whf / 2, bh / 2)``, float32, cached. Halving is exact in floating point and commutes
    with every rounding of the matmul, the contrast scale and the bias, so the hidden units'
    ``a / 2`` comes out of them bit for bit as halving ``a`` afterwards would give it, without
    that extra pass over ``(N, K)``."""
    key = ("half-hidden",)
    if key not in model._cache:
        model._cache[key] = (np.ascontiguousarray(model.whf * np.float32(0.5)),
                             (model.bh * np.float32(0.5)).astype(np.float32))
    return model._cache[key]


def precompute(model: GatedRBM, *, max_disp: int) -> None:
    """Compute the per-model constants :func:`raw_patch_motion` needs (folded displacement
    filters, centred filters) now rather than on the first frame. They are cached on the model
    and reused until :meth:`GatedRBM.invalidate`. Also warms up OpenBLAS
    (:func:`_warm_blas`)."""
    _warm_blas()
    _hidden_displacement_filters(model, max_disp)
    _half_hidden_weights(model)
    if model.normalization == "contrast":
        _centred_filters(model, "x")
        _centred_filters(model, "y")


_BLAS_WARM = False


def _warm_blas(threads: int = 2) -> None:
    """Put OpenBLAS in its fast state for ``threads`` concurrent callers, once per process: one
    512 x 512 float32 matmul in each of ``threads`` threads at the same time.

    With numpy's bundled OpenBLAS (one thread), a readout-sized matmul (1,131 x 169 by 169 x
    200) is several times slower until a matmul with a large enough second operand has run, with
    bit-identical results either way; the readout's own matmuls never make the switch. The state
    belongs to the buffer OpenBLAS lends a call, and two calls running at once get two buffers:
    one matmul warms only one, and the engine's second thread (``overlap``) stayed slow while
    the calling thread was fast. Warming as many buffers as the engine has threads cures both.
    """
    global _BLAS_WARM
    if _BLAS_WARM:
        return
    a = np.ones((512, 512), np.float32)
    together = threading.Barrier(threads)

    def multiply() -> None:
        with contextlib.suppress(threading.BrokenBarrierError):
            together.wait(timeout=5)
        a @ a

    helpers = [threading.Thread(target=multiply, daemon=True) for _ in range(threads - 1)]
    for helper in helpers:
        helper.start()
    multiply()
    for helper in helpers:
        helper.join()
    _BLAS_WARM = True


def raw_patch_motion(
    model: GatedRBM,
    x_raw: Optional[np.ndarray],
    y_raw: np.ndarray,
    *,
    max_disp: int,
    x_features: Optional[PatchFeatures] = None,
    subpixel: bool = True,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`GatedRBM.prepare` + :func:`patch_displacements` on raw patches, fused.

    Same result as ``patch_displacements(model, *model.prepare(x_raw, y_raw)[:2])`` (to float32
    rounding) with fewer passes over the data: the normalisation is folded into the projections
    (:func:`patch_features`) and the displacement filters into the mapping-unit weights.

    Parameters
    ----------
    model : GatedRBM
    x_raw : (N, p*p) float32 raw patches in [0, 1], or None when ``x_features`` is given
    y_raw : (N, p*p) float32
    max_disp : int
    x_features : PatchFeatures, optional
        ``patch_features(model, x_raw, side="x")`` when already computed (reused across reads).

    Returns
    -------
    disp : (N, 2) float32
    confidence : (N,) float32, 0 for flat pairs
    flat : (N,) bool
    """
    fx = x_features if x_features is not None else patch_features(model, x_raw, side="x")
    fy = patch_features(model, y_raw, side="y")
    # Factor products in place in fy's projections (fy is ours; fx may be a caller's cache).
    f = np.multiply(fy.proj, fx.proj, out=fy.proj)
    half_whf, half_bh = _half_hidden_weights(model)
    a = f @ half_whf.T  # a / 2 of sigmoid(a) = (1 + tanh(a / 2)) / 2, exactly (see there)
    if model.normalization == "contrast":
        rms = np.sqrt(0.5 * (fx.energy + fy.energy))
        flat = rms < model.contrast_floor
        scale = np.maximum(rms, np.float32(model.contrast_floor))
        # The pair's shared scale divides both projections: 1 / scale**2 on their product, applied
        # after the (linear) matmul to the narrower (N, K) array.
        a *= (1.0 / (scale * scale)).astype(np.float32)[:, None]
    else:
        flat = fx.const | fy.const
    a += half_bh
    # sigmoid(a) = (1 + tanh(a / 2)) / 2: fewer passes than 1 / (1 + exp(-a)), no overflow.
    h = np.tanh(a, out=a)
    h *= np.float32(0.5)
    h += np.float32(0.5)
    scores = h @ _hidden_displacement_filters(model, max_disp)
    disp, conf = _peaks(scores, int(max_disp), subpixel=subpixel)
    conf[flat] = 0.0
    return disp, conf, flat


def max_flow_field(
    model: GatedRBM,
    x: np.ndarray,
    y: Optional[np.ndarray] = None,
    *,
    radius: Optional[int] = None,
    h: Optional[np.ndarray] = None,
) -> np.ndarray:
    """The max-flow field: for every input pixel ``i``, the offset to ``argmax_j M[i, j]``.

    Parameters
    ----------
    model : GatedRBM
    x, y : (N, p*p) float32 model inputs (``y`` may be omitted when ``h`` is given)
    radius : int, optional
        Only consider targets ``j`` within this Chebyshev distance of ``i`` (windowed max-flow;
        cost ``O(p^2 (2r+1)^2 F)`` per patch instead of ``O(p^4 F)``). ``None``: all ``p*p``
        targets, as in the paper.
    h : (N, K) float32, optional

    Returns
    -------
    (N, p, p, 2) float32
        ``[dx, dy]`` per input pixel (row-major over the patch): where pixel ``(row, col)`` of
        ``x`` goes, ``y[row + dy, col + dx]``.
    """
    h = _hidden(model, x, y, h)
    p = model.patch_size
    p2 = p * p
    g = model.factor_gains(h)
    n = g.shape[0]
    flow = np.empty((n, p2, 2), np.float32)
    if radius is None or radius >= p - 1:
        # All targets: T[i, j, f] = wxf[i, f] * wyf[j, f], argmax over j.
        key = ("full",)
        if key not in model._cache:
            model._cache[key] = (model.wxf[:, None, :] * model.wyf[None, :, :]).reshape(p2 * p2, -1)
        full = model._cache[key]
        coords = np.stack(np.meshgrid(np.arange(p), np.arange(p)), axis=2).reshape(p2, 2).astype(np.float32)
        for start in range(0, n, _CHUNK):
            stop = min(n, start + _CHUNK)
            target = np.argmax((g[start:stop] @ full.T).reshape(stop - start, p2, p2), axis=2)
            flow[start:stop] = coords[target] - coords[None, :, :]
        return flow.reshape(n, p, p, 2)
    pairs = _masked_pair_products(model, radius)
    offsets = displacement_offsets(radius).astype(np.float32)
    n_off = offsets.shape[0]
    g1 = np.hstack([g, np.ones((n, 1), np.float32)])
    for start in range(0, n, _CHUNK):
        stop = min(n, start + _CHUNK)
        m = (g1[start:stop] @ pairs.T).reshape(stop - start, p2, n_off)
        flow[start:stop] = offsets[np.argmax(m, axis=2)]
    return flow.reshape(n, p, p, 2)


def _patch_origins(size: int, p: int, stride: int) -> np.ndarray:
    """Top-left offsets of patches along one axis of ``size`` pixels: every ``stride``, plus
    one flush with the far edge so that every pixel is covered. ``(n,) intp``."""
    starts = list(range(0, size - p + 1, stride))
    if starts[-1] != size - p:
        starts.append(size - p)
    return np.asarray(starts, np.intp)


def _nearest_origin(size: int, starts: np.ndarray, p: int) -> np.ndarray:
    """For each pixel along an axis, the index of the patch (origins ``starts``) whose centre
    is nearest: ``(size,) intp``. That patch holds the pixel farthest from its own border,
    where max-flow targets are least often cut off by the patch edge."""
    centres = starts + (p - 1) / 2.0
    return np.argmin(np.abs(np.arange(size)[:, None] - centres[None, :]), axis=1)


def max_flow_image(
    model: GatedRBM,
    image1: np.ndarray,
    image2: np.ndarray,
    *,
    stride: int,
    radius: Optional[int] = None,
) -> np.ndarray:
    """The max-flow field (paper, Algorithm 2) of two whole images, pixel by pixel.

    Patches are cut every ``stride`` pixels (and flush with the far edges); every pixel takes
    the max-flow vector it has in the patch whose centre is nearest. An image of one patch's
    size is the paper's setup: one patch pair, one max-flow vector per pixel.

    Parameters
    ----------
    model : GatedRBM
    image1, image2 : (H, W) gray or (H, W, 3) BGR images of one size, ``H, W >= p``; uint8
        0-255 or float in [0, 1] (see :func:`bgsub.model.tiling.to_gray`)
    stride : int
        Patch step, 1 to ``p``.
    radius : int, optional
        Windowed max-flow (see :func:`max_flow_field`); None: all targets, as in the paper.

    Returns
    -------
    (H, W, 2) float32
        ``(dx, dy)`` per pixel of ``image1``; NaN where the patch pair is flat (no contrast:
        nothing to read).

    Raises
    ------
    InputError
        Images of different sizes or smaller than a patch, ``stride`` outside 1 to ``p``.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    from bgsub.model.tiling import to_gray

    p = model.patch_size
    if not isinstance(stride, (int, np.integer)) or not 1 <= stride <= p:
        raise InputError(f"stride must be from 1 to the model's patch size {p}, not {stride}")
    g1, g2 = to_gray(image1), to_gray(image2)
    if g1.shape != g2.shape or min(g1.shape) < p:
        raise InputError(f"max-flow needs two images of one size, at least {p}x{p}, not "
                         f"{g1.shape[1]}x{g1.shape[0]} and {g2.shape[1]}x{g2.shape[0]}")
    hgt, wid = g1.shape
    ys, xs = _patch_origins(hgt, p, stride), _patch_origins(wid, p, stride)

    def cut(img: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(sliding_window_view(img, (p, p))[np.ix_(ys, xs)]
                                    ).reshape(-1, p * p)

    x, y, flat = model.prepare(cut(g1), cut(g2))
    flow = max_flow_field(model, x, y, radius=radius)  # (N, p, p, 2)
    flow[flat] = np.nan
    iy, ix = _nearest_origin(hgt, ys, p), _nearest_origin(wid, xs, p)
    rows, cols = np.arange(hgt), np.arange(wid)
    patch = iy[:, None] * len(xs) + ix[None, :]
    return flow[patch, (rows - ys[iy])[:, None], (cols - xs[ix])[None, :]]


def analogy(model: GatedRBM, x: np.ndarray, y: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Apply the transformation that takes ``x`` to ``y`` to ``x2`` (paper, Figure 7).

    Parameters
    ----------
    x, y, x2 : (N, p*p) float32 model inputs

    Returns
    -------
    (N, p*p) float32: the expected ``y2`` (probabilities for binary units, means for Gaussian).
    """
    h = model.hidden_probs(x, y)
    return model.output_probs(x2, h)


def analogy_images(
    model: GatedRBM, image_x: np.ndarray, image_y: np.ndarray, image_x2: np.ndarray, *, stride: Optional[int] = None
) -> np.ndarray:
    """:func:`analogy` on whole gray images of equal size, patch by patch.

    Each ``p x p`` patch of ``image_x2`` is transformed the way the patch at the same place moved
    from ``image_x`` to ``image_y``; overlapping outputs are blended with a Hann weight so
    patch borders (where content enters from outside the patch) count least.

    Parameters
    ----------
    image_x, image_y, image_x2 : (H, W) gray images of one size, ``H, W >= p``
        float in [0, 1] or uint8 0-255 (converted like :func:`bgsub.model.tiling.to_gray`, which also
        takes BGR).
    stride : int, optional
        Patch step, 1 to ``p`` (default ``p // 3``, so every pixel is covered several times).

    Returns
    -------
    (H, W) float32 in [0, 1]

    Raises
    ------
    InputError
        Images of different sizes or smaller than a patch, or ``stride`` outside 1 to ``p``.
    """
    from numpy.lib.stride_tricks import sliding_window_view

    from bgsub.model.tiling import to_gray

    p = model.patch_size
    if stride is not None and (not isinstance(stride, (int, np.integer)) or not 1 <= stride <= p):
        raise InputError(f"stride must be from 1 to the model's patch size {p} (a larger step "
                         f"leaves pixels uncovered), not {stride}; None for the default")
    image_x, image_y, image_x2 = (to_gray(im) for im in (image_x, image_y, image_x2))
    if not image_x.shape == image_y.shape == image_x2.shape:
        sizes = ", ".join(f"{im.shape[1]}x{im.shape[0]}" for im in (image_x, image_y, image_x2))
        raise InputError(f"the analogy images x, y and x2 must have the same size, not {sizes}")
    hgt, wid = image_x.shape
    if hgt < p or wid < p:
        raise InputError(f"the analogy images are {wid}x{hgt}, smaller than the model's {p}x{p} "
                         "patches")
    stride = max(1, stride or p // 3)
    ys = list(range(0, hgt - p + 1, stride))
    xs = list(range(0, wid - p + 1, stride))
    if ys[-1] != hgt - p:
        ys.append(hgt - p)
    if xs[-1] != wid - p:
        xs.append(wid - p)

    def cut(img: np.ndarray) -> np.ndarray:
        view = sliding_window_view(img.astype(np.float32), (p, p))
        return view[np.ix_(ys, xs)].reshape(-1, p * p)

    raw_x, raw_y, raw_x2 = cut(image_x), cut(image_y), cut(image_x2)
    x, y, _ = model.prepare(raw_x, raw_y)
    x2, _, _ = model.prepare(raw_x2, raw_x2)
    out = analogy(model, x, y, x2)
    if model.normalization == "contrast":
        # Undo the normalisation of x2: its mean and contrast scale.
        mean = raw_x2.mean(axis=1, keepdims=True)
        centred = raw_x2 - mean
        scale = np.maximum(np.sqrt(np.mean(centred * centred, axis=1, keepdims=True)), model.contrast_floor)
        out = out * scale + mean
    win = np.outer(np.hanning(p + 2)[1:-1], np.hanning(p + 2)[1:-1]).astype(np.float32)
    acc = np.zeros((hgt, wid), np.float32)
    wsum = np.zeros((hgt, wid), np.float32)
    rows = (np.asarray(ys)[:, None, None, None] + np.arange(p)[None, None, :, None])
    cols = (np.asarray(xs)[None, :, None, None] + np.arange(p)[None, None, None, :])
    rows, cols = np.broadcast_arrays(rows, cols)
    weights = np.broadcast_to(win, rows.shape)
    np.add.at(acc, (rows, cols), out.reshape(rows.shape) * weights)
    np.add.at(wsum, (rows, cols), weights)
    return np.clip(acc / np.maximum(wsum, 1e-12), 0.0, 1.0)
