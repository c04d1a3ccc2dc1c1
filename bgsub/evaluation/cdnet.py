"""CDnet 2014 evaluation: confusion counts and the seven metrics, per sequence and per dataset.

Ground truth (one sequence)
    A folder with ``groundtruth/gtNNNNNN.png`` (1-based frame numbers), optionally
    ``temporalROI.txt`` ("first last": the frames that carry valid ground truth) and ``ROI.bmp``
    (the spatial region of interest: non-zero = inside). Labels are CDnet's:

    ======  =======================  ==========
    value   meaning                  counted as
    ======  =======================  ==========
    0       static background        negative
    50      hard shadow              negative
    85      outside the ROI          ignored
    170     unknown / object border  ignored
    255     moving object            positive
    ======  =======================  ==========

    Any other value is an :class:`InputError` naming the file: the real CDnet ground truth uses
    exactly these five values (checked on ``CDnet2014_cameraJitter_traffic``: 0, 50, 85, 170, 255
    only), so another value means the file is not CDnet ground truth (e.g. an anti-aliased or
    JPEG-compressed mask) and guessing a class for it would bias the scores. Colour ground-truth
    images are accepted when their three channels are equal (CDnet's own pngs are stored so).

Ground truth (a dataset)
    A root folder searched at any depth; a folder is a sequence if it holds a ``groundtruth/``
    subfolder (its subfolders are not searched further). A sequence's *category* is the name of
    the folder holding it (``root/cameraJitter/traffic`` -> ``cameraJitter``); a sequence lying
    directly in the root has the family of its name instead: the part before the first ``_``
    (``BMS26_cars1`` -> ``BMS26``, ``static_s1`` -> ``static``, a name without ``_`` is its own
    family).

Predictions
    A folder of ``binNNNNNN.png`` masks (same numbering as the ground truth; ``.bmp``/``.jpg``/
    ``.tif`` are read too) or a mask video, whose frame ``k`` (0-based) is frame number
    ``video_start + k * video_step + 1``; or, from Python, an iterable of ``(frame_number, mask)``
    pairs. A mask video carries no frame numbers, so ``video_start``/``video_step``/``video_stop``
    (``bgsub eval --start/--step/--stop``) say which input frames it holds, with the meaning of
    ``bgsub run``'s options of those names (0-based, ``range(start, stop, step)``; defaults 0, 1,
    the end): the same flags that wrote it. Only the frames they cover are evaluated, and
    ``skip_first`` leaves out the video's first frame. A folder's masks carry their frame
    numbers: there the same options only select the frames `bgsub run` read with them (``--step
    2`` wrote ``bin000001.png``, ``bin000003.png``, ...: only frames 1, 3, ... are evaluated), with
    the same ``skip_first``. Python masks name their frames themselves: giving these options with
    them is an error (ignoring them would hide that the user expected something to shift). A
    prediction longer than the ground truth (a mask video with a frame past its last frame, or
    masks numbered past it) is scored on the frames with ground truth, with a warning in
    :attr:`SequenceResult.warnings`: often the masks of another sequence. Only ground truth with
    a file for every frame from 1 (CDnet's layout) states where the input ends: its last frame,
    or the temporal ROI's end when later (:attr:`GroundTruth.sequence_end`); ground truth with
    gaps (every N-th frame labelled) or starting later (a labelled window) states none, and
    masks past it draw no warning. CDnet numbers frames from 1: a ``bin000000.png`` is
    ignored with a warning (masks numbered from 0 would each be scored against the previous
    frame's ground truth; the warning says so when the masks look shifted that way). A pixel is
    foreground when its value is > 127 (colour masks are converted to gray first). For a
    dataset, the prediction of the sequence at ``GT_ROOT/REL`` (``REL`` = its path relative to
    the root, e.g. ``cameraJitter/traffic``; ``NAME`` = its folder name) is the first that
    exists of
    ``PRED_ROOT/REL/``, ``PRED_ROOT/NAME/``, ``PRED_ROOT/REL.<ext>``, ``PRED_ROOT/NAME.<ext>``
    with ``<ext>`` a video extension (:data:`VIDEO_EXTENSIONS`). A `bgsub compare` report holds
    one mask set per method (``METHOD/`` or ``METHOD.mkv``, inside ``REL/`` for a dataset):
    ``method`` (``bgsub eval --method``) picks one.

Prediction size
    ``bgsub run --width/--scale`` writes masks at the processed size. A prediction whose size is
    a uniform scale of the ground truth's (:func:`is_uniform_scale`: one factor explains both
    sides to within the rounding of :func:`bgsub.io.sources.output_size`) is brought to the ground
    truth's size with nearest-neighbour interpolation (masks stay 0/255), and the result notes
    it once. Any other size is an :class:`InputError` naming both sizes.

Which pixels and frames count
    Frames with a ground-truth png inside the temporal ROI (all of them without
    ``temporalROI.txt``), optionally narrowed by ``first_frame``/``last_frame``/``frames`` and
    ``skip_first`` (leaves out frame 1, the first frame of the video, where a background model
    has seen nothing yet; it changes nothing when the temporal ROI starts later, as in CDnet).
    Pixels inside ``ROI.bmp`` (unless ``ignore_roi_bmp``) whose label is not 85 or 170. An
    ``ROI.bmp`` that cannot be read or whose size differs from the frames is an error (the real
    CDnet ``cameraJitter/traffic`` ROI.bmp is 352x240 for 320x240 frames): pass
    ``ignore_roi_bmp`` to evaluate without it (label 85 still excludes outside-ROI pixels).

Missing predictions
    A frame to evaluate without a prediction (a missing png, or a video that ends early) is an
    :class:`InputError` listing how many and the first ones, unless ``allow_missing``: then each
    missing frame counts as an all-background prediction (so its objects are false negatives;
    missing output is never rewarded) and the result reports the count. When a folder's masks
    among those frames are one evenly spaced run (a part of the sequence, or every N-th frame),
    the error, and :attr:`SequenceResult.missing_hint`, name the options that score just them
    (e.g. ``--first-frame 991 --last-frame 1030``, or ``--step 2``).

Metrics (CDnet 2014; counts summed over all evaluated frames of a sequence)
    Recall = TP/(TP+FN), Specificity = TN/(TN+FP), FPR = FP/(FP+TN), FNR = FN/(TP+FN),
    PWC = 100 (FN+FP)/(TP+FN+FP+TN), Precision = TP/(TP+FP), F-measure = 2 TP/(2 TP+FP+FN)
    (which equals 2 Precision Recall/(Precision+Recall) whenever both are defined).
    A ratio whose denominator is 0 is undefined: ``nan`` (``n/a`` in tables, ``null`` in JSON);
    e.g. Precision of a method that marked nothing, Recall of a sequence without objects. F is
    0 when there are objects and none were found (even if nothing was marked), and undefined
    only when there was nothing to find and nothing was marked.

Averaging (the CDnet way)
    A category's metrics are the mean of its sequences' metrics; the overall metrics are the
    mean of the categories' metrics (each category weighs the same, whatever its size). Means
    skip undefined values (a metric undefined in every member stays undefined).
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import sys
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from abc import ABC, abstractmethod
from typing import (
    Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Tuple, Union,
)

import cv2
import numpy as np
from tqdm import tqdm

from bgsub.errors import InputError, given_path
from bgsub.io.sources import VIDEO_SUFFIXES, open_source

#: Mask-video extensions recognised when looking for a sequence's prediction in a dataset, in
#: that order: :data:`bgsub.io.sources.VIDEO_SUFFIXES` (one list for every module that names videos).
VIDEO_EXTENSIONS = VIDEO_SUFFIXES
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

_GT_NAME = re.compile(r"^gt(\d+)\.png$", re.IGNORECASE)
_BIN_NAME = re.compile(r"^bin(\d+)\.(png|bmp|jpe?g|tiff?)$", re.IGNORECASE)
_MAX_LISTED = 5  # missing frames named in a message

PathLike = Union[str, "os.PathLike[str]"]
Prediction = Union[PathLike, Iterable[Tuple[int, np.ndarray]], Mapping[int, np.ndarray]]


# --------------------------------------------------------------------------------------------
# Counts and metrics
# --------------------------------------------------------------------------------------------


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
            f"prediction is {_size(prediction)} but ground truth is {_size(labels)}"
        )
    classes = classify_labels(labels)
    if roi is not None:
        classes = np.where(roi, classes, np.uint8(IGNORED))
    # One pass: code = 2 * class + predicted, counted with bincount.
    code = classes * np.uint8(2) + (prediction > 127).astype(np.uint8)
    hist = np.bincount(code.ravel(), minlength=6)
    return Counts(tp=int(hist[3]), fp=int(hist[1]), fn=int(hist[2]), tn=int(hist[0]))


def _size(image: np.ndarray) -> str:
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


# --------------------------------------------------------------------------------------------
# Ground truth
# --------------------------------------------------------------------------------------------


def is_sequence(path: PathLike) -> bool:
    """Whether ``path`` is a CDnet sequence folder (it holds a ``groundtruth/`` folder)."""
    return (Path(path) / "groundtruth").is_dir()


def _read_labels(path: Path) -> np.ndarray:
    """Read one ground-truth png as ``(H, W) uint8`` labels (equal-channel colour accepted)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise InputError(f"cannot read ground-truth image {path}")
    if image.dtype != np.uint8:
        raise InputError(f"ground truth {path} is {image.dtype}, expected 8-bit labels")
    if image.ndim == 3:
        channels = image[..., :3]
        first = channels[..., 0]
        if not all(np.array_equal(first, channels[..., c]) for c in range(1, channels.shape[2])):
            raise InputError(f"ground truth {path} is a colour image (its channels differ)")
        image = np.ascontiguousarray(first)
    return image


def _read_temporal_roi(path: Path) -> Optional[Tuple[int, int]]:
    if not path.exists():
        return None
    if not path.is_file():
        raise InputError(f"{path} is not a file (it should hold 'first last')")
    try:
        parts = path.read_text(errors="replace").split()
    except OSError as err:
        raise InputError(f"cannot read {path}: {err.strerror or err}") from None
    try:
        first, last = int(parts[0]), int(parts[1])
    except (IndexError, ValueError):
        raise InputError(f"{path} must hold two frame numbers 'first last'") from None
    if first < 1 or last < first:
        raise InputError(f"{path} holds an empty or invalid frame range {first}-{last}")
    return first, last


@dataclass
class GroundTruth:
    """One CDnet sequence's ground truth, read lazily frame by frame.

    Attributes
    ----------
    path : Path
        The sequence folder.
    frames : dict int -> Path
        Frame number (1-based) -> ``gtNNNNNN.png``, in order.
    temporal_roi : (first, last) or None
        From ``temporalROI.txt``.
    roi : (H, W) bool or None
        From ``ROI.bmp`` (non-zero = inside), when present and used.
    width, height : int
        Frame size (of the first ground-truth frame).
    """

    path: Path
    frames: Dict[int, Path]
    temporal_roi: Optional[Tuple[int, int]]
    roi: Optional[np.ndarray]
    width: int
    height: int
    notes: List[str] = field(default_factory=list)

    def select_frames(
        self,
        *,
        first_frame: Optional[int] = None,
        last_frame: Optional[int] = None,
        frames: Optional[Iterable[int]] = None,
        skip_first: bool = False,
    ) -> List[int]:
        """Frame numbers to evaluate, ascending (see "Which pixels and frames count").

        Parameters
        ----------
        first_frame, last_frame : int, optional
            Keep only frame numbers in ``[first_frame, last_frame]`` (1-based, inclusive).
        frames : iterable of int, optional
            Keep only these frame numbers (e.g. a handful, for a quick check).
        skip_first : bool
            Leave out frame 1, where a background model run from the start has no history.
        """
        if first_frame is not None and last_frame is not None and first_frame > last_frame:
            raise InputError(f"first_frame (--first-frame {first_frame}) is after last_frame "
                             f"(--last-frame {last_frame}): no frame lies between them")
        numbers = list(self.frames)
        if self.temporal_roi is not None:
            lo, hi = self.temporal_roi
            numbers = [n for n in numbers if lo <= n <= hi]
        if first_frame is not None:
            numbers = [n for n in numbers if n >= first_frame]
        if last_frame is not None:
            numbers = [n for n in numbers if n <= last_frame]
        if frames is not None:
            wanted = {int(n) for n in frames}
            numbers = [n for n in numbers if n in wanted]
        if skip_first:
            numbers = [n for n in numbers if n != 1]
        if not numbers:
            roi = (f" (temporal ROI {self.temporal_roi[0]}-{self.temporal_roi[1]})"
                   if self.temporal_roi else "")
            raise InputError(f"no ground-truth frames left to evaluate in {self.path}{roi}")
        return numbers

    @property
    def sequence_end(self) -> Optional[int]:
        """The last frame number of the input, as the ground truth states it; None if it does not.

        CDnet's ground truth has a ``gtNNNNNN.png`` for every input frame from 1 (frames outside
        the temporal ROI too), so its last file is the input's last frame; a temporal ROI that
        ends later says the input goes on at least that far (ground truth not given for all of
        it). Ground truth with gaps (a label every N-th frame) or starting after frame 1 (a
        window of the input) labels a sample or a part: where it stops says nothing about
        where the input does, so masks that go on past it are no sign of another sequence's.
        """
        last = next(reversed(self.frames))  # frames are sorted
        if min(self.frames) != 1 or len(self.frames) != last:  # not every frame from 1
            return None
        return max(last, self.temporal_roi[1]) if self.temporal_roi is not None else last

    def describe_end(self) -> str:
        """``"SEQ has 10 ground-truth frames, up to gt000010.png"`` (and the temporal ROI's
        end when it lies later): what a warning about masks past the end compares them with."""
        last = next(reversed(self.frames))
        text = (f"{self.path} has {len(self.frames)} ground-truth frames, up to "
                f"{self.frames[last].name}")
        if self.temporal_roi is not None and self.temporal_roi[1] > last:
            text += f", and its temporal ROI ends at frame {self.temporal_roi[1]}"
        return text

    def labels(self, number: int) -> np.ndarray:
        """``(H, W) uint8`` CDnet labels of frame ``number``."""
        path = self.frames[number]
        labels = _read_labels(path)
        if labels.shape != (self.height, self.width):
            raise InputError(
                f"ground truth {path} is {_size(labels)} but the sequence's first frame is "
                f"{self.width}x{self.height}"
            )
        return labels


def open_ground_truth(path: PathLike, *, ignore_roi_bmp: bool = False) -> GroundTruth:
    """Index a CDnet sequence folder (reads only its first ground-truth frame and ROI.bmp).

    Parameters
    ----------
    path : str or Path
        Folder holding ``groundtruth/``.
    ignore_roi_bmp : bool
        Do not read ``ROI.bmp`` (labels 85/170 still exclude pixels).

    Raises
    ------
    InputError
        No ground-truth pngs, malformed ``temporalROI.txt``, unreadable or mis-sized ``ROI.bmp``.
    """
    root = Path(path)
    gt_dir = root / "groundtruth"
    if not gt_dir.is_dir():
        raise InputError(f"{root} is not a CDnet sequence: it has no groundtruth/ folder")
    frames: Dict[int, Path] = {}
    for entry in os.scandir(gt_dir):
        match = _GT_NAME.match(entry.name)
        if match:
            frames[int(match.group(1))] = Path(entry.path)
    if not frames:
        raise InputError(f"no gtNNNNNN.png files in {gt_dir}")
    frames = dict(sorted(frames.items()))
    first = _read_labels(next(iter(frames.values())))
    height, width = first.shape
    temporal_roi = _read_temporal_roi(root / "temporalROI.txt")
    notes: List[str] = []
    roi = None
    roi_path = root / "ROI.bmp"
    if roi_path.is_file():
        if ignore_roi_bmp:
            notes.append("ROI.bmp ignored")
        else:
            image = cv2.imread(str(roi_path), cv2.IMREAD_GRAYSCALE)
            if image is None:
                raise InputError(f"cannot read {roi_path} (pass --no-roi-bmp to ignore it)")
            if image.shape != (height, width):
                raise InputError(
                    f"{roi_path} is {_size(image)} but the ground truth is {width}x{height} "
                    "(pass --no-roi-bmp to ignore it)"
                )
            roi = image > 0
            notes.append("ROI.bmp applied")
    return GroundTruth(root, frames, temporal_roi, roi, width, height, notes)


# --------------------------------------------------------------------------------------------
# Predictions
# --------------------------------------------------------------------------------------------


def _bin_frames(folder: Path) -> Dict[int, Path]:
    found: Dict[int, Path] = {}
    for entry in os.scandir(folder):
        match = _BIN_NAME.match(entry.name)
        if match:
            found.setdefault(int(match.group(1)), Path(entry.path))
    return found


def _to_gray(mask: np.ndarray, source: str) -> np.ndarray:
    if mask.ndim == 3:
        if mask.shape[2] == 1:
            return mask[..., 0]
        return cv2.cvtColor(mask[..., :3], cv2.COLOR_BGR2GRAY)
    if mask.ndim != 2:
        raise InputError(f"prediction {source} has shape {mask.shape}, expected (H, W)")
    return mask


def _as_uint8_mask(mask: Any, number: int) -> np.ndarray:
    """A mask given from Python as uint8; a bool mask (True = foreground) becomes 0/255."""
    mask = np.asarray(mask)
    if mask.dtype == bool:
        return mask.astype(np.uint8) * np.uint8(255)
    if mask.dtype != np.uint8:
        raise InputError(f"predicted mask of frame {number} is {mask.dtype}; give uint8 0/255 "
                         "or bool masks")
    return mask


@dataclass(frozen=True)
class VideoFrames:
    """Which input frames a mask video holds: those ``bgsub run --start --step --stop`` read.

    Frame ``k`` (0-based) of the video is the mask of input index ``start + k * step`` (0-based),
    i.e. of frame number ``start + k * step + 1``; the indices are ``range(start, stop, step)``
    (``stop=None``: up to the end), as in :func:`bgsub.io.sources.open_source`.
    """

    start: int = 0
    step: int = 1
    stop: Optional[int] = None

    def __post_init__(self) -> None:
        # Each message names the field and the `bgsub eval` flag that sets it: both kinds of
        # caller (Python, the CLI) read these.
        if not isinstance(self.start, (int, np.integer)) or self.start < 0:
            raise InputError(f"start (--start) takes a 0-based frame index >= 0, as in bgsub "
                             f"run, not {self.start!r}")
        if not isinstance(self.step, (int, np.integer)) or self.step < 1:
            raise InputError(f"step (--step) must be at least 1, not {self.step!r}")
        if self.stop is not None and (not isinstance(self.stop, (int, np.integer))
                                      or self.stop <= self.start):
            raise InputError(f"stop (--stop, {self.stop!r}) must be after start ({self.start})")

    @property
    def is_default(self) -> bool:
        """True for a video of every frame from the first (frame ``k`` is number ``k + 1``)."""
        return (self.start, self.step, self.stop) == (0, 1, None)

    def number(self, k: int) -> int:
        """1-based frame number of the video's frame ``k`` (0-based)."""
        return self.start + k * self.step + 1

    def covers(self, number: int) -> bool:
        """Whether frame ``number`` (1-based) is one the video was made from."""
        index = number - 1
        return (index >= self.start and (index - self.start) % self.step == 0
                and (self.stop is None or index < self.stop))

    def flags(self) -> str:
        """The ``bgsub eval`` options that state this range (``""`` for the default)."""
        parts = [f"--start {self.start}" if self.start else "",
                 f"--step {self.step}" if self.step != 1 else "",
                 f"--stop {self.stop}" if self.stop is not None else ""]
        return " ".join(p for p in parts if p)


class _PredictionReader(ABC):
    """Yields ``(number, mask)`` for the wanted frame numbers it has; knows how to name them."""

    label: str

    @abstractmethod
    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        """``(number, mask)`` for each wanted frame number this prediction has."""

    def frame_name(self, number: int) -> str:
        return f"frame {number}"

    def missing_message(self, missing: Sequence[int], total: int) -> str:
        names = ", ".join(self.frame_name(n) for n in missing[:_MAX_LISTED])
        more = ", ..." if len(missing) > _MAX_LISTED else ""
        return (f"{len(missing)} of {total} frames to evaluate have no prediction in "
                f"{self.label} (first: {names}{more})")


def _mask_sets(folder: Path) -> List[str]:
    """Names of the mask sets inside ``folder``, as `bgsub compare` writes one per method: mask
    videos (``grbm.mkv``) and subfolders holding ``binNNNNNN.png`` masks (``grbm/``)."""
    found = []
    for entry in sorted(os.scandir(folder), key=lambda e: e.name):
        if entry.is_file() and os.path.splitext(entry.name)[1].lower() in VIDEO_EXTENSIONS:
            found.append(entry.name)
        elif entry.is_dir():
            try:
                names = os.listdir(entry.path)
            except OSError:  # unreadable: not something to point at
                continue
            if any(_BIN_NAME.match(name) for name in names):
                found.append(entry.name + "/")
    return found


def _methods_held(folders: Sequence[Path]) -> str:
    """``"; it holds the methods grbm, mog2"``: the methods whose mask sets the `bgsub compare`
    report ``folders`` hold, or ``""`` when they hold none."""
    names: Dict[str, None] = {}
    for folder in folders:
        if folder.is_dir():
            for entry in _mask_sets(folder):
                names[os.path.splitext(entry.rstrip("/"))[0] if not entry.endswith("/")
                      else entry.rstrip("/")] = None
    return f"; it holds the methods {', '.join(names)}" if names else ""


def _no_masks_message(folder: Path, gt: Optional[Path]) -> str:
    """Why ``folder`` is no prediction, saying what it holds instead."""
    text = f"no binNNNNNN.png masks in {folder}"
    sets = _mask_sets(folder)
    if not sets:
        count = sum(1 for _ in os.scandir(folder))
        return text + (" (the folder is empty)" if not count else
                       f" (none of its {count} files and folders is one)")
    listed = ", ".join(sets[:_MAX_LISTED]) + (", ..." if len(sets) > _MAX_LISTED else "")
    example = folder / sets[0]
    name = sets[0].rstrip("/")
    method = os.path.splitext(name)[0] if not sets[0].endswith("/") else name
    return (f"{text}: it holds the mask sets {listed} (`bgsub compare` writes one per method); "
            f"score one with method={method!r} (--method {method}), or give it, e.g. "
            f"`bgsub eval {example} {gt or 'GROUNDTRUTH'}`")


class _FolderReader(_PredictionReader):
    def __init__(self, folder: Path, gt: Optional[Path] = None) -> None:
        self.label = str(folder)
        self.files = _bin_frames(folder)
        # CDnet numbers frames from 1: bin000000.png is no frame's mask. Set aside rather than
        # dropped, so the result can say it was not scored and what it suggests.
        self.zero = self.files.pop(0, None)
        if not self.files:
            if self.zero is not None:
                raise InputError(f"the only mask in {folder} is {self.zero.name}, but CDnet "
                                 "numbers frames from 1 (bin000001.png is the mask of "
                                 "in000001.jpg): renumber the masks from 1")
            raise InputError(_no_masks_message(folder, gt))

    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        for number in numbers:
            path = self.files.get(number)
            if path is None:
                continue
            mask = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
            if mask is None:
                raise InputError(f"cannot read predicted mask {path}")
            yield number, mask

    def frame_name(self, number: int) -> str:
        return f"bin{number:06d}.png"

    def numbered_from_0(self, gt_end: int) -> bool:
        """Whether the masks are ``bin000000.png`` to ``bin{gt_end - 1}.png``, every one: the
        frames 1 to ``gt_end`` of the ground truth numbered from 0."""
        return (self.zero is not None and len(self.files) == gt_end - 1
                and max(self.files) == gt_end - 1)

    def zero_warning(self, gt_end: int) -> str:
        """The one-line warning about the folder's ``bin000000.png`` (``""`` without one),
        with the fix when the masks look numbered from 0 for ground truth ending at
        ``gt_end``."""
        if self.zero is None:
            return ""
        text = (f"{self.zero.name} in {self.label} is not a CDnet frame number (they start at "
                "1: bin000001.png is the mask of in000001.jpg) and was ignored")
        # Mask K of a count from 0 is of frame K + 1, but meets gtK: a frame too early.
        if not self.numbered_from_0(gt_end):
            return (text + "; the masks may be numbered from 0: then each is paired with "
                    "the ground truth of the frame before its own")
        return (text + f": the masks {self.zero.name}-{self.frame_name(gt_end - 1)} look "
                f"numbered from 0 for the ground truth's frames 1-{gt_end}, so each is paired "
                "with the ground truth of the frame before its own; renumber them from 1 "
                "(binK.png -> bin(K+1).png, as `bgsub run` writes them)")

    def range_hint(self, selected: Sequence[int], *, skip_first: bool = False) -> str:
        """``"to score just the frames with a mask (40, bin000991.png-bin001030.png), use
        --first-frame 991 --last-frame 1030"``: the options that score exactly those of the
        ``selected`` ground-truth frames (before any --start/--step/--stop) that have a mask,
        when these masks form one evenly spaced run (what `bgsub run --start/--step/--stop`
        writes); ``""`` when they do not (holes no range leaves out) or none is there."""
        lo, hi = selected[0], selected[-1]
        inside = sorted(n for n in self.files if lo <= n <= hi)
        step = _even_step(inside)
        if step is None:
            return ""
        first, last = inside[0], inside[-1]
        if step == 1 and not skip_first:
            # (With --skip-first, the run's own range below: --first-frame would keep the masks'
            # first frame, the one a model met without history.)
            chosen = [n for n in selected if first <= n <= last]
            flags = " ".join(f for f in (f"--first-frame {first}" if first > lo else "",
                                         f"--last-frame {last}" if last < hi else "") if f)
        else:
            # The run's own --start when every mask is of the run (they give the same frames).
            everything = sorted(self.files)
            start = (everything[0] if _even_step(everything) == step else first) - 1
            frames = VideoFrames(start, step, last if last + step <= hi else None)
            chosen = [n for n in selected
                      if frames.covers(n) and not (skip_first and n == frames.number(0))]
            flags = frames.flags()
        if not flags or not chosen or any(n not in self.files for n in chosen):
            return ""
        span = (f"{self.frame_name(first)}-{self.frame_name(last)}" if len(inside) > 1
                else self.frame_name(first))
        every = f", one frame in {step}" if step > 1 else ""
        return f"to score just the frames with a mask ({len(inside)}, {span}{every}), use {flags}"

    def missing_message(self, missing: Sequence[int], total: int) -> str:
        text = super().missing_message(missing, total)
        if len(missing) == total:  # not one wanted number: the masks are numbered otherwise
            low, high = min(self.files), max(self.files)
            text += f"; the folder's masks are numbered {low}-{high}"
            # (Masks among the wanted numbers, just not on them: a --step of another phase.)
            if low == 1 and not any(min(missing) <= n <= max(missing) for n in self.files):
                text += (" (`bgsub run` numbers masks by position in its input: run on part of "
                         "a folder or glob, they start at 1 whatever the frames' names; run it "
                         "on the whole folder with --start/--stop to keep the frame numbers)")
        return text


def _even_step(numbers: Sequence[int]) -> Optional[int]:
    """The spacing of ascending ``numbers`` when it is the same throughout (1 for one number),
    else None (also for none)."""
    if not numbers:
        return None
    if len(numbers) == 1:
        return 1
    step = numbers[1] - numbers[0]
    return step if all(b - a == step for a, b in zip(numbers, numbers[1:])) else None


class _VideoReader(_PredictionReader):
    def __init__(self, path: Path, frames: VideoFrames = VideoFrames()) -> None:
        self.label = str(path)
        self.path = path
        self.frames = frames
        self.frames_read = 0
        #: The input's last frame number as the ground truth states it
        #: (:attr:`GroundTruth.sequence_end`), when it does (set before :meth:`read`).
        self.gt_end: Optional[int] = None
        #: After :meth:`read`: ``(k, total)`` when the video has a frame ``k`` (0-based) past
        #: ``gt_end``; ``total`` is its frame count when the container states one above ``k``.
        self.past_gt: Optional[Tuple[int, Optional[int]]] = None

    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        wanted = set(numbers)
        # ``numbers`` are all frames the video covers, so the last one is exactly its frame
        # ``last``. Reading from the start (not from the first wanted frame) lets a video that
        # ends before the first wanted frame report missing frames instead of failing to open.
        last = (max(numbers) - 1 - self.frames.start) // self.frames.step
        # A video with a frame past the ground truth's end is longer than the sequence it is
        # scored against: often another clip's masks. Its frame ``past`` is decoded to know:
        # at no cost when it follows ``last``; else only when the container's (possibly
        # estimated) count says the video reaches it.
        past = None
        if self.gt_end is not None:
            past = max(0, (self.gt_end - 1 - self.frames.start) // self.frames.step + 1)
            if self.frames.stop is not None and self.frames.number(past) > self.frames.stop:
                past = None  # the video's range ends before: a longer video is no sign
        with open_source(str(self.path)) as source:
            total = source.info.frame_count
            end = last
            if past is not None and (past == last + 1 or (total is not None and total > past)):
                end = past
            for k, frame in source:
                if k > end:
                    break
                self.frames_read = k + 1
                if k == past:
                    self.past_gt = (past, total if total is not None and total > past else None)
                number = self.frames.number(k)
                if number in wanted:
                    yield number, _to_gray(frame, f"{self.path} frame {k + 1}")

    def missing_message(self, missing: Sequence[int], total: int) -> str:
        # The video has no frame numbers of its own: a short video is often one written from a
        # later start or with a step, read here as if it began at frame 1.
        flags = self.frames.flags()
        given = f"with {flags}" if flags else "from frame 1, every frame"
        return (f"{self.label} ends after frame {self.frames.number(self.frames_read - 1)} but "
                f"the ground truth needs frames up to {max(missing)}: "
                + super().missing_message(missing, total)
                + "; a mask video carries no frame numbers: if bgsub run wrote it with "
                  f"--start/--step/--stop, give eval the same flags (read here {given})")


class _IterableReader(_PredictionReader):
    def __init__(self, pairs: Union[Iterable[Tuple[int, np.ndarray]], Mapping[int, np.ndarray]],
                 label: str = "the given predictions") -> None:
        self.label = label
        self.pairs = pairs.items() if isinstance(pairs, Mapping) else pairs

    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        wanted = set(numbers)
        for number, mask in self.pairs:
            if int(number) < 1:  # ignored, it would only show as a frame "with no prediction"
                raise InputError(f"a prediction for frame number {number}: CDnet frame numbers "
                                 "start at 1 (in000001.jpg is frame 1); add 1 to 0-based frame "
                                 "indices such as FrameSource's")
            if int(number) in wanted:
                yield int(number), _to_gray(_as_uint8_mask(mask, number), f"frame {number}")


def _prediction_reader(pred: Optional[Prediction], video: VideoFrames = VideoFrames(),
                       gt: Optional[Path] = None) -> _PredictionReader:
    if pred is None:  # a dataset sequence without any prediction (allow_missing)
        return _IterableReader((), label="(no prediction)")
    if isinstance(pred, (str, os.PathLike)):
        path = Path(pred)
        if path.is_dir():  # its numbers are the frames': a range only selects among them
            return _FolderReader(path, gt)
        if path.is_file():
            return _VideoReader(path, video)
        raise InputError(f"prediction {path} does not exist")
    _refuse_video_frames(video, "these are masks from Python")
    return _IterableReader(pred)


def _refuse_video_frames(video: VideoFrames, what: str) -> None:
    """Refuse a video frame range for a prediction that numbers its own frames.

    Ignoring it would leave a user who expected a shift with scores of other frames than meant.
    """
    if not video.is_default:
        raise InputError(f"--start/--step/--stop ({video.flags()}) place the frames of a mask "
                         f"video or select those of a mask folder, but {what} that number "
                         "their own frames; use first_frame/last_frame/frames to choose frames")


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


@dataclass
class SequenceResult:
    """Evaluation of one sequence.

    Attributes
    ----------
    name, category : str
        Sequence folder name and its category (see the module docstring).
    counts : Counts
        Summed over the evaluated frames.
    n_frames : int
        Frames evaluated (including missing ones counted as background).
    missing : list of int
        Frame numbers without a prediction (only non-empty with ``allow_missing``).
    first_frame, last_frame : int
        Evaluated frame-number range.
    """

    name: str
    category: str
    gt_path: str
    pred_path: str
    counts: Counts
    n_frames: int
    first_frame: int
    last_frame: int
    missing: List[int] = field(default_factory=list)
    notes: List[str] = field(default_factory=list)
    #: Signs that the prediction and the ground truth may not belong together (the CLI prints
    #: them as warnings), e.g. a mask video with more frames than the ground truth.
    warnings: List[str] = field(default_factory=list)
    #: With ``missing``: the options that score just the frames that have a mask, when those
    #: form one evenly spaced run (e.g. ``"to score just ... use --first-frame 5"``), else "".
    missing_hint: str = ""

    @property
    def metrics(self) -> Metrics:
        return self.counts.metrics()

    def to_dict(self) -> Dict[str, Any]:
        return {
            "name": self.name,
            "category": self.category,
            "groundtruth": self.gt_path,
            "prediction": self.pred_path,
            "frames": self.n_frames,
            "first_frame": self.first_frame,
            "last_frame": self.last_frame,
            "missing": len(self.missing),
            "missing_frames": self.missing[:_MAX_LISTED],
            "counts": self.counts.as_dict(),
            "metrics": self.metrics.as_dict(),
            "notes": list(self.notes),
            "warnings": list(self.warnings),
        }


@dataclass
class CategoryResult:
    """A category: metrics = mean of its sequences' metrics; counts = their sum (for reference)."""

    name: str
    sequences: List[str]
    metrics: Metrics
    counts: Counts

    def to_dict(self) -> Dict[str, Any]:
        return {"name": self.name, "sequences": list(self.sequences),
                "counts": self.counts.as_dict(), "metrics": self.metrics.as_dict()}


@dataclass
class DatasetResult:
    """Per-sequence, per-category and overall (mean of category means) results."""

    sequences: List[SequenceResult]
    categories: List[CategoryResult]
    overall: Metrics

    @classmethod
    def from_sequences(cls, sequences: Sequence[SequenceResult]) -> "DatasetResult":
        """Average the CDnet way: categories = mean of sequences, overall = mean of categories."""
        by_category: Dict[str, List[SequenceResult]] = {}
        for result in sequences:
            by_category.setdefault(result.category, []).append(result)
        categories = []
        for name, members in by_category.items():
            total = Counts()
            for member in members:
                total += member.counts
            categories.append(CategoryResult(
                name, [m.name for m in members], Metrics.mean([m.metrics for m in members]), total
            ))
        overall = Metrics.mean([c.metrics for c in categories])
        return cls(list(sequences), categories, overall)

    def to_dict(self) -> Dict[str, Any]:
        return {
            "sequences": [s.to_dict() for s in self.sequences],
            "categories": [c.to_dict() for c in self.categories],
            "overall": self.overall.as_dict(),
        }


# --------------------------------------------------------------------------------------------
# Evaluation
# --------------------------------------------------------------------------------------------


def category_of(rel_path: PathLike) -> str:
    """Category of a sequence at ``rel_path`` (relative to the dataset root); see module doc."""
    parts = Path(rel_path).parts
    if len(parts) >= 2:
        return parts[-2]
    name = parts[-1]
    return name.split("_", 1)[0] if "_" in name.strip("_") else name


def evaluate_sequence(
    pred: Optional[Prediction],
    gt_dir: PathLike,
    *,
    name: Optional[str] = None,
    category: Optional[str] = None,
    ignore_roi_bmp: bool = False,
    allow_missing: bool = False,
    skip_first: bool = False,
    first_frame: Optional[int] = None,
    last_frame: Optional[int] = None,
    frames: Optional[Iterable[int]] = None,
    video_start: int = 0,
    video_step: int = 1,
    video_stop: Optional[int] = None,
    quiet: bool = True,
) -> SequenceResult:
    """Evaluate the predicted masks of one sequence against its CDnet ground truth.

    Parameters
    ----------
    pred : path or iterable of (frame_number, (H, W) uint8 mask), or None
        A ``binNNNNNN.png`` folder, a mask video, or masks from Python (a generator works: it is
        consumed once, streaming; a dict ``{frame_number: mask}`` too; frame numbers are CDnet's,
        from 1, so a number below 1 is an error). ``None``: no prediction
        at all (every frame missing).
    gt_dir : path
        CDnet sequence folder (``groundtruth/``, optional ``temporalROI.txt``, ``ROI.bmp``).
    name, category : str, optional
        Defaults: the folder name and :func:`category_of` it.
    ignore_roi_bmp, allow_missing, skip_first, first_frame, last_frame, frames
        See the module docstring and :meth:`GroundTruth.select_frames`.
    video_start, video_step, video_stop : int
        For a mask video: the input frames it holds, as ``bgsub run --start --step --stop``
        (0-based, ``range(video_start, video_stop, video_step)``; see :class:`VideoFrames`).
        Only those frames are evaluated; ``skip_first`` also leaves out the video's first one.
        For a folder, the same frames are selected among its numbered masks. Anything but the
        defaults (0, 1, None) is an error for masks from Python.
    quiet : bool
        No progress bar (it is also off when stderr is not a terminal).

    Returns
    -------
    SequenceResult

    Raises
    ------
    InputError
        Bad ground truth, a prediction of a size that is not a uniform scale of the ground
        truth's, a video frame range for masks from Python, or missing
        predictions without ``allow_missing``.
    """
    video = VideoFrames(video_start, video_step, video_stop)
    gt = open_ground_truth(gt_dir, ignore_roi_bmp=ignore_roi_bmp)
    numbers = gt.select_frames(first_frame=first_frame, last_frame=last_frame, frames=frames,
                               skip_first=skip_first)
    reader = _prediction_reader(pred, video, gt.path)
    # A dataset sequence without any prediction (pred None, allow_missing) counts the frames the
    # videos of the others hold, so the frame totals of the two agree. A folder's masks carry
    # their frame numbers: the range selects among them the frames the run read, as for a video.
    video_range = not video.is_default and (
        pred is None or isinstance(reader, (_VideoReader, _FolderReader)))
    selected = numbers  # before the range: what a suggested range is chosen from
    if video_range:
        # Frames the run did not read have no mask by design: they are not "missing". The
        # video's first frame is the one a background model met without history.
        held = [n for n in numbers
                if video.covers(n) and not (skip_first and n == video.number(0))]
        if not held:  # select_frames() never returns an empty list
            what = "masks" if isinstance(reader, _FolderReader) else "mask video"
            raise InputError(f"no ground-truth frames left to evaluate in {gt.path} among the "
                             f"frames of {what} {reader.label} ({video.flags()}): the "
                             f"ground truth's selected frames are {numbers[0]}-{numbers[-1]}")
        numbers = held
    warnings: List[str] = []
    # Masks past the end of the input the ground truth labels are often another sequence's;
    # sparse ground truth, or a labelled window of the input, states no such end.
    gt_end = gt.sequence_end
    if isinstance(reader, _FolderReader):
        beyond = [n for n in reader.files if n > gt_end] if gt_end is not None else []
        if beyond:
            warnings.append(
                f"{len(beyond)} of the {len(reader.files)} masks in {reader.label} are numbered "
                f"past the ground truth's last frame (up to {reader.frame_name(max(beyond))}; "
                f"{gt.describe_end()}): check that these masks belong to this sequence; "
                "only frames with ground truth were scored")
    elif isinstance(reader, _VideoReader):
        reader.gt_end = gt_end
    zero_warning, shifted = "", False
    if isinstance(reader, _FolderReader):
        shift_end = gt_end if gt_end is not None else max(gt.frames)
        zero_warning, shifted = reader.zero_warning(shift_end), reader.numbered_from_0(shift_end)
        if zero_warning:
            warnings.append(zero_warning)
    # Masks of a contiguous part (or every N-th frame) of the sequence: the options that score
    # just those, rather than --allow-missing, which scores the rest as missed objects. Not for
    # masks numbered from 0: a range would score them against the wrong frames all the same.
    missing_hint = (reader.range_hint(selected, skip_first=skip_first)
                    if isinstance(reader, _FolderReader) and not shifted else "")

    def advice(count: int) -> str:
        # An error drops the warnings: a bin000000.png is named in it (a reason for a missing
        # mask); masks numbered from 0 want renumbering, which no option does.
        zero = f"; {zero_warning}" if zero_warning else ""
        if shifted:
            return zero
        if missing_hint:
            return (f"{zero}; {missing_hint}; or use --allow-missing to count the {count} "
                    "frames without one as background")
        return f"{zero}; use --allow-missing to count them as background"

    if isinstance(reader, _FolderReader) and not allow_missing:
        absent = [n for n in numbers if n not in reader.files]
        if absent:  # fail before reading anything
            raise InputError(reader.missing_message(absent, len(numbers)) + advice(len(absent)))

    counts = Counts()
    seen = set()
    scaled_from: Optional[str] = None  # size of the first prediction brought to the gt's size
    bar = tqdm(total=len(numbers), desc=f"eval {gt.path.name}", unit="frame", file=sys.stderr,
               disable=quiet or not sys.stderr.isatty(), leave=False, dynamic_ncols=True)
    with bar:
        for number, mask in reader.read(numbers):
            if number in seen:
                continue
            seen.add(number)
            labels = gt.labels(number)
            if mask.shape != labels.shape:
                if not is_uniform_scale((mask.shape[1], mask.shape[0]), (gt.width, gt.height)):
                    raise InputError(
                        f"prediction {reader.label} ({reader.frame_name(number)}) is "
                        f"{_size(mask)} but ground truth {gt.frames[number]} is {_size(labels)}"
                    )
                # Masks of `bgsub run --width/--scale`: scored at the ground truth's size, as
                # `bgsub compare` does; nearest neighbour keeps them 0/255.
                scaled_from = scaled_from or _size(mask)
                mask = cv2.resize(mask, (gt.width, gt.height), interpolation=cv2.INTER_NEAREST)
            if int(mask.max()) == 1:
                # 0/1 masks (mask.astype(np.uint8)) would score as all background: a slip, not
                # a prediction.
                raise InputError(
                    f"prediction {reader.label} ({reader.frame_name(number)}) holds 0/1 values; "
                    "masks are 0/255 (foreground above 127): multiply by 255, or give bool masks")
            try:
                counts += count_frame(mask, labels, gt.roi)
            except InputError as err:
                raise InputError(f"{gt.frames[number]}: {err}") from None
            bar.update(1)

        missing = [n for n in numbers if n not in seen]
        if missing and not allow_missing:
            raise InputError(reader.missing_message(missing, len(numbers))
                             + advice(len(missing)))
        for number in missing:  # an absent mask is an all-background prediction
            labels = gt.labels(number)
            counts += count_frame(np.zeros_like(labels), labels, gt.roi)
            bar.update(1)

    notes = list(gt.notes)
    if gt.temporal_roi is not None:
        notes.append(f"temporal ROI {gt.temporal_roi[0]}-{gt.temporal_roi[1]}")
    if missing:
        notes.append(f"{len(missing)} missing frames counted as background")
    if video_range:
        notes.append(f"only the frames of {video.flags()} scored"
                     if isinstance(reader, _FolderReader)
                     else f"mask video read with {video.flags()}")
    if isinstance(reader, _VideoReader) and reader.past_gt is not None:
        past, total = reader.past_gt
        held = f"{total} frames" if total is not None else f"more than {past} frames"
        if total is not None and not video.is_default:
            held += (f" (frames {video.number(0)}-{video.number(total - 1)} read with "
                     f"{video.flags()})")
        warnings.append(
            f"mask video {reader.label} holds {held}, past the end of the ground truth: "
            f"{gt.describe_end()}; check that the video belongs to this sequence (only "
            "frames with ground truth were scored)")
    if scaled_from is not None:
        notes.append(f"{scaled_from} predictions scaled to {gt.width}x{gt.height} (nearest "
                     "neighbour)")
    # A step leaves frames out on purpose: only holes in its grid are gaps.
    step = video.step if video_range else 1
    gaps = len(range(numbers[0], numbers[-1] + 1, step)) - len(numbers)
    if gaps and frames is None:
        # Sparse ground truth (labels for some frames only) is legitimate, but say it: the
        # range in the summary would otherwise read as every frame of it.
        notes.append(f"no ground truth for {gaps} of the frames in that range")
    rel_name = name or gt.path.resolve().name
    return SequenceResult(
        name=rel_name,
        category=category or category_of(rel_name),
        gt_path=str(gt.path),
        pred_path=reader.label,
        counts=counts,
        n_frames=len(numbers),
        first_frame=numbers[0],
        last_frame=numbers[-1],
        missing=missing,
        notes=notes,
        warnings=warnings,
        missing_hint=missing_hint if missing else "",
    )


def find_sequences(gt_root: PathLike) -> List[Path]:
    """CDnet sequence folders under ``gt_root`` at any depth, sorted by relative path."""
    root = Path(gt_root)
    if not root.is_dir():
        raise InputError(f"ground truth {root} is not a folder")
    found: List[Path] = []
    for current, dirs, _files in os.walk(root):
        if "groundtruth" in dirs:
            found.append(Path(current))
            dirs[:] = []  # a sequence's subfolders are its own
        else:
            dirs.sort()
    return sorted(found, key=lambda p: p.relative_to(root).as_posix())


def find_prediction(pred_root: PathLike, rel_path: PathLike,
                    method: Optional[str] = None) -> Optional[Path]:
    """The prediction of the sequence ``rel_path`` in ``pred_root`` (see module doc), or None.

    With ``method``, the masks of that method in a `bgsub compare` report: ``METHOD/`` or
    ``METHOD.<ext>`` inside the sequence's folder ``REL/`` or ``NAME/``.
    """
    root, rel = Path(pred_root), Path(rel_path)
    bases = [root / rel, root / rel.name]
    if method is not None:
        bases = [base / method for base in bases]
    for candidate in bases:
        if candidate.is_dir():
            return candidate
    for base in bases:
        for ext in VIDEO_EXTENSIONS:
            candidate = base.with_name(base.name + ext)
            if candidate.is_file():
                return candidate
    return None


def evaluate_dataset(
    pred_root: PathLike,
    gt_root: PathLike,
    *,
    allow_missing: bool = False,
    method: Optional[str] = None,
    jobs: int = 1,
    scheduler: Optional[str] = None,
    **options: Any,
) -> DatasetResult:
    """Evaluate every sequence under ``gt_root`` against its prediction in ``pred_root``.

    Parameters
    ----------
    pred_root : path
        One prediction per sequence: ``REL/`` or ``NAME/`` (bin pngs) or ``REL.mkv`` /
        ``NAME.mkv`` (any of :data:`VIDEO_EXTENSIONS`).
    gt_root : path
        Dataset root (sequences at any depth).
    allow_missing : bool
        Count missing frames, and sequences without any prediction, as all background.
    method : str, optional
        Score this method's masks of a `bgsub compare` report (see :func:`find_prediction`).
    jobs, scheduler : int, str, optional
        Sequences scored at once in local processes, or on the Dask cluster at ``scheduler``
        (:func:`bgsub.batch.executors.ordered_map`).
    **options
        Passed to :func:`evaluate_sequence` (``ignore_roi_bmp``, ``skip_first``, ...);
        ``video_start``/``video_step``/``video_stop`` apply to every sequence (mask videos and
        folders alike).

    Returns
    -------
    DatasetResult
    """
    root = Path(gt_root)
    sequences = find_sequences(root)
    if not sequences:
        raise InputError(f"no CDnet sequences (folders with groundtruth/) under {root}")
    if not Path(pred_root).is_dir():
        raise InputError(f"predictions {pred_root} must be a folder when the ground truth is a "
                         "dataset of several sequences")
    rels = [seq.relative_to(root) for seq in sequences]
    preds = {rel: find_prediction(pred_root, rel, method) for rel in rels}
    absent = [rel.as_posix() for rel, p in preds.items() if p is None]
    if method is not None and len(absent) == len(rels):
        # A misspelt method, not missing sequences: --allow-missing would score nothing.
        raise InputError(f"no masks of method {method!r} in {pred_root} for any of its "
                         f"{len(rels)} sequences"
                         f"{_methods_held([Path(pred_root) / rel for rel in rels])}")
    if absent and not allow_missing:
        listed = ", ".join(absent[:_MAX_LISTED]) + (", ..." if len(absent) > _MAX_LISTED else "")
        of = f" of method {method!r}" if method is not None else ""
        raise InputError(f"no prediction{of} in {pred_root} for {len(absent)} of {len(rels)} "
                         f"sequences ({listed}); use --allow-missing to count them as background")
    from bgsub.batch.executors import ordered_map

    if scheduler or jobs > 1:
        options["quiet"] = True  # bars of several processes at once would garble the terminal
    calls = [(preds[rel], seq, dict(options, name=rel.name, category=category_of(rel),
                                     allow_missing=allow_missing))
             for seq, rel in zip(sequences, rels)]
    results = ordered_map(_evaluate_call, calls, jobs=jobs, scheduler=scheduler)
    return DatasetResult.from_sequences(results)


def _evaluate_call(call: Tuple[Any, Path, Dict[str, Any]]) -> "SequenceResult":
    """:func:`evaluate_sequence` of ``(pred, gt_dir, keyword arguments)``, for a worker."""
    pred, gt_dir, options = call
    return evaluate_sequence(pred, gt_dir, **options)


def evaluate(pred: PathLike, gt: PathLike, *, method: Optional[str] = None, jobs: int = 1,
             scheduler: Optional[str] = None, **options: Any) -> DatasetResult:
    """Evaluate a sequence or a dataset (whichever ``gt`` is) -> :class:`DatasetResult`.

    A single sequence gives a result with one sequence, one category, and overall = it.
    ``method`` picks one method's masks in a `bgsub compare` report folder ``pred``
    (``METHOD/`` or ``METHOD.mkv``, per sequence for a dataset).
    """
    if isinstance(pred, (str, os.PathLike)):  # not masks handed over from Python
        given_path(pred, what="prediction", hint="a mask folder or a mask video")
    given_path(gt, what="ground truth", hint="a CDnet sequence folder or a dataset root")
    if method is not None:
        _check_method_name(method, pred)
    if not Path(gt).exists():
        raise InputError(f"ground truth {gt} does not exist")
    if is_sequence(gt):
        if method is not None:
            found = find_prediction(pred, method)
            if found is None:
                raise InputError(f"no masks of method {method!r} in {pred} (neither "
                                 f"{method}/ nor {method}.mkv or another video)"
                                 f"{_methods_held([Path(pred)])}")
            pred = found
        return DatasetResult.from_sequences([evaluate_sequence(pred, gt, **options)])
    return evaluate_dataset(pred, gt, method=method, jobs=jobs, scheduler=scheduler, **options)


def _check_method_name(method: str, pred: Any) -> None:
    """``method`` names a mask set in a `bgsub compare` report folder ``pred``."""
    if not method.strip():
        raise InputError("method (--method) is empty; give a method's name, e.g. grbm")
    if "/" in method or "\\" in method or method in (".", ".."):
        raise InputError(f"method (--method) takes a method's name, e.g. grbm, not a path: "
                         f"{method!r}")
    if not isinstance(pred, (str, os.PathLike)):
        raise InputError("method (--method) picks one method's masks in a `bgsub compare` "
                         "report folder, not among masks from Python")
    if not Path(pred).is_dir():
        what = "is not a folder" if Path(pred).exists() else "does not exist"
        raise InputError(f"prediction {pred} {what}; method (--method) picks one method's "
                         "masks in a `bgsub compare` report folder")


# --------------------------------------------------------------------------------------------
# Reports
# --------------------------------------------------------------------------------------------

CSV_COLUMNS = ("level", "name", "category", "frames", "missing", "tp", "fp", "fn", "tn") + \
    METRIC_NAMES


def result_rows(result: DatasetResult) -> List[Dict[str, Any]]:
    """One flat row per sequence, per category and overall (``level`` says which)."""
    rows: List[Dict[str, Any]] = []
    for s in result.sequences:
        rows.append({"level": "sequence", "name": s.name, "category": s.category,
                     "frames": s.n_frames, "missing": len(s.missing), **s.counts.as_dict(),
                     **s.metrics.as_dict()})
    total = Counts()
    for c in result.categories:
        total += c.counts
        members = [s for s in result.sequences if s.category == c.name]
        rows.append({"level": "category", "name": c.name, "category": c.name,
                     "frames": sum(s.n_frames for s in members),
                     "missing": sum(len(s.missing) for s in members), **c.counts.as_dict(),
                     **c.metrics.as_dict()})
    rows.append({"level": "overall", "name": "overall", "category": "",
                 "frames": sum(s.n_frames for s in result.sequences),
                 "missing": sum(len(s.missing) for s in result.sequences), **total.as_dict(),
                 **result.overall.as_dict()})
    return rows


def format_csv(result: DatasetResult) -> str:
    """CSV text with a header row and :data:`CSV_COLUMNS`; undefined metrics are empty cells."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in result_rows(result):
        writer.writerow({k: ("" if row[k] is None else row[k]) for k in CSV_COLUMNS})
    return buffer.getvalue()


def _cell(value: Optional[float], pwc: bool = False) -> str:
    if value is None:
        return "n/a"
    return f"{value:.3f}" if pwc else f"{value:.4f}"


def format_table(result: DatasetResult) -> str:
    """Human-readable table: sequences, then (for several) category means and the overall mean."""
    rows = result_rows(result)
    single = len(result.sequences) == 1
    shown = rows[:1] if single else rows
    names = [r["name"] if r["level"] != "category" else f"[{r['name']}]" for r in shown]
    width = max(12, *(len(n) for n in names))
    header = f"{'sequence':<{width}} {'frames':>6} " + " ".join(
        f"{t:>11}" for t in METRIC_TITLES)
    lines = [header, "-" * len(header)]
    titles = {"category": "categories (mean of their sequences):",
              "overall": "overall (mean of the categories):"}
    previous = "sequence"
    for row, label in zip(shown, names):
        if row["level"] != previous:
            lines.append(titles[row["level"]])
            previous = row["level"]
        cells = " ".join(f"{_cell(row[m], m == 'pwc'):>11}" for m in METRIC_NAMES)
        lines.append(f"{label:<{width}} {row['frames']:>6} {cells}")
    for s in result.sequences:
        c = s.counts
        notes = "; ".join(s.notes)
        lines.append(f"{s.name}: frames {s.first_frame}-{s.last_frame}, TP {c.tp} FP {c.fp} "
                     f"FN {c.fn} TN {c.tn}" + (f" ({notes})" if notes else ""))
    return "\n".join(lines)
