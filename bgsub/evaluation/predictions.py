"""Predicted masks of one sequence: a ``binNNNNNN.png`` folder, a mask video, or masks from
Python, each read by a :class:`PredictionReader` that knows its own numbering, range hints and
warnings (see :mod:`bgsub.evaluation.cdnet` for the conventions).
"""

from __future__ import annotations

import os
import re
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.evaluation.groundtruth import GroundTruth
from bgsub.io.sources import VIDEO_SUFFIXES, open_source, read_image_quietly

#: Mask-video extensions recognised when looking for a sequence's prediction in a dataset, in
#: that order: :data:`bgsub.io.sources.VIDEO_SUFFIXES` (one list for every module that names videos).
VIDEO_EXTENSIONS = VIDEO_SUFFIXES

_BIN_NAME = re.compile(r"^bin(\d+)\.(png|bmp|jpe?g|tiff?)$", re.IGNORECASE)
_MAX_LISTED = 5  # missing frames named in a message

PathLike = Union[str, "os.PathLike[str]"]
Prediction = Union[PathLike, Iterable[Tuple[int, np.ndarray]], Mapping[int, np.ndarray]]


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


class PredictionReader(ABC):
    """The predicted masks of one sequence, read frame by frame.

    Each kind of prediction answers for itself: how its masks are numbered and named, which
    ground-truth frames a ``--start/--step/--stop`` range leaves to score, what it warns about
    before and after reading (masks past the end of the ground truth, a ``bin000000.png``), how
    it explains missing masks and which options would score just the masks it has.
    :func:`bgsub.evaluation.cdnet.evaluate_sequence` calls, in this order, :meth:`select`,
    :meth:`inspect`, :meth:`range_hint`, :meth:`absent`, :meth:`read`, :meth:`end_warnings`.

    Attributes
    ----------
    label : str
        Names the prediction in messages (its path, or a description).
    frames : VideoFrames
        The input frames the prediction was written from (``bgsub run --start/--step/--stop``).
    """

    label: str
    frames: VideoFrames
    #: Names this kind of prediction in the error of a range that leaves no frame to score.
    kind = "mask video"

    @abstractmethod
    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        """``(number, (H, W) uint8 mask)`` for each wanted frame number this prediction has."""

    def select(self, gt_path: Path, numbers: Sequence[int], *, skip_first: bool) -> List[int]:
        """The ground-truth frames of ``numbers`` (ascending, 1-based) this prediction was
        written for: those of :attr:`frames`, less its first frame with ``skip_first`` (the
        one a background model met without history). Frames the run did not read have no mask
        by design: they are not "missing"."""
        video = self.frames
        if video.is_default:
            return list(numbers)
        held = [n for n in numbers
                if video.covers(n) and not (skip_first and n == video.number(0))]
        if not held:
            raise InputError(f"no ground-truth frames left to evaluate in {gt_path} among the "
                             f"frames of {self.kind} {self.label} ({video.flags()}): the "
                             f"ground truth's selected frames are {numbers[0]}-{numbers[-1]}")
        return held

    def inspect(self, gt: GroundTruth) -> List[str]:
        """Warnings known before reading, given the ground truth (none by default)."""
        return []

    def range_hint(self, selected: Sequence[int], *, skip_first: bool = False) -> str:
        """The options that score just the frames with a mask, or ``""`` (see the folder's)."""
        return ""

    def absent(self, numbers: Sequence[int]) -> List[int]:
        """Frames of ``numbers`` known to have no mask before reading (none by default)."""
        return []

    def range_note(self) -> str:
        """The result's note on :attr:`frames` (``""`` for every frame from the first)."""
        return "" if self.frames.is_default else f"mask video read with {self.frames.flags()}"

    def end_warnings(self, gt: GroundTruth) -> List[str]:
        """Warnings known after reading (none by default)."""
        return []

    def frame_name(self, number: int) -> str:
        return f"frame {number}"

    def missing_message(self, missing: Sequence[int], total: int) -> str:
        names = ", ".join(self.frame_name(n) for n in missing[:_MAX_LISTED])
        more = ", ..." if len(missing) > _MAX_LISTED else ""
        return (f"{len(missing)} of {total} frames to evaluate have no prediction in "
                f"{self.label} (first: {names}{more})")

    def missing_error(self, missing: Sequence[int], total: int, hint: str) -> str:
        """The error for frames without a mask (without ``allow_missing``): what is missing,
        and what to do (``hint``: :meth:`range_hint`'s options)."""
        return self.missing_message(missing, total) + self._advice(len(missing), hint)

    def _advice(self, count: int, hint: str) -> str:
        if hint:
            return (f"; {hint}; or use --allow-missing to count the {count} frames without one "
                    "as background")
        return "; use --allow-missing to count them as background"


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


def methods_held(folders: Sequence[Path]) -> str:
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


class MaskFolderReader(PredictionReader):
    """A folder of ``binNNNNNN.png`` masks (``.bmp``/``.jpg``/``.tif`` too): the names carry
    the frame numbers, so a ``--start/--step/--stop`` range only selects among them.

    Parameters
    ----------
    folder : Path
    frames : VideoFrames
        The frames `bgsub run` read to write them.
    gt : Path, optional
        The ground truth, named in the advice when the folder holds mask sets instead.
    """

    kind = "masks"

    def __init__(self, folder: Path, frames: Optional[VideoFrames] = None,
                 gt: Optional[Path] = None) -> None:
        self.label = str(folder)
        self.frames = frames if frames is not None else VideoFrames()
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
        # Set by inspect(): the bin000000.png warning, and whether the masks look numbered
        # from 0 (then no frame range helps: they want renumbering).
        self._zero_warning, self._shifted = "", False

    def read(self, numbers: Sequence[int]) -> Iterator[Tuple[int, np.ndarray]]:
        for number in numbers:
            path = self.files.get(number)
            if path is None:
                continue
            mask = read_image_quietly(path, cv2.IMREAD_GRAYSCALE)
            if mask is None:
                raise InputError(f"cannot read predicted mask {path}")
            yield number, mask

    def frame_name(self, number: int) -> str:
        return f"bin{number:06d}.png"


    def inspect(self, gt: GroundTruth) -> List[str]:
        """Masks numbered past the ground truth's end (often another sequence's), and a
        ``bin000000.png`` (with the fix when the masks look numbered from 0)."""
        warnings = []
        gt_end = gt.sequence_end
        beyond = [n for n in self.files if n > gt_end] if gt_end is not None else []
        if beyond:
            warnings.append(
                f"{len(beyond)} of the {len(self.files)} masks in {self.label} are numbered "
                f"past the ground truth's last frame (up to {self.frame_name(max(beyond))}; "
                f"{gt.describe_end()}): check that these masks belong to this sequence; "
                "only frames with ground truth were scored")
        shift_end = gt_end if gt_end is not None else max(gt.frames)
        self._zero_warning = self.zero_warning(shift_end)
        self._shifted = self.numbered_from_0(shift_end)
        if self._zero_warning:
            warnings.append(self._zero_warning)
        return warnings

    def absent(self, numbers: Sequence[int]) -> List[int]:
        return [n for n in numbers if n not in self.files]

    def range_note(self) -> str:
        return "" if self.frames.is_default else f"only the frames of {self.frames.flags()} scored"

    def _advice(self, count: int, hint: str) -> str:
        # An error drops the warnings: a bin000000.png is named in it (a reason for a missing
        # mask); masks numbered from 0 want renumbering, which no option does.
        zero = f"; {self._zero_warning}" if self._zero_warning else ""
        if self._shifted:
            return zero
        return zero + super()._advice(count, hint)

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
        if self._shifted:  # a range would score them against the wrong frames all the same
            return ""
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


class MaskVideoReader(PredictionReader):
    """A mask video: frame ``k`` (0-based) is the mask of frame number ``frames.number(k)``."""

    def __init__(self, path: Path, frames: Optional[VideoFrames] = None) -> None:
        self.label = str(path)
        self.path = path
        self.frames = frames if frames is not None else VideoFrames()
        self.frames_read = 0
        #: The input's last frame number as the ground truth states it
        #: (:attr:`GroundTruth.sequence_end`), when it does (set by :meth:`inspect`).
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

    def inspect(self, gt: GroundTruth) -> List[str]:
        self.gt_end = gt.sequence_end
        return []

    def end_warnings(self, gt: GroundTruth) -> List[str]:
        """A frame past the ground truth's end: the video is longer than the sequence."""
        if self.past_gt is None:
            return []
        past, total = self.past_gt
        video = self.frames
        held = f"{total} frames" if total is not None else f"more than {past} frames"
        if total is not None and not video.is_default:
            held += (f" (frames {video.number(0)}-{video.number(total - 1)} read with "
                     f"{video.flags()})")
        return [f"mask video {self.label} holds {held}, past the end of the ground truth: "
                f"{gt.describe_end()}; check that the video belongs to this sequence (only "
                "frames with ground truth were scored)"]

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


class MaskListReader(PredictionReader):
    """Masks from Python: ``(frame_number, mask)`` pairs or a ``{frame_number: mask}`` dict,
    consumed once (a generator streams). ``frames`` is not the default only for the stand-in
    of a sequence without any prediction (``pred=None``), so that its frame total matches
    the others'."""

    def __init__(self, pairs: Union[Iterable[Tuple[int, np.ndarray]], Mapping[int, np.ndarray]],
                 label: str = "the given predictions", frames: Optional[VideoFrames] = None) -> None:
        self.label = label
        self.frames = frames if frames is not None else VideoFrames()
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


def open_prediction(pred: Optional[Prediction], video: Optional[VideoFrames] = None,
                    gt: Optional[Path] = None) -> PredictionReader:
    """The reader of ``pred``: a mask folder, a mask video, masks from Python, or ``None`` (no
    prediction: every frame missing). ``video`` is the range `bgsub run` read (a range for
    masks from Python is an :class:`InputError`: they number their own frames)."""
    video = video if video is not None else VideoFrames()
    if pred is None:  # a dataset sequence without any prediction (allow_missing)
        return MaskListReader((), label="(no prediction)", frames=video)
    if isinstance(pred, (str, os.PathLike)):
        path = Path(pred)
        if path.is_dir():
            return MaskFolderReader(path, video, gt)
        if path.is_file():
            return MaskVideoReader(path, video)
        raise InputError(f"prediction {path} does not exist")
    _refuse_video_frames(video, "these are masks from Python")
    return MaskListReader(pred)


def _refuse_video_frames(video: VideoFrames, what: str) -> None:
    """Refuse a video frame range for a prediction that numbers its own frames.

    Ignoring it would leave a user who expected a shift with scores of other frames than meant.
    """
    if not video.is_default:
        raise InputError(f"--start/--step/--stop ({video.flags()}) place the frames of a mask "
                         f"video or select those of a mask folder, but {what} that number "
                         "their own frames; use first_frame/last_frame/frames to choose frames")



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

