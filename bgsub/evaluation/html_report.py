"""The report of `bgsub compare` as one self-contained web page, ``report.html``.

Nothing comes from the network: the style sheet is inline, the charts are inline SVG drawn
here, the pictures are ``data:`` URIs (a few frames per input, shrunk; see
:mod:`bgsub.evaluation.report_frames`). Every text that comes from the run (sequence, family and
method names, the input's path, notes) is HTML-escaped.

The page leads with the answer: the methods ranked by F (:meth:`ComparisonReport.ranking`), the
best marked and ``grbm`` highlighted, and a sentence on what F, precision and recall mean. Then
the warnings, bar charts of the F-measure per method (and, for a dataset root, per sequence and
per family; frames per second when nothing was scored), the metrics table (one row per sequence
and method, then family and overall means), the settings as a table, and per input
its frames: input, ground truth (when there is one) and each method's mask, and its
``side_by_side.mp4``: played in the page when it is H.264, linked otherwise (by a relative
address, so the page and the videos move together).
"""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Callable, List, Optional, Sequence, Tuple, Union
from urllib.parse import quote

from bgsub.errors import OutputError
from bgsub.evaluation.compare_report import (OURS, TIMING_NOTE, ComparisonReport, ComparisonRow,
                                             setting_text)
from bgsub.evaluation.metrics import METRIC_NAMES, METRIC_TITLES
from bgsub.evaluation.report_frames import THUMB_WIDTH, Picture, SequenceFrames

PathLike = Union[str, "Path"]

#: Bar colours, one per method in order (cycled), chosen to stay apart for colour-blind readers.
PALETTE = ("#0072b2", "#e69f00", "#009e73", "#cc79a7", "#56b4e9", "#d55e00", "#f0e442",
           "#000000")

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; background: #fff; }
h1 { font-size: 1.4em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #eee; } td.text { text-align: left; }
tr.family td { background: #f4f4f4; } tr.overall td { background: #e8eef8; font-weight: bold; }
.note { color: #555; font-size: 0.85em; } .warn { color: #a00; }
figure { display: inline-block; margin: 0 0.4em 0.4em 0; text-align: center; }
figcaption { font-size: 0.75em; color: #333; }
img { display: block; image-rendering: pixelated; border: 1px solid #999; }
figure img { width: THUMB_WIDTHpx; height: auto; }
tr.best td { font-weight: bold; } tr.ours td { background: #fff4d6; }
.mark { color: #0a6; font-weight: bold; }
.frame { margin-bottom: 0.6em; }
video { display: block; max-width: 100%; background: #000; }
""".replace("THUMB_WIDTH", str(THUMB_WIDTH))  # every thumbnail one size, whatever its frame's

# Chart geometry (pixels).
_LABEL_W, _BAR_AREA_W, _VALUE_W = 190, 380, 60
_BAR_H, _GROUP_GAP, _TOP = 14, 8, 28


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _number(value: Optional[float], digits: int = 4) -> str:
    return "n/a" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def bar_chart_svg(title: str, groups: Sequence[Tuple[str, Sequence[Tuple[str, float]]]],
                  methods: Sequence[str], *, top: Optional[float] = None) -> str:
    """A horizontal grouped bar chart as an inline ``<svg>`` element.

    Parameters
    ----------
    title : str
        Written above the bars.
    groups : sequence of (label, [(method, value), ...])
        One group of bars per label (e.g. a sequence), one bar per method; NaN values draw no
        bar and read "n/a".
    methods : sequence of str
        Every method, in order: gives each its colour (:data:`PALETTE`) and the legend.
    top : float, optional
        The value at the right end of the axis (1 for F-measures); default the largest value.
    """
    values = [v for _, bars in groups for _, v in bars if not math.isnan(v)]
    top = top if top is not None else max([*values, 0.0]) or 1.0
    colour = {m: PALETTE[k % len(PALETTE)] for k, m in enumerate(methods)}
    parts: List[str] = []
    y = _TOP + 18
    for label, bars in groups:
        group_h = len(bars) * _BAR_H
        parts.append(f'<text x="{_LABEL_W - 6}" y="{y + group_h / 2 + 4:.1f}" '
                     f'text-anchor="end">{_e(label)}</text>')
        for method, value in bars:
            parts.append(_bar(y, method, value, top, colour[method]))
            y += _BAR_H
        y += _GROUP_GAP
    width = _LABEL_W + _BAR_AREA_W + _VALUE_W
    axis = _axis(top, _TOP + 18, y)
    legend = _legend(methods, colour)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{y + 18}" '
            f'viewBox="0 0 {width} {y + 18}" font-family="sans-serif" font-size="11" '
            f'role="img" aria-label="{_e(title)}">'
            f'<text x="0" y="13" font-size="13" font-weight="bold">{_e(title)}</text>'
            f'{legend}{axis}{"".join(parts)}</svg>')


def _bar(y: float, method: str, value: float, top: float, colour: str) -> str:
    """One bar of ``value`` (NaN: none) at height ``y``, with its value at its end."""
    if math.isnan(value):
        return (f'<text x="{_LABEL_W + 4}" y="{y + _BAR_H - 3}" fill="#777">'
                f'{_e(method)}: n/a</text>')
    length = max(0.0, min(1.0, value / top)) * _BAR_AREA_W
    return (f'<rect x="{_LABEL_W}" y="{y + 1}" width="{length:.1f}" height="{_BAR_H - 2}" '
            f'fill="{colour}"><title>{_e(method)}: {value:.4g}</title></rect>'
            f'<text x="{_LABEL_W + length + 4:.1f}" y="{y + _BAR_H - 3}">{value:.3g}</text>')


def _axis(top: float, y0: float, y1: float) -> str:
    """Vertical grid lines at quarters of ``top``, labelled below the bars."""
    lines = []
    for k in range(5):
        x = _LABEL_W + _BAR_AREA_W * k / 4
        lines.append(f'<line x1="{x:.1f}" y1="{y0 - 4}" x2="{x:.1f}" y2="{y1}" '
                     f'stroke="#ddd"/><text x="{x:.1f}" y="{y1 + 12}" text-anchor="middle" '
                     f'fill="#555">{top * k / 4:.3g}</text>')
    return "".join(lines)


def _legend(methods: Sequence[str], colour: dict) -> str:
    items, x = [], _LABEL_W
    for method in methods:
        items.append(f'<rect x="{x}" y="{_TOP - 2}" width="10" height="10" '
                     f'fill="{colour[method]}"/><text x="{x + 14}" y="{_TOP + 7}">'
                     f'{_e(method)}</text>')
        x += 24 + 7 * len(method)
    return "".join(items)


def _f(row: ComparisonRow) -> float:
    return row.metrics.f_measure if row.metrics is not None else math.nan


def _charts(report: ComparisonReport) -> List[str]:
    """The F-measure charts (per method; per sequence and family for a dataset), or the
    frames per second per method when nothing was scored."""
    methods = report.methods
    if not report.has_metrics:
        return [bar_chart_svg("frames per second (inside engine.apply)",
                              _grouped(report.rows, value=lambda r: r.fps), methods)]
    charts = []
    if report.overall:
        charts.append(bar_chart_svg("F-measure per method (mean of the families)",
                                    [("overall", [(r.method, _f(r)) for r in report.overall])],
                                    methods, top=1.0))
    per_sequence = _grouped(report.rows)
    if not report.overall:
        charts.append(bar_chart_svg("F-measure per method", per_sequence, methods, top=1.0))
    else:
        charts.append(bar_chart_svg("F-measure per sequence", per_sequence, methods, top=1.0))
        charts.append(bar_chart_svg("F-measure per family (mean of its sequences)",
                                    _grouped(report.families), methods, top=1.0))
    return charts


def _grouped(rows: Sequence[ComparisonRow], *,
             value: Callable[[ComparisonRow], float] = _f
             ) -> List[Tuple[str, List[Tuple[str, float]]]]:
    """Rows grouped by name, in order of first appearance: ``[(name, [(method, value)])]``
    (value: the F-measure by default)."""
    groups: dict = {}
    for row in rows:
        groups.setdefault(row.name, []).append((row.method, value(row)))
    return list(groups.items())


def _table(report: ComparisonReport) -> str:
    """The metrics table: a row per sequence and method, then family and overall means."""
    titles = ["sequence", "family", "method", "frames", "fps", "scored", *METRIC_TITLES]
    head = "".join(f"<th>{_e(t)}</th>" for t in titles)
    body = []
    for row in report.all_rows():
        label = f"[{row.name}]" if row.level == "family" else row.name
        cells = [f'<td class="text">{_e(label)}</td>', f'<td class="text">{_e(row.family)}</td>',
                 f'<td class="text">{_e(row.method)}</td>', f"<td>{row.frames}</td>",
                 f"<td>{_number(row.fps, 1)}</td>", f"<td>{row.eval_frames}</td>"]
        for name in METRIC_NAMES:
            value = getattr(row.metrics, name) if row.metrics is not None else None
            cells.append(f"<td>{_number(value, 3 if name == 'pwc' else 4)}</td>")
        ours = " ours" if row.method == OURS else ""
        body.append(f'<tr class="{_e(row.level)}{ours}">{"".join(cells)}</tr>')
    return (f'<table class="metrics"><thead><tr>{head}</tr></thead>'
            f'<tbody>{"".join(body)}</tbody></table>')


def data_uri(picture: Picture) -> str:
    """``data:<mime>;base64,...`` for an ``<img src>``."""
    return f"data:{picture.mime};base64,{base64.b64encode(picture.data).decode('ascii')}"


def _video(path: str, codec: Optional[str]) -> str:
    """The side-by-side video: played in the page when H.264 (browsers play it), else a link
    (MPEG-4 part 2 plays in desktop players, not in browsers). A relative address: the page
    plays it from the report folder, never from the network."""
    src = _e(quote(path))
    if codec == "h264":
        return (f'<video controls muted preload="metadata" src="{src}"></video>'
                f'<div class="note">{_e(path)} (H.264)</div>')
    return (f'<p class="note">side by side: <a href="{src}">{_e(path)}</a> (MPEG-4 part 2: '
            "open it in a desktop video player)</p>")


def _frames(shown: SequenceFrames, codec: Optional[str] = None) -> str:
    """One input's frames: a line of labelled pictures per frame, and its side-by-side video
    (in ``codec``) when there is one."""
    title = shown.name + (f" ({shown.family})" if shown.family else "")
    lines = [f"<h3>{_e(title)}</h3>"]
    if shown.video:
        lines.append(_video(shown.video, codec))
    if not shown.frames:
        lines.append('<p class="note">no frame to show</p>')
    for tiles in shown.frames:
        figures = "".join(
            f'<figure><img src="{data_uri(picture)}" alt="{_e(label)}, frame {tiles.number}">'
            f"<figcaption>{_e(label)}</figcaption></figure>" for label, picture in tiles.pictures)
        lines.append(f'<div class="frame"><div class="note">frame {tiles.number}</div>'
                     f"{figures}</div>")
    return "\n".join(lines)


#: What the figures mean, in one sentence at the top of the page.
METRICS_SENTENCE = (
    "Precision is the share of the pixels a method calls foreground that are foreground in the "
    "ground truth, recall the share of the true foreground it finds, and F their harmonic mean "
    "(2PR / (P + R)): 1 is perfect, 0 finds nothing right.")

def _answer(report: ComparisonReport) -> str:
    """The methods ranked by F, the best marked and ours highlighted, with what F means."""
    ranked = report.ranking()
    if not ranked:
        return ""
    head = "".join(f"<th>{t}</th>" for t in ("", "method", "F", "precision", "recall", "fps"))
    body = []
    for place, row in enumerate(ranked, 1):
        classes = " ".join(c for c, on in (("best", place == 1), ("ours", row.method == OURS))
                           if on)
        mark = ' <span class="mark">best</span>' if place == 1 else ""
        metrics = row.metrics
        cells = [f"<td>{place}</td>", f'<td class="text">{_e(row.method)}{mark}</td>',
                 f"<td>{_number(_f(row), 3)}</td>",
                 f"<td>{_number(metrics.precision if metrics else None, 3)}</td>",
                 f"<td>{_number(metrics.recall if metrics else None, 3)}</td>",
                 f"<td>{_number(row.fps, 1)}</td>"]
        body.append(f'<tr class="{classes}">{"".join(cells)}</tr>')
    return (f'<table class="answer"><thead><tr>{head}</tr></thead><tbody>{"".join(body)}'
            f'</tbody></table><p class="note">{_e(METRICS_SENTENCE)}</p>')


def settings_table(settings: dict) -> str:
    """The run's settings as a two-column table (engine parameters as ``key=value``)."""
    rows = "".join(f'<tr><td class="text">{_e(k.replace("_", " "))}</td>'
                   f'<td class="text">{_e(setting_text(v))}</td></tr>'
                   for k, v in settings.items())
    return f'<table class="settings"><tbody>{rows}</tbody></table>'


def render_html(report: ComparisonReport) -> str:
    """The whole page, as text: the answer (methods ranked by F) first, then the charts, the
    figures, the settings and the frames."""
    warnings = "".join(f'<p class="warn">{_e(w)}</p>' for w in report.warnings)
    notes = []
    for row in report.rows[::max(1, len(report.methods))]:
        notes += [f"<li>{_e(row.name)}: {_e(n)}</li>" for n in row.notes]
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>bgsub compare: {_e(report.input)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>bgsub compare: {_e(report.input)}</h1>",
        f'<p>methods: {_e(", ".join(report.methods))}</p>', warnings,
        _answer(report), "<h2>Charts</h2>", *(f"<div>{svg}</div>" for svg in _charts(report)),
        "<h2>Figures</h2>", _table(report),
        f'<ul class="note">{"".join(notes)}</ul>' if notes else "",
        f'<p class="note">{_e(TIMING_NOTE)}</p>',
        "<h2>Settings</h2>", settings_table(report.settings),
        "<h2>Frames</h2>",
        *(_frames(shown, report.settings.get("video_codec")) for shown in report.frames),
        "</body></html>",
    ]
    return "\n".join(part for part in parts if part) + "\n"


def write_html_report(report: ComparisonReport, path: PathLike) -> Path:
    """Write :func:`render_html` of ``report`` to ``path``; :class:`OutputError` when it
    cannot be written."""
    path = Path(path)
    try:
        path.write_text(render_html(report), encoding="utf-8")
    except OSError as err:
        raise OutputError(f"cannot write {path}: {err.strerror}") from None
    return path
