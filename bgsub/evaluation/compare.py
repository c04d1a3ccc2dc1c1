"""Run several engines on the same frames and compare their speed and CDnet 2014 scores.

Every frame is decoded once and fed to every engine in turn (streaming: memory does not grow
with the length of the input). Only ``engine.apply`` is timed, so each method's frames per
second exclude decoding, scoring and writing. With ground truth, each mask is scored as it is
produced, with :mod:`bgsub.evaluation.cdnet`'s rules (temporal ROI, labels 85/170 ignored, optional
``ROI.bmp``), so the figures equal ``bgsub eval`` run on the masks written here.

The input is one of

* a CDnet sequence folder (``input/`` + ``groundtruth/``): its own ground truth is used;
* a dataset root holding several such sequences (``root/NAME/`` or ``root/CATEGORY/NAME/``):
  one row per sequence and method, then per-family means and the mean over families, averaged
  the CDnet way (:class:`bgsub.evaluation.cdnet.DatasetResult`); the family of ``root/NAME`` is the
  part of ``NAME`` before its first ``_`` (``BMS26_cars1`` -> ``BMS26``), of
  ``root/CATEGORY/NAME`` it is ``CATEGORY``;
* anything :func:`bgsub.io.sources.open_source` reads (video, image folder, glob), with optional
  ground truth given separately.

Outputs in ``report_dir`` (per sequence in ``report_dir/<sequence>/`` for a dataset root):
``<method>/binNNNNNN.png`` masks (or ``<method>.mkv``), ``side_by_side.mp4`` (input | one mask
per method, labelled), and ``report.txt`` / ``report.csv`` / ``report.json`` at the top;
``report.json`` lists these outputs, and a later run with ``overwrite=True`` removes them (and
nothing else) before writing its own.

An input that ends before its ground truth does is scored up to its last frame (as
``bgsub eval --last-frame <end>`` scores its masks); the report's notes and
:attr:`ComparisonReport.warnings` say how many of the ground-truth frames asked for were scored.

Example::

    from bgsub.evaluation.compare import compare_methods
    report = compare_methods("data/real/BMS26_cars1", methods=["grbm", "mog2"],
                             report_dir="cmp", skip_first=True)
    for row in report.rows:
        print(row.method, row.fps, row.metrics.f_measure)
"""

from __future__ import annotations

import contextlib
import csv
import glob
import io
import json
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import cv2
import numpy as np

from bgsub.cli.common import progress
from bgsub.engines import available_engines, create_engine, get_engine_spec
from bgsub.errors import BgsubError, InputError, OutputError, ProcessingError, given_path
from bgsub.evaluation.cdnet import (
    METRIC_NAMES,
    METRIC_TITLES,
    Counts,
    DatasetResult,
    GroundTruth,
    Metrics,
    SequenceResult,
    category_of,
    count_frame,
    find_sequences,
    is_sequence,
    open_ground_truth,
)
from bgsub.io.sinks import VideoSink, hold_interrupts, names_a_folder, open_mask_sink
from bgsub.io.sources import VideoInfo, open_source

PathLike = Union[str, "Path"]

#: What the fps column measures; printed with every report.
TIMING_NOTE = (
    "fps = frames / seconds spent inside engine.apply() (decoding, scoring and writing "
    "excluded); each frame is decoded once and fed to every method."
)

#: Mask outputs: a folder of CDnet binNNNNNN.png, a lossless FFV1 video, or nothing.
MASK_FORMATS = ("png", "mkv", "none")

#: The report's files, at the top of the report folder.
REPORT_FILES = ("report.txt", "report.csv", "report.json")
#: The side-by-side video of each input (in its sequence's folder for a dataset root).
SIDE_BY_SIDE = "side_by_side.mp4"

# Side-by-side tiles are shrunk (never enlarged) to at most this height, and the whole picture
# to at most this width. OpenCV's mp4v writer has no bitrate control (about 0.26 bytes per pixel
# per frame measured on mask tiles), so the file size follows the picture size: 180 px tiles keep
# input + 4 methods on 320x240 frames near 55 KiB per frame.
TILE_HEIGHT = 180
_VIDEO_MAX_WIDTH = 1600
_TILES_PER_ROW = 5


# --------------------------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ComparisonRow:
    """One method on one sequence, or a mean over a family or over all families.

    Attributes
    ----------
    level : str
        ``"sequence"``, ``"family"`` (mean over the family's sequences) or ``"overall"`` (mean
        over the families).
    name : str
        Sequence name, family name, or ``"overall"``.
    family : str
        The sequence's family ("" for the overall row or without ground truth).
    method : str
        Engine name.
    frames : int
        Frames processed (summed for means).
    seconds : float
        Time spent inside ``engine.apply`` for those frames.
    eval_frames : int
        Frames scored against ground truth (0 without ground truth).
    counts : Counts or None
        TP/FP/FN/TN summed over the scored frames (and over sequences for means).
    metrics : Metrics or None
        The seven CDnet metrics (``nan`` where undefined; means skip undefined values);
        ``None`` without ground truth.
    not_ok : int
        Frames whose ``engine.last_status`` was not ``"ok"`` (engines that report trouble).
    notes : tuple of str
    """

    level: str
    name: str
    family: str
    method: str
    frames: int
    seconds: float
    eval_frames: int = 0
    counts: Optional[Counts] = None
    metrics: Optional[Metrics] = None
    not_ok: int = 0
    notes: Tuple[str, ...] = ()

    @property
    def fps(self) -> float:
        """Frames per second of ``engine.apply`` (``nan`` if nothing was timed)."""
        return self.frames / self.seconds if self.seconds > 0 else math.nan

    def to_dict(self) -> Dict[str, Any]:
        """JSON-ready view; undefined metrics are ``None``."""
        return {
            "level": self.level,
            "name": self.name,
            "family": self.family,
            "method": self.method,
            "frames": self.frames,
            "seconds": self.seconds,
            "fps": None if math.isnan(self.fps) else self.fps,
            "eval_frames": self.eval_frames,
            "counts": self.counts.as_dict() if self.counts is not None else None,
            "metrics": self.metrics.as_dict() if self.metrics is not None else None,
            "not_ok": self.not_ok,
            "notes": list(self.notes),
        }


@dataclass
class ComparisonReport:
    """Everything :func:`compare_methods` measured.

    Attributes
    ----------
    input : str
        The input as given.
    methods : list of str
    rows : list of ComparisonRow
        One per sequence and method (level ``"sequence"``), sequences in order.
    families : list of ComparisonRow
        Dataset roots with ground truth: one per family and method (mean of its sequences).
    overall : list of ComparisonRow
        Dataset roots with ground truth: one per method (mean of the family means).
    settings : dict
        The options that shaped the figures (frame range, skip_first, ROI.bmp use, ...).
    report_dir : str or None
        Where the outputs went.
    outputs : list of str
        What this run wrote in ``report_dir``, as paths relative to it (``report.txt``, ...,
        ``mog2``, ``famA_one/side_by_side.mp4``); ``report.json`` lists them so that a later
        run with ``overwrite`` removes exactly these.
    warnings : list of str
        What the caller should be told (``bgsub compare`` prints them on stderr), e.g. an input
        that ends before its ground truth, so that fewer frames were scored than it holds.
    """

    input: str
    methods: List[str]
    rows: List[ComparisonRow] = field(default_factory=list)
    families: List[ComparisonRow] = field(default_factory=list)
    overall: List[ComparisonRow] = field(default_factory=list)
    settings: Dict[str, Any] = field(default_factory=dict)
    report_dir: Optional[str] = None
    outputs: List[str] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)

    @property
    def has_metrics(self) -> bool:
        return any(r.metrics is not None for r in self.rows)

    def all_rows(self) -> List[ComparisonRow]:
        """Sequence rows, then family means, then overall means."""
        return [*self.rows, *self.families, *self.overall]

    def to_dict(self) -> Dict[str, Any]:
        return {
            "input": self.input,
            "methods": list(self.methods),
            "note": TIMING_NOTE,
            "settings": dict(self.settings),
            "rows": [r.to_dict() for r in self.rows],
            "families": [r.to_dict() for r in self.families],
            "overall": [r.to_dict() for r in self.overall],
            "warnings": list(self.warnings),
            "outputs": list(self.outputs),
        }

    def to_csv(self) -> str:
        """One CSV row per sequence/family/overall and method; undefined values are empty."""
        columns = ["level", "name", "family", "method", "frames", "seconds", "fps",
                   "eval_frames", "tp", "fp", "fn", "tn", *METRIC_NAMES, "not_ok"]
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        for row in self.all_rows():
            record: Dict[str, Any] = {
                "level": row.level, "name": row.name, "family": row.family,
                "method": row.method, "frames": row.frames, "seconds": f"{row.seconds:.6f}",
                "fps": "" if math.isnan(row.fps) else f"{row.fps:.3f}",
                "eval_frames": row.eval_frames, "not_ok": row.not_ok,
            }
            if row.counts is not None:
                record.update(row.counts.as_dict())
            if row.metrics is not None:
                record.update({k: ("" if v is None else v)
                               for k, v in row.metrics.as_dict().items()})
            writer.writerow(record)
        return buffer.getvalue()

    def to_text(self) -> str:
        """The comparison as a fixed-width table with the settings that shaped it."""
        lines = [f"bgsub compare: {self.input}", f"methods: {', '.join(self.methods)}"]
        settings = ", ".join(f"{k}={v}" for k, v in self.settings.items())
        if settings:
            lines.append(f"settings: {settings}")
        lines += [TIMING_NOTE, ""]
        with_metrics = self.has_metrics
        name_width = max([8, *(len(r.name) + 2 for r in self.all_rows())])
        method_width = max([6, *(len(m) for m in self.methods)])
        header = (f"{'sequence':<{name_width}} {'method':<{method_width}} {'frames':>6} "
                  f"{'fps':>8}")
        if with_metrics:
            header += f" {'scored':>6} " + " ".join(f"{t:>11}" for t in METRIC_TITLES)
        lines += [header, "-" * len(header)]

        def emit(row: ComparisonRow, label: str) -> None:
            fps = "n/a" if math.isnan(row.fps) else f"{row.fps:.1f}"
            line = f"{label:<{name_width}} {row.method:<{method_width}} {row.frames:>6} {fps:>8}"
            if with_metrics:
                line += f" {row.eval_frames:>6} " + _metric_cells(row.metrics)
            lines.append(line)

        for row in self.rows:
            emit(row, row.name)
        if self.families:
            lines.append("families (mean of their sequences; fps = all frames / all seconds):")
            for row in self.families:
                emit(row, f"[{row.name}]")
        if self.overall:
            lines.append("overall (mean of the families):")
            for row in self.overall:
                emit(row, row.name)
        notes = [(r.name, r.method, n) for r in self.rows for n in r.notes]
        trouble = [r for r in self.rows if r.not_ok]
        if notes or trouble:
            lines.append("")
        for r in trouble:
            lines.append(f"{r.name} / {r.method}: {r.not_ok} of {r.frames} frames reported a "
                         "non-ok status (engine fallback)")
        shown = set()
        for name, method, note in notes:
            if (name, note) not in shown:  # ground-truth notes are the same for every method
                shown.add((name, note))
                lines.append(f"{name}: {note}")
        return "\n".join(lines)

    def write(self, folder: PathLike) -> None:
        """Write ``report.txt``, ``report.csv`` and ``report.json`` into ``folder``."""
        folder = Path(folder)
        self.outputs = [*REPORT_FILES, *(p for p in self.outputs if p not in REPORT_FILES)]
        outputs = {"report.txt": self.to_text() + "\n", "report.csv": self.to_csv(),
                   "report.json": json.dumps(self.to_dict(), indent=2) + "\n"}
        for name, text in outputs.items():
            try:
                (folder / name).write_text(text)
            except OSError as err:
                raise OutputError(f"cannot write {folder / name}: {err.strerror}") from None


def _metric_cells(metrics: Optional[Metrics]) -> str:
    if metrics is None:
        return " ".join(f"{'-':>11}" for _ in METRIC_NAMES)
    cells = []
    for name in METRIC_NAMES:
        value = getattr(metrics, name)
        text = "n/a" if math.isnan(value) else (f"{value:.3f}" if name == "pwc" else
                                                 f"{value:.4f}")
        cells.append(f"{text:>11}")
    return " ".join(cells)


# --------------------------------------------------------------------------------------------
# The side-by-side video
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TileLayout:
    """Where each tile of the side-by-side picture goes.

    ``labels[0]`` is the input, then one label per method; tiles fill rows of at most
    :data:`_TILES_PER_ROW`, each ``tile_width x tile_height`` (even numbers, so every codec
    takes the picture).
    """

    labels: Tuple[str, ...]
    tile_width: int
    tile_height: int
    columns: int
    rows: int

    @property
    def width(self) -> int:
        return self.columns * self.tile_width

    @property
    def height(self) -> int:
        return self.rows * self.tile_height

    @classmethod
    def for_frames(cls, width: int, height: int, labels: Sequence[str], *,
                   tile_height: int = TILE_HEIGHT) -> "TileLayout":
        """Layout for frames of ``width x height``, one tile per label, tiles at most
        ``tile_height`` pixels high (frames are never enlarged)."""
        n = len(labels)
        rows = math.ceil(n / _TILES_PER_ROW)
        columns = math.ceil(n / rows)
        max_width = max(_VIDEO_MAX_WIDTH, columns * tile_height * width / height)
        scale = min(1.0, tile_height / height, max_width / (columns * width))
        tile_w = max(2, int(width * scale) // 2 * 2)
        tile_h = max(2, int(height * scale) // 2 * 2)
        return cls(tuple(labels), tile_w, tile_h, columns, rows)

    def compose(self, frame: np.ndarray, masks: Sequence[np.ndarray]) -> np.ndarray:
        """The picture: ``frame`` then ``masks`` as labelled tiles.

        Parameters
        ----------
        frame : (H, W, 3) uint8 BGR
        masks : sequence of (h, w) uint8 0/255, one per method (any size; resized to the tile)

        Returns
        -------
        (height, width, 3) uint8 BGR picture.
        """
        canvas = np.zeros((self.height, self.width, 3), np.uint8)
        size = (self.tile_width, self.tile_height)
        for k, (label, image) in enumerate(zip(self.labels, [frame, *masks])):
            shrink = image.shape[1] > self.tile_width
            tile = cv2.resize(image, size, interpolation=cv2.INTER_AREA if shrink
                              else cv2.INTER_NEAREST)
            if tile.ndim == 2:
                tile = cv2.cvtColor(tile, cv2.COLOR_GRAY2BGR)
            _draw_label(tile, label)
            # A thin gray frame keeps neighbouring white masks apart.
            cv2.rectangle(tile, (0, 0), (tile.shape[1] - 1, tile.shape[0] - 1), (96, 96, 96), 1)
            r, c = divmod(k, self.columns)
            y, x = r * self.tile_height, c * self.tile_width
            canvas[y:y + self.tile_height, x:x + self.tile_width] = tile
        return canvas


def _draw_label(tile: np.ndarray, text: str) -> None:
    """Write ``text`` in the tile's top-left corner on a dark box (in place)."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    scale = max(0.35, min(0.7, tile.shape[0] / 400))
    thickness = 1
    (tw, th), base = cv2.getTextSize(text, font, scale, thickness)
    cv2.rectangle(tile, (0, 0), (min(tile.shape[1] - 1, tw + 6), th + base + 5), (0, 0, 0), -1)
    cv2.putText(tile, text, (3, th + 3), font, scale, (0, 255, 255), thickness, cv2.LINE_AA)


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Job:
    """One input to process: its frames, its ground truth (if any) and where outputs go."""

    name: str
    family: str
    frames: str  # passed to open_source
    gt: Optional[Path]
    out: Optional[Path]  # folder for this input's masks and video, None = write nothing


def _has_glob(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def _is_cdnet_sequence(path: Path) -> bool:
    return (path / "input").is_dir() and is_sequence(path)


def _plan(input_path: str, gt: Optional[PathLike], report_dir: Optional[Path]) -> Tuple[
        List[_Job], bool, List[str]]:
    """Resolve the input to jobs; returns ``(jobs, is_dataset, notes)``."""
    path = Path(input_path)
    if not path.exists() and not _has_glob(input_path):
        raise InputError(f"input {input_path} does not exist")
    if gt is not None and not is_sequence(gt):
        raise InputError(f"--gt {gt} is not a CDnet sequence folder (it has no groundtruth/)")

    if path.is_dir() and not (path / "input").is_dir():
        sequences = find_sequences(path)
        usable = [s for s in sequences if (s / "input").is_dir()]
        if usable and gt is not None:
            raise InputError(f"{path} is a dataset root whose sequences carry their own ground "
                             "truth: --gt only applies to a single input")
        if usable:
            notes = [f"{s.relative_to(path).as_posix()}: skipped (groundtruth/ but no input/)"
                     for s in sequences if s not in usable]
            jobs = []
            for seq in usable:
                rel = seq.relative_to(path)
                jobs.append(_Job(name=rel.name, family=category_of(rel), frames=str(seq),
                                 gt=seq, out=report_dir / rel if report_dir else None))
            names = [j.name for j in jobs]
            if len(set(names)) != len(names):  # root/a/x and root/b/x: keep the paths apart
                jobs = [_Job(name=s.relative_to(path).as_posix(), family=j.family,
                             frames=j.frames, gt=j.gt, out=j.out) for s, j in zip(usable, jobs)]
            return jobs, True, notes

    seq_gt = Path(gt) if gt is not None else (path if _is_cdnet_sequence(path) else None)
    name = path.resolve().name if path.exists() else path.name  # a glob keeps its pattern
    family = category_of(seq_gt.resolve().name) if seq_gt is not None else ""
    return [_Job(name=name, family=family, frames=input_path, gt=seq_gt, out=report_dir)], \
        False, []


# Names that are files, not folders: `-o cmp.txt` most likely meant the report itself.
_FILE_SUFFIXES = {".txt", ".csv", ".json", ".md", ".html", ".htm", ".pdf", ".png", ".jpg",
                  ".mkv", ".avi", ".mp4", ".mov", ".webm"}


def _check_report_dir(report_dir: PathLike, overwrite: bool) -> Optional[Path]:
    """Create ``report_dir`` or check that it may be filled; raise :class:`OutputError` when it
    holds results (without ``overwrite``), is a file, looks like a file name, or cannot be
    made. ``report_dir`` as given: a trailing slash marks a dotted name as a folder. Returns
    the outermost folder created here (``report_dir`` or a missing parent), or None."""
    given_path(report_dir, what="report folder", hint="a folder name such as cmp/",
               error=OutputError)
    if Path(report_dir).suffix.lower() in _FILE_SUFFIXES and not names_a_folder(report_dir):
        raise OutputError(
            f"{report_dir}: the report goes in a folder (report.txt, .csv and .json are written "
            "inside it); give a folder name such as cmp/")
    report_dir = Path(report_dir)
    created = None
    for folder in (report_dir, *report_dir.parents):
        if folder.exists():
            break
        created = folder
    if created is None:
        if not report_dir.is_dir():
            raise OutputError(f"report folder {report_dir} exists and is not a folder")
        if any(report_dir.iterdir()) and not overwrite:
            raise OutputError(f"report folder {report_dir} exists and is not empty "
                              "(use --overwrite to replace its results)")
    try:
        report_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create report folder {report_dir}: {err.strerror}") from None
    return created


def _remove_if_no_files(folder: Path) -> None:
    """Remove ``folder`` (made by this run, with any parents it needed) when it holds no file,
    only empty folders: a run refused before writing anything leaves no trace."""
    if folder.is_dir() and not any(p.is_file() for p in folder.rglob("*")):
        shutil.rmtree(folder, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# The outputs of this run, and those of a previous one (overwrite)
# --------------------------------------------------------------------------------------------

# Deepest output below the report folder: CATEGORY/NAME/<method> for a dataset root.
_MAX_OUTPUT_DEPTH = 3


class _Outputs:
    """What a run writes in the report folder, and the one-time removal of a previous run's.

    With ``overwrite``, :meth:`clear_previous` (called once the first input and its ground
    truth are accepted, before anything is written) removes the outputs of the compare run that
    filled the folder before, and nothing else: see :func:`remove_previous_outputs`.
    """

    def __init__(self, root: Optional[Path], *, overwrite: bool, methods: Sequence[str],
                 protect: Sequence[Path]) -> None:
        self.root = root
        self.overwrite = overwrite
        self.methods = list(methods)
        self.protect = list(protect)
        self.paths: List[str] = []
        self._cleared = False

    def clear_previous(self) -> None:
        if self._cleared or self.root is None or not self.overwrite:
            return
        self._cleared = True
        remove_previous_outputs(self.root, methods=self.methods, protect=self.protect)

    def add(self, path: Path) -> None:
        if self.root is not None:
            rel = path.relative_to(self.root).as_posix()
            if rel not in self.paths:
                self.paths.append(rel)


def _previous_report(root: Path) -> Tuple[Optional[List[str]], List[str]]:
    """``(outputs, methods)`` listed by ``root/report.json``; outputs ``None`` when it lists
    none (no report, an unreadable one, or one written before reports listed their outputs)."""
    try:
        data = json.loads((root / "report.json").read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None, []
    if not isinstance(data, dict):
        return None, []
    methods = data.get("methods")
    methods = [m for m in methods if isinstance(m, str) and m] if isinstance(methods, list) \
        else []
    outputs = data.get("outputs")
    if not isinstance(outputs, list) or not all(isinstance(p, str) for p in outputs):
        return None, methods
    return list(outputs), methods


def _names_an_output(rel: str, methods: Sequence[str]) -> bool:
    """Whether ``rel`` (relative to the report folder) is a path compare writes: a report file
    at the top, or ``[SEQUENCE/]side_by_side.mp4``, ``<method>`` or ``<method>.mkv`` at most
    :data:`_MAX_OUTPUT_DEPTH` levels down."""
    parts = rel.split("/")
    if not rel or rel.startswith("/") or "\\" in rel or len(parts) > _MAX_OUTPUT_DEPTH \
            or any(part in ("", ".", "..") for part in parts):
        return False
    name = parts[-1]
    if name in REPORT_FILES:
        return len(parts) == 1
    return name == SIDE_BY_SIDE or name in methods or \
        (name.endswith(".mkv") and name[:-len(".mkv")] in methods)


def _outputs_by_name(root: Path, methods: Sequence[str]) -> List[str]:
    """The paths compare's naming rules give, for a folder whose report does not list them:
    the report files, and ``side_by_side.mp4``, ``<method>/`` and ``<method>.mkv`` at the top
    (a single input) or in folders one or two levels down (``NAME/``, ``CATEGORY/NAME/`` of a
    dataset root). Folders named after a method are mask folders, not sequences."""
    found = list(REPORT_FILES)
    per_input = [SIDE_BY_SIDE, *methods, *(f"{m}.mkv" for m in methods)]
    level = [""]
    for depth in range(_MAX_OUTPUT_DEPTH):
        found += [f"{prefix}{name}" for prefix in level for name in per_input]
        if depth == _MAX_OUTPUT_DEPTH - 1:
            break
        below = []
        for prefix in level:
            try:
                children = sorted((root / prefix).iterdir())
            except OSError:
                continue
            below += [f"{prefix}{child.name}/" for child in children
                      if child.is_dir() and not child.is_symlink()
                      and child.name not in methods and not child.name.startswith(".")]
        level = below
    return found


def remove_previous_outputs(root: PathLike, *, methods: Sequence[str] = (),
                            protect: Sequence[PathLike] = ()) -> List[str]:
    """Remove what an earlier compare run wrote in the report folder ``root``, nothing else.

    The outputs are those the earlier run's ``report.json`` lists (``"outputs"``); without
    that list (no report, e.g. after Ctrl-C, or one from an older version) compare's naming
    rules find them (:func:`_outputs_by_name`), for the methods the report names, the
    registered engines and ``methods``. Of a mask folder only its ``binNNNNNN.png`` files go
    (and the folder, once empty); of a video or report file, the file and the temporary file
    an interrupted writer may have left. Folders emptied this way are removed up to ``root``.
    Other files stay. Symbolic links are never followed nor removed.

    Parameters
    ----------
    root : path
        The report folder.
    methods : sequence of str
        Method names besides the registered engines (those of the run about to start).
    protect : sequence of path
        What the run about to start reads (its input, its ground truth): refused when an
        output to remove is, or holds, one of them.

    Returns
    -------
    list of str
        The removed paths, relative to ``root``.

    Raises
    ------
    OutputError
        A protected path would be removed, or a file cannot be.
    """
    from bgsub.io.sinks import _MASK_NAME, _PARTIAL_MASK_NAME

    root = Path(root)
    listed, report_methods = _previous_report(root)
    names = list(dict.fromkeys([*report_methods, *(spec.name for spec in available_engines()),
                                *methods]))
    if listed is None:
        candidates = _outputs_by_name(root, names)
    else:
        candidates = [rel for rel in listed if _names_an_output(rel, names)]

    # What goes, gathered before anything is removed so a protected input stops it all.
    files: List[Path] = []
    folders: List[Path] = []  # mask folders, removed once empty
    for rel in dict.fromkeys(candidates):
        path = root / rel
        name = path.name
        if path.is_symlink():
            continue
        if name in names and path.is_dir():  # a mask folder
            try:
                entries = sorted(path.iterdir())
            except OSError as err:
                raise OutputError(f"cannot read {path}: {err.strerror}") from None
            files += [entry for entry in entries if not entry.is_symlink() and entry.is_file()
                      and (_MASK_NAME.fullmatch(entry.name)
                           or _PARTIAL_MASK_NAME.fullmatch(entry.name))]
            folders.append(path)
        elif name in REPORT_FILES or name == SIDE_BY_SIDE \
                or (name.endswith(".mkv") and name[:-len(".mkv")] in names):
            # The file, and the one an interrupted video writer leaves (sinks._partial_path).
            partial = path.with_name(f".{path.stem}.partial{path.suffix}")
            files += [p for p in (path, partial) if p.is_file() and not p.is_symlink()]
    guarded = {Path(p).resolve() for p in protect}
    for path in [*files, *folders]:
        resolved = path.resolve()
        if resolved in guarded or any(parent in guarded for parent in resolved.parents):
            raise OutputError(f"{path} was written by an earlier bgsub compare but is part of "
                              "this run's input: --overwrite will not remove it; write the "
                              "report elsewhere")

    removed: List[str] = []
    emptied = set()
    for path in files:
        try:
            path.unlink()
        except FileNotFoundError:
            continue
        except OSError as err:
            raise OutputError(f"cannot remove {path} (left by an earlier bgsub compare): "
                              f"{err.strerror}") from None
        removed.append(path.relative_to(root).as_posix())
        emptied.add(path.parent)
    emptied.update(folders)
    # Deepest first, so a sequence folder is looked at after its mask folders.
    for folder in sorted(emptied, key=lambda p: len(p.parts), reverse=True):
        while folder != root and root in folder.parents:
            try:
                folder.rmdir()  # only when empty
            except OSError:
                break
            removed.append(folder.relative_to(root).as_posix() + "/")
            folder = folder.parent
    return removed


def _read_paths(jobs: Sequence[_Job]) -> List[Path]:
    """What the jobs read: their frames (a sequence's input/, a glob's matches) and their
    ground truth's files; outputs of an earlier run found among them are not removed."""
    paths: List[Path] = []
    for job in jobs:
        frames = Path(job.frames)
        if (frames / "input").is_dir():
            paths.append(frames / "input")
        elif frames.exists():
            paths.append(frames)
        elif _has_glob(job.frames):
            paths += [Path(p) for p in glob.glob(job.frames)]
        if job.gt is not None:
            paths += [job.gt / "groundtruth", job.gt / "temporalROI.txt", job.gt / "ROI.bmp"]
    return paths


# --------------------------------------------------------------------------------------------
# Running one input
# --------------------------------------------------------------------------------------------


@dataclass
class _Scoring:
    """Ground truth of one input and the frame numbers (1-based) to score."""

    gt: GroundTruth
    numbers: List[int]
    resize: Optional[Tuple[int, int]]  # (w, h) to bring masks to the ground truth's size
    # What this run would score were the input long enough (frame range, --max-frames and
    # skip_first applied, but not the input's end): ``numbers`` falls short of it when the
    # input ends before its ground truth does.
    requested: List[int] = field(default_factory=list)


def _frame_span(numbers: Sequence[int]) -> str:
    return f"{numbers[0]}-{numbers[-1]}" if len(numbers) > 1 else f"{numbers[0]}"


def _short_input_note(scored: int, requested: Sequence[int], input_end: int) -> str:
    """``"scored 16 of 276 ground-truth frames (25-300): the input ends at frame 40"``."""
    return (f"scored {scored} of {len(requested)} ground-truth frames ({_frame_span(requested)}): "
            f"the input ends at frame {input_end}")


def _scoring(job: _Job, info: VideoInfo, *, start: int, stop: Optional[int], step: int,
             skip_first: bool, ignore_roi_bmp: bool, resized: bool,
             tolerate_empty: bool) -> Tuple[Optional[_Scoring], List[str], List[str]]:
    """Which frames of ``job`` get scored: ``(scoring, notes, warnings)``, ``scoring`` None when
    none can be."""
    if job.gt is None:
        return None, [], []
    gt = open_ground_truth(job.gt, ignore_roi_bmp=ignore_roi_bmp)
    if (info.width, info.height) != (gt.width, gt.height) and not resized:
        raise InputError(f"frames of {job.frames} are {info.width}x{info.height} but the ground "
                         f"truth in {job.gt} is {gt.width}x{gt.height}")
    # Frame numbers (1-based) this run asks for, then those it processes: the input's end,
    # when known up front, may cut the request short.
    limit = max(gt.frames)
    if stop is not None:
        limit = min(limit, stop)
    asked = range(start + 1, limit + 1, step)
    last = limit
    if info.frame_count is not None:
        last = min(last, start + (info.frame_count - 1) * step + 1)
    processed = range(start + 1, last + 1, step)
    if skip_first:
        # The first frame the engines see has no history; a frame later in the input (say the
        # start of CDnet traffic's temporal ROI, frame 900) has plenty and is scored.
        asked, processed = asked[1:], processed[1:]
    try:
        requested = gt.select_frames(frames=asked)
    except InputError as err:
        if not tolerate_empty:
            raise
        return None, [f"not scored: {err}"], []
    try:
        numbers = gt.select_frames(frames=processed)
    except InputError:
        # The input ends before the first frame to score, e.g. before a temporal ROI opens.
        message = (f"{job.frames} ends at frame {last}, before the first ground-truth frame to "
                   f"score ({requested[0]}; {len(requested)} frames, "
                   f"{_frame_span(requested)}, in {job.gt})")
        if not tolerate_empty:
            raise InputError(message) from None
        return None, [f"not scored: {message}"], [f"{job.name}: not scored: {message}"]
    resize = (gt.width, gt.height) if (info.width, info.height) != (gt.width, gt.height) \
        else None
    warnings = []
    input_end = (start + (info.frame_count - 1) * step + 1 if info.frame_count is not None
                 else None)
    gt_end = gt.sequence_end  # None: sparse ground truth, or a window; it states no end
    if stop is None and input_end is not None and gt_end is not None and input_end > gt_end:
        # As `bgsub eval` says of masks past the ground truth: often another clip's frames.
        warnings.append(f"{job.name}: {job.frames} holds frames up to {input_end}, past the "
                        f"ground truth's last ({max(gt.frames)} in {job.gt}): check that the "
                        "ground truth belongs to this input; only frames with ground truth "
                        "are scored")
    return _Scoring(gt, numbers, resize, requested), list(gt.notes), warnings


def _run_job(job: _Job, methods: Sequence[str], params: Mapping[str, Mapping[str, Any]], *,
             source_options: Dict[str, Any], max_frames: Optional[int], skip_first: bool,
             ignore_roi_bmp: bool, masks: str, video: bool, tile_height: int, overwrite: bool,
             quiet: bool, tolerate_empty: bool, written: "_Outputs"
             ) -> Tuple[List[ComparisonRow], List[str]]:
    """Run ``methods`` on one input; returns its rows and the warnings for stderr."""
    options = dict(source_options)
    start, step = options["start"], options["step"]
    if max_frames is not None:
        limit = start + max_frames * step
        options["stop"] = limit if options["stop"] is None else min(options["stop"], limit)
    resized = options.get("scale") is not None or options.get("width") is not None

    with open_source(job.frames, **options) as source:
        info = source.info
        scoring, notes, warnings = _scoring(
            job, info, start=start, stop=options["stop"], step=step, skip_first=skip_first,
            ignore_roi_bmp=ignore_roi_bmp, resized=resized, tolerate_empty=tolerate_empty)
        to_score = set(scoring.numbers) if scoring else set()
        mask_size = scoring.resize if scoring and scoring.resize else (info.width, info.height)
        engines = {m: create_engine(m, **params.get(m, {})) for m in methods}
        seconds = dict.fromkeys(methods, 0.0)
        not_ok = dict.fromkeys(methods, 0)
        counts = {m: Counts() for m in methods}
        scored: List[int] = []
        n_frames = 0

        # The input and its ground truth are accepted: a previous run's results may go.
        written.clear_previous()
        if job.out is not None and (video or masks != "none"):
            # A dataset root's per-sequence folder (video sinks need their folder to exist).
            try:
                job.out.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise OutputError(f"cannot create {job.out}: {err.strerror}") from None
        stopped: Optional[KeyboardInterrupt] = None
        try:
            with contextlib.ExitStack() as stack:
                sinks = _open_mask_sinks(stack, job.out, methods, masks, size=mask_size,
                                         fps=info.fps, overwrite=overwrite, written=written)
                layout = TileLayout.for_frames(info.width, info.height, ["input", *methods],
                                               tile_height=tile_height)
                picture = None
                if video and job.out is not None:
                    written.add(job.out / SIDE_BY_SIDE)
                    picture = stack.enter_context(VideoSink(
                        job.out / SIDE_BY_SIDE, fps=info.fps, width=layout.width,
                        height=layout.height, overwrite=overwrite))
                frames = progress(source, total=info.frame_count, desc=job.name, quiet=quiet)
                for index, frame in frames:
                    number = index + 1
                    labels = scoring.gt.labels(number) if number in to_score else None
                    outputs, took, frame_counts, trouble = [], {}, {}, set()
                    for method, engine in engines.items():
                        t0 = time.perf_counter()
                        mask = engine.apply(frame)
                        took[method] = time.perf_counter() - t0
                        mask = _checked_mask(mask, method, info)
                        status = getattr(engine, "last_status", "ok")
                        if status is not None and status != "ok":
                            trouble.add(method)
                        if mask_size != (info.width, info.height):
                            mask = cv2.resize(mask, mask_size, interpolation=cv2.INTER_NEAREST)
                        if labels is not None:
                            try:
                                frame_counts[method] = count_frame(mask, labels,
                                                                   scoring.gt.roi)
                            except InputError as err:
                                raise InputError(f"{scoring.gt.frames[number]}: {err}") from None
                        outputs.append(mask)
                    tiles = layout.compose(frame, outputs) if picture is not None else None
                    # A frame goes to every output and into the figures or, when interrupted,
                    # to none: a partial report describes exactly the masks written.
                    with hold_interrupts():
                        for method, mask in zip(engines, outputs):
                            if method in sinks:
                                sinks[method].write(mask, index)
                        if picture is not None:
                            picture.write(tiles)
                        for method in engines:
                            seconds[method] += took[method]
                            not_ok[method] += method in trouble
                            if labels is not None:
                                counts[method] += frame_counts[method]
                        if labels is not None:
                            scored.append(number)
                        n_frames += 1
        except KeyboardInterrupt as stop:  # the sinks have closed their partial outputs
            stopped = stop
    if n_frames == 0:
        if stopped is not None:
            raise stopped
        raise InputError(f"{job.frames}: no frames in the requested range")

    # (Decoding ended well before the end the video declares; not asked when interrupted.)
    short = source.truncation() if stopped is None else None
    if short:
        notes.append(short)
        warnings.append(short)
    if stopped is not None:
        notes.append(f"stopped by {str(stopped) or 'Ctrl-C'} after {n_frames} frames: the "
                     "figures cover those")
        warnings.append(f"{job.name}: {notes[-1]}")
    if scoring is not None:
        # `number` is now the last frame read. Frames the source promised but never delivered
        # (a video that states the wrong length, or none) are not scored, like those past an
        # end known up front: the figures are those of `bgsub eval --last-frame <end>` on the
        # masks written here.
        if not scored:
            notes.append(f"not scored: {job.frames} ends at frame {number}, before the first "
                         f"ground-truth frame to score ({scoring.requested[0]})")
            warnings.append(f"{job.name}: {notes[-1]}")
            scoring = None
        else:
            notes.append(f"scored frames {_frame_span(scored)} ({len(scored)} frames)")
            if len(scored) < len(scoring.requested) and stopped is None:
                notes.append(_short_input_note(len(scored), scoring.requested, number))
                warnings.append(f"{job.name}: {notes[-1]}")
    rows = []
    for method in methods:
        metrics = counts[method].metrics() if scoring is not None else None
        rows.append(ComparisonRow(
            level="sequence", name=job.name, family=job.family, method=method,
            frames=n_frames, seconds=seconds[method],
            eval_frames=len(scored) if scoring else 0,
            counts=counts[method] if scoring else None, metrics=metrics,
            not_ok=not_ok[method], notes=tuple(notes)))
    if stopped is not None:
        raise _Partial(rows, warnings, stopped)
    return rows, warnings


def _job_elsewhere(call: Tuple[_Job, Dict[str, Any]]) -> Tuple[List[ComparisonRow], List[str],
                                                               List[str]]:
    """:func:`_run_job` in a worker: its rows, warnings and the report files it wrote."""
    job, options = call
    written = _Outputs(options.pop("root"), overwrite=False, methods=options["methods"],
                       protect=[])
    rows, warnings = _run_job(job, options.pop("methods"), options.pop("params"), quiet=True,
                              written=written, **options)
    return rows, warnings, written.paths


def _run_jobs_elsewhere(jobs: Sequence[_Job], options: Dict[str, Any], report: "ComparisonReport",
                        written: "_Outputs", *, workers: int, scheduler: Optional[str]) -> None:
    """Run the jobs on local processes or Dask, adding their rows, warnings and files to
    ``report`` and ``written`` in the jobs' order. The previous run's outputs go first (every
    ground truth was accepted already)."""
    from bgsub.batch.executors import ordered_map

    written.clear_previous()
    calls = [(job, dict(options, root=written.root)) for job in jobs]
    for rows, warnings, paths in ordered_map(_job_elsewhere, calls, jobs=workers,
                                             scheduler=scheduler):
        report.rows.extend(rows)
        report.warnings.extend(warnings)
        written.paths.extend(path for path in paths if path not in written.paths)


class _Partial(Exception):
    """Ctrl-C (or SIGTERM) stopped a job after some frames: its rows so far, and the interrupt
    to raise again once they are in the report."""

    def __init__(self, rows: List[ComparisonRow], warnings: List[str],
                 stop: KeyboardInterrupt) -> None:
        super().__init__("interrupted")
        self.rows, self.warnings, self.stop = rows, warnings, stop


def _checked_mask(mask: Any, method: str, info: VideoInfo) -> np.ndarray:
    if not isinstance(mask, np.ndarray) or mask.shape != (info.height, info.width) \
            or mask.dtype != np.uint8:
        shape = getattr(mask, "shape", None)
        raise ProcessingError(f"method {method!r} returned a mask of shape {shape}, expected "
                              f"({info.height}, {info.width}) uint8")
    return mask


def _open_mask_sinks(stack: contextlib.ExitStack, out: Optional[Path], methods: Sequence[str],
                     masks: str, *, size: Tuple[int, int], fps: float, overwrite: bool,
                     written: "_Outputs") -> Dict[str, Any]:
    if out is None or masks == "none":
        return {}
    sinks = {}
    for method in methods:
        target = out / (method if masks == "png" else f"{method}.mkv")
        written.add(target)
        sinks[method] = stack.enter_context(open_mask_sink(
            target, width=size[0], height=size[1], fps=fps, overwrite=overwrite))
    return sinks


# --------------------------------------------------------------------------------------------
# Means
# --------------------------------------------------------------------------------------------


def _means(rows: Sequence[ComparisonRow], methods: Sequence[str]) -> Tuple[
        List[ComparisonRow], List[ComparisonRow]]:
    """Per-family and overall mean rows, averaged by :class:`DatasetResult` (the CDnet way)."""
    families: List[ComparisonRow] = []
    overall: List[ComparisonRow] = []
    for method in methods:
        mine = [r for r in rows if r.method == method and r.metrics is not None]
        if not mine:
            continue
        result = DatasetResult.from_sequences([
            SequenceResult(name=r.name, category=r.family, gt_path="", pred_path="",
                           counts=r.counts, n_frames=r.eval_frames, first_frame=0, last_frame=0)
            for r in mine
        ])
        for category in result.categories:
            members = [r for r in mine if r.family == category.name]
            families.append(_mean_row("family", category.name, category.name, method, members,
                                      category.metrics, category.counts))
        total = Counts()
        for category in result.categories:
            total += category.counts
        overall.append(_mean_row("overall", "overall", "", method, mine, result.overall, total))
    families.sort(key=lambda r: (r.name, methods.index(r.method)))
    return families, overall


def _mean_row(level: str, name: str, family: str, method: str,
              members: Sequence[ComparisonRow], metrics: Metrics, counts: Counts
              ) -> ComparisonRow:
    return ComparisonRow(
        level=level, name=name, family=family, method=method,
        frames=sum(r.frames for r in members), seconds=sum(r.seconds for r in members),
        eval_frames=sum(r.eval_frames for r in members), counts=counts, metrics=metrics,
        not_ok=sum(r.not_ok for r in members),
    )


# --------------------------------------------------------------------------------------------
# The entry point
# --------------------------------------------------------------------------------------------


def compare_methods(
    input_path: PathLike,
    *,
    methods: Optional[Sequence[str]] = None,
    report_dir: Optional[PathLike] = None,
    gt: Optional[PathLike] = None,
    params: Optional[Mapping[str, Mapping[str, Any]]] = None,
    skip_first: bool = False,
    ignore_roi_bmp: Optional[bool] = None,
    start: int = 0,
    stop: Optional[int] = None,
    step: int = 1,
    scale: Optional[float] = None,
    width: Optional[int] = None,
    fps: Optional[float] = None,
    max_frames: Optional[int] = None,
    masks: str = "png",
    video: bool = True,
    tile_height: int = TILE_HEIGHT,
    overwrite: bool = False,
    quiet: bool = True,
    workers: int = 1,
    scheduler: Optional[str] = None,
) -> ComparisonReport:
    """Run ``methods`` on the same frames; time them and score them against ground truth.

    Parameters
    ----------
    input_path : path
        A CDnet sequence folder, a dataset root of such sequences, or a video / image folder /
        glob pattern (see the module docstring).
    methods : sequence of str, optional
        Registered engine names; default all registered engines.
    report_dir : path, optional
        Where masks, side-by-side videos and ``report.{txt,csv,json}`` go; ``None`` writes
        nothing (figures only). An existing non-empty folder needs ``overwrite``.
    gt : path, optional
        CDnet sequence folder with the ground truth of a single input (default: the input
        itself when it is a CDnet sequence). Not allowed with a dataset root.
    params : ``{method: {param: value}}``, optional
        Engine parameters.
    skip_first : bool
        Do not score the first processed frame (the engines have seen nothing before it).
        When processing starts at frame 1 this is ``bgsub eval --skip-first`` (which leaves out
        frame 1); with ``start`` it leaves out the first frame actually processed.
    ignore_roi_bmp : bool, optional
        Ignore ``ROI.bmp``; default: ignored for dataset roots (the real CDnet traffic ROI.bmp
        has the wrong size), used for a single sequence.
    start, stop, step, scale, width, fps
        Frame range, resizing and frame rate, as :func:`bgsub.io.sources.open_source`; applied to
        every sequence. Resized masks are brought back to the ground truth's size (nearest
        neighbour) for scoring and writing.
    max_frames : int, optional
        Process at most this many frames per sequence.
    masks : {"png", "mkv", "none"}
        ``<method>/binNNNNNN.png``, lossless ``<method>.mkv``, or no masks.
    video : bool
        Write ``side_by_side.mp4`` per input.
    tile_height : int
        Largest height of one tile of the side-by-side video (frames are never enlarged).
    overwrite : bool
        Replace earlier results in ``report_dir``: once the (first) input and its ground truth
        are accepted, the outputs of the compare run that wrote there before are removed (those
        its ``report.json`` lists, else those compare's naming rules give; see
        :func:`remove_previous_outputs`), so the folder holds this run's results only; other
        files stay.
    quiet : bool
        No progress bars (they are also off when stderr is not a terminal).
    workers, scheduler : int, str, optional
        The inputs of a dataset run at once in local processes, or on the Dask cluster at
        ``scheduler`` (:func:`_run_jobs_elsewhere`); the methods must be registered in the
        workers too (built-in ones are).

    Returns
    -------
    ComparisonReport
        Its ``warnings`` say when an input ends before its ground truth does (frames the run
        asked for that were never scored), also stated in the report's notes.

    Raises
    ------
    InputError
        Unknown method or parameter, missing or unreadable input or ground truth.
    OutputError
        ``report_dir`` exists and is not empty (without ``overwrite``), or cannot be written.
    """
    input_text = str(input_path)
    names = list(methods) if methods else [spec.name for spec in available_engines()]
    if not names:
        raise InputError("no methods to compare")
    duplicates = sorted({m for m in names if names.count(m) > 1})
    if duplicates:
        raise InputError(f"method {duplicates[0]!r} is listed twice")
    params = dict(params or {})
    for method in params:
        if method not in names:
            raise InputError(f"parameters given for {method!r}, which is not among the methods")
    for method in names:
        # Built once here so an unknown method, a bad parameter or a missing model file fails
        # before anything is decoded or written.
        get_engine_spec(method).create(**params.get(method, {}))
    if masks not in MASK_FORMATS:
        raise InputError(f"masks must be one of {', '.join(MASK_FORMATS)}, not {masks!r}")
    if max_frames is not None and max_frames < 1:
        raise InputError(f"max_frames must be at least 1, not {max_frames}")
    if tile_height < 16:
        raise InputError(f"tile height must be at least 16 pixels, not {tile_height}")

    out = Path(report_dir) if report_dir is not None else None
    jobs, is_dataset, plan_notes = _plan(input_text, gt, out)
    ignore_roi = is_dataset if ignore_roi_bmp is None else bool(ignore_roi_bmp)
    for job in jobs:  # bad ground truth (e.g. a mis-sized ROI.bmp) fails before any output
        if job.gt is not None:
            open_ground_truth(job.gt, ignore_roi_bmp=ignore_roi)
    created = _check_report_dir(report_dir, overwrite) if out is not None else None
    source_options = dict(start=start, stop=stop, step=step, scale=scale, width=width, fps=fps)

    report = ComparisonReport(
        input=input_text, methods=names, report_dir=str(out) if out else None,
        settings={
            "start": start, "stop": stop, "step": step, "scale": scale, "width": width,
            "max_frames": max_frames, "skip_first": skip_first, "roi_bmp": not ignore_roi,
            "params": {m: dict(v) for m, v in params.items()},
        },
    )
    # With overwrite, the previous run's outputs go once the first input is accepted (so a
    # mistyped --gt or a frame-size mismatch leaves them in place), and only they.
    written = _Outputs(out, overwrite=overwrite, methods=names, protect=_read_paths(jobs))
    outer = progress(jobs, total=len(jobs), desc="sequences", quiet=quiet or not is_dataset,
                     unit="seq")
    stopped: Optional[KeyboardInterrupt] = None
    run_options = dict(methods=names, params=params, source_options=source_options,
                       max_frames=max_frames, skip_first=skip_first, ignore_roi_bmp=ignore_roi,
                       masks=masks, video=video, tile_height=tile_height, overwrite=overwrite,
                       tolerate_empty=is_dataset)
    if len(jobs) > 1 and (workers > 1 or scheduler):
        outer.close()
        outer = []  # the loop below is this process's; the jobs run elsewhere
        try:
            _run_jobs_elsewhere(jobs, run_options, report, written, workers=workers,
                                scheduler=scheduler)
        except (BgsubError, KeyboardInterrupt):
            if created is not None:
                _remove_if_no_files(created)
            raise
    try:
        for job in outer:
            try:
                rows, warnings = _run_job(
                    job, names, params, source_options=source_options, max_frames=max_frames,
                    skip_first=skip_first, ignore_roi_bmp=ignore_roi, masks=masks, video=video,
                    tile_height=tile_height, overwrite=overwrite, quiet=quiet,
                    tolerate_empty=is_dataset, written=written)
            except _Partial as partial:
                rows, warnings, stopped = partial.rows, partial.warnings, partial.stop
            except KeyboardInterrupt as stop:  # before the job's first frame
                if not report.rows:
                    raise
                rows, warnings, stopped = [], [], stop
            report.rows.extend(rows)
            report.warnings.extend(warnings)
            if stopped is not None:
                break
    except (BgsubError, KeyboardInterrupt):  # refused or stopped before any result
        if created is not None:
            _remove_if_no_files(created)
        raise
    if stopped is not None and len(report.rows) < len(jobs) * len(names):
        report.warnings.append(f"stopped by {str(stopped) or 'Ctrl-C'}: "
                               f"{len(report.rows) // len(names)} of {len(jobs)} inputs run")
    if is_dataset:
        report.families, report.overall = _means(report.rows, names)
    if plan_notes:
        report.settings["skipped"] = plan_notes
    if out is not None:
        written.clear_previous()
        report.outputs = list(written.paths)
        report.write(out)
    if stopped is not None:
        # The figures of the frames processed are in the report folder; the caller learns of
        # the interrupt, with the report attached (bgsub compare prints it).
        stopped.report = report  # type: ignore[attr-defined]
        raise stopped
    return report
