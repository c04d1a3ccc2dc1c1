"""CDnet 2014 ground truth: one sequence's labels read frame by frame, and a dataset's
sequences (see :mod:`bgsub.evaluation.cdnet` for the layout and what counts).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Tuple, Union

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.evaluation.metrics import frame_size
from bgsub.io.sources import read_image_quietly

PathLike = Union[str, "os.PathLike[str]"]

_GT_NAME = re.compile(r"^gt(\d+)\.png$", re.IGNORECASE)


def is_sequence(path: PathLike) -> bool:
    """Whether ``path`` is a CDnet sequence folder (it holds a ``groundtruth/`` folder)."""
    return (Path(path) / "groundtruth").is_dir()


def _read_labels(path: Path) -> np.ndarray:
    """Read one ground-truth png as ``(H, W) uint8`` labels (equal-channel colour accepted)."""
    image = read_image_quietly(path, cv2.IMREAD_UNCHANGED)
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
                f"ground truth {path} is {frame_size(labels)} but the sequence's first frame is "
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
            image = read_image_quietly(roi_path, cv2.IMREAD_GRAYSCALE)
            if image is None:
                raise InputError(f"cannot read {roi_path} (pass --no-roi-bmp to ignore it)")
            if image.shape != (height, width):
                raise InputError(
                    f"{roi_path} is {frame_size(image)} but the ground truth is {width}x{height} "
                    "(pass --no-roi-bmp to ignore it)"
                )
            roi = image > 0
            notes.append("ROI.bmp applied")
    return GroundTruth(root, frames, temporal_roi, roi, width, height, notes)



def category_of(rel_path: PathLike) -> str:
    """Category of a sequence at ``rel_path`` (relative to the dataset root); see module doc."""
    parts = Path(rel_path).parts
    if len(parts) >= 2:
        return parts[-2]
    name = parts[-1]
    return name.split("_", 1)[0] if "_" in name.strip("_") else name



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

