"""CDnet 2014 confusion counts and the seven metrics (see :mod:`bgsub.evaluation.cdnet`).

Ground-truth labels: 0 and 50 negative, 255 positive, 85 and 170 ignored; any other value is
an :class:`InputError`. A predicted pixel is foreground when its value is > 127.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from bgsub.errors import InputError

#: The seven CDnet metrics, in CDnet's order (attribute names of :class:`Metrics`).
METRIC_NAMES = ("recall", "specificity", "fpr", "fnr", "pwc", "precision", "f_measure")
METRIC_TITLES = ("Recall", "Specificity", "FPR", "FNR", "PWC", "Precision", "F-measure")

# Ground-truth label -> class. Looking a whole frame up in a 256-entry table classifies every
# pixel in one vectorised step.
NEGATIVE, POSITIVE, IGNORED, INVALID = 0, 1, 2, 3
_LABEL_CLASS = np.full(256, INVALID, np.uint8)
_LABEL_CLASS[[0, 50]] = NEGATIVE
_LABEL_CLASS[255] = POSITIVE
_LABEL_CLASS[[85, 170]] = IGNORED



def _ratio(num: float, den: float) -> float:
    return num / den if den else math.nan


@dataclass(frozen=True)
class Metrics:
    """The seven CDnet 2014 metrics; ``nan`` where undefined (see the module docstring)."""

    recall: float
    specificity: float
    fpr: float
    fnr: float
    pwc: float
    precision: float
    f_measure: float

    def as_dict(self) -> Dict[str, Optional[float]]:
        """Metric name -> value, ``None`` where undefined (JSON-ready)."""
        return {k: (None if math.isnan(v) else float(v)) for k, v in asdict(self).items()}

    @classmethod
    def mean(cls, items: Sequence["Metrics"]) -> "Metrics":
        """Per-metric mean of ``items``, skipping undefined values (CDnet averaging)."""
        values = {}
        for f in fields(cls):
            defined = [getattr(m, f.name) for m in items if not math.isnan(getattr(m, f.name))]
            values[f.name] = float(np.mean(defined)) if defined else math.nan
        return cls(**values)


@dataclass
class Counts:
    """Pixel confusion counts: true/false positives/negatives (ignored pixels are not in them)."""

    tp: int = 0
    fp: int = 0
    fn: int = 0
    tn: int = 0

    @property
    def total(self) -> int:
        return self.tp + self.fp + self.fn + self.tn

    def __add__(self, other: "Counts") -> "Counts":
        return Counts(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn,
                      self.tn + other.tn)

    def __iadd__(self, other: "Counts") -> "Counts":
        self.tp += other.tp
        self.fp += other.fp
        self.fn += other.fn
        self.tn += other.tn
        return self

    def metrics(self) -> Metrics:
        """The seven CDnet metrics of these counts."""
        return metrics(self)

    def as_dict(self) -> Dict[str, int]:
        return {"tp": self.tp, "fp": self.fp, "fn": self.fn, "tn": self.tn}


def metrics(counts: Counts) -> Metrics:
    """The seven CDnet 2014 metrics of ``counts`` (``nan`` where a denominator is 0)."""
    tp, fp, fn, tn = (float(v) for v in (counts.tp, counts.fp, counts.fn, counts.tn))
    return Metrics(
        recall=_ratio(tp, tp + fn),
        specificity=_ratio(tn, tn + fp),
        fpr=_ratio(fp, fp + tn),
        fnr=_ratio(fn, tp + fn),
        pwc=_ratio(100.0 * (fn + fp), tp + fn + fp + tn),
        precision=_ratio(tp, tp + fp),
        f_measure=_ratio(2.0 * tp, 2.0 * tp + fp + fn),
    )


def classify_labels(labels: np.ndarray, *, source: str = "ground truth") -> np.ndarray:
    """CDnet labels -> classes (0 negative, 1 positive, 2 ignored); other values raise.

    Parameters
    ----------
    labels : (H, W) uint8
        Ground-truth values 0, 50, 85, 170 or 255.
    source : str
        Named in the error message.

    Returns
    -------
    (H, W) uint8 array of :data:`NEGATIVE`, :data:`POSITIVE`, :data:`IGNORED`.
    """
    classes = _LABEL_CLASS[labels]
    if np.any(classes == INVALID):
        bad = np.unique(labels[classes == INVALID])[:5].tolist()
        raise InputError(
            f"{source} has values {bad} that are not CDnet labels (0, 50, 85, 170, 255)"
        )
    return classes


def count_frame(
    prediction: np.ndarray, labels: np.ndarray, roi: Optional[np.ndarray] = None
) -> Counts:
    """Confusion counts of one frame.

    Parameters
    ----------
    prediction : (H, W) uint8
        Predicted mask; foreground where > 127.
    labels : (H, W) uint8
        CDnet ground-truth labels (see :func:`classify_labels`).
    roi : (H, W) bool, optional
        Pixels to evaluate; ``None`` = all.

    Returns
    -------
    Counts of this frame.
    """
    if prediction.shape != labels.shape:
        raise InputError(
            f"prediction is {frame_size(prediction)} but ground truth is {frame_size(labels)}"
        )
    classes = classify_labels(labels)
    if roi is not None:
        classes = np.where(roi, classes, np.uint8(IGNORED))
    # One pass: code = 2 * class + predicted, counted with bincount.
    code = classes * np.uint8(2) + (prediction > 127).astype(np.uint8)
    hist = np.bincount(code.ravel(), minlength=6)
    return Counts(tp=int(hist[3]), fp=int(hist[1]), fn=int(hist[2]), tn=int(hist[0]))


def frame_size(image: np.ndarray) -> str:
    """``"WxH"`` of an ``(H, W[, C])`` image, for messages."""
    return f"{image.shape[1]}x{image.shape[0]}"


def is_uniform_scale(size: Tuple[int, int], reference: Tuple[int, int]) -> bool:
    """Whether ``size`` could be ``reference`` resized by one factor (``run --scale/--width``).

    :func:`bgsub.io.sources.output_size` rounds each side of ``reference * s`` to the nearest
    integer, so ``size`` qualifies when some factor ``s`` has ``|w_ref * s - w| <= 1/2`` and
    ``|h_ref * s - h| <= 1/2``: the two intervals of ``s`` overlap. Computed in integers (the
    inequalities times 2 and cross-multiplied) so a boundary case is not lost to rounding.

    Parameters
    ----------
    size, reference : (width, height) of int
        Sizes in pixels, each side >= 1.

    Returns
    -------
    bool (also True when the sizes are equal).
    """
    (w, h), (w_ref, h_ref) = size, reference
    return ((2 * w - 1) * h_ref <= (2 * h + 1) * w_ref
            and (2 * h - 1) * w_ref <= (2 * w + 1) * h_ref)

