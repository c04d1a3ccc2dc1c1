"""The report of `bgsub compare`: one row per sequence and method, family and overall means
(averaged the CDnet way), as text, CSV and JSON.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from bgsub.errors import OutputError
from bgsub.evaluation.metrics import METRIC_NAMES, METRIC_TITLES, Counts, Metrics
from bgsub.evaluation.report_frames import SequenceFrames
from bgsub.evaluation.results import DatasetResult, SequenceResult

PathLike = Union[str, "Path"]

#: What the fps column measures; printed with every report.
TIMING_NOTE = (
    "fps = frames / seconds spent inside the engine: apply() and the look-back start's "
    "read-ahead (decoding, scoring and writing excluded); each frame is decoded once and fed "
    "to every method."
)

#: The report's files, at the top of the report folder.
REPORT_FILES = ("report.txt", "report.csv", "report.json")
#: The report as one self-contained web page (:mod:`bgsub.evaluation.html_report`), beside them.
HTML_REPORT = "report.html"


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
    frames : list of SequenceFrames
        A few frames of each input (input, ground truth, masks) for the HTML report; not in
        the text, CSV or JSON.
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
    frames: List[SequenceFrames] = field(default_factory=list)

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

    def ranking(self) -> List[ComparisonRow]:
        """The rows that answer "which method is best": the overall means of a dataset, else
        each method's row of the one input, sorted by F (best first, unscored last); empty
        for several inputs without means or without ground truth."""
        rows = list(self.overall) if self.overall else list(self.rows)
        if not self.has_metrics or (not self.overall and len({r.name for r in rows}) > 1):
            return []
        return sorted(rows, key=lambda row: _sort_key(row.metrics))

    def to_text(self) -> str:
        """The comparison as a fixed-width table, after the methods ranked by F and the
        settings that shaped it."""
        lines = [f"bgsub compare: {self.input}", f"methods: {', '.join(self.methods)}"]
        ranked = self.ranking()
        if ranked:
            lines.append("ranked by F: " + ", ".join(
                f"{row.method} {_f_text(row.metrics)}" + (" (best)" if k == 0 else "")
                for k, row in enumerate(ranked)))
        settings = "; ".join(f"{k.replace('_', ' ')}: {setting_text(v)}"
                             for k, v in self.settings.items())
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


#: The method the reports are about: highlighted wherever it is ranked.
OURS = "grbm"


def _sort_key(metrics: Optional[Metrics]) -> float:
    """Best F first; an undefined F (no metrics, or nan) last."""
    f = metrics.f_measure if metrics is not None else math.nan
    return math.inf if math.isnan(f) else -f


def _f_text(metrics: Optional[Metrics]) -> str:
    f = metrics.f_measure if metrics is not None else math.nan
    return "n/a" if math.isnan(f) else f"{f:.3f}"


def setting_text(value: Any) -> str:
    """A setting's value as a reader writes it: "-" for none, yes/no, ``k=v`` lists (engine
    parameters by method: ``mog2: history=200``)."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, dict):
        parts = [f"{k}: {setting_text(v)}" if isinstance(v, dict) else f"{k}={setting_text(v)}"
                 for k, v in value.items()]
        return "; ".join(part for part in parts if not part.endswith(": -")) or "-"
    if isinstance(value, (list, tuple)):
        return "; ".join(map(str, value)) or "-"
    return str(value)


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


def mean_rows(rows: Sequence[ComparisonRow], methods: Sequence[str]) -> Tuple[
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
