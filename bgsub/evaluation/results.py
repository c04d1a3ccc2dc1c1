"""Evaluation results: per sequence, per category and overall, and their tables (text, CSV,
JSON-ready dicts). Averaging is CDnet's (see :mod:`bgsub.evaluation.cdnet`).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence

from bgsub.evaluation.metrics import METRIC_NAMES, METRIC_TITLES, Counts, Metrics

_MAX_LISTED = 5  # missing frames named in a result



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
