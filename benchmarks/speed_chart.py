"""The speed/accuracy chart of docs/BENCHMARKS.md, ``docs/speed_accuracy.png``: each preset of
``grbm`` beside MOG2, KNN and ``compensated``, drawn with OpenCV from the benchmarks' JSON files.

x: frames per second as a multiple of MOG2's, timed in the same run (log scale), from
``bgsub bench --presets --json`` (each preset alternating with MOG2) and ``bgsub bench --json``
(the other methods; MOG2 must be among them); several runs give the median ratio. y: development
F (mean of the families) from ``benchmarks/accuracy.py --json`` files of one set (``--set real``
by default). Re-run it with new files to redraw the chart::

    OMP_NUM_THREADS=1 bgsub bench --presets --size 640x480 --json > presets.json
    OMP_NUM_THREADS=1 bgsub bench -m mog2,knn,compensated --size 640x480 --json > methods.json
    OMP_NUM_THREADS=1 python benchmarks/accuracy.py --set real --preset fast --json real_fast.json
    ...                                      # balanced, accurate; -m mog2, knn, compensated
    python benchmarks/speed_chart.py --timing presets.json methods.json --accuracy real_*.json

A file of ``accuracy.py`` names its point by its ``--method`` and ``--preset``; ``KEY=FILE``
names it instead (``grbm:fast=real_fast.json`` for a file made with the preset's ``-p`` values).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "mog2"
DEFAULT_PRESET = "balanced"

#: The canvas and the plot area inside it, in pixels.
WIDTH, HEIGHT = 960, 600
LEFT, RIGHT, TOP, BOTTOM = 90, 40, 60, 110
#: BGR colours: the presets' engine in blues, every other method its own colour.
PRESET_COLOURS = {"fast": (235, 170, 90), "balanced": (200, 110, 20), "accurate": (120, 50, 10)}
METHOD_COLOURS = {"mog2": (170, 70, 170), "knn": (40, 120, 240), "compensated": (60, 170, 60)}
OTHER_COLOURS = [(40, 40, 200), (120, 120, 120), (20, 160, 200)]
INK, GRID, WHITE = (30, 30, 30), (225, 225, 225), (255, 255, 255)
FONT = cv2.FONT_HERSHEY_SIMPLEX


@dataclass
class Point:
    """One method (and preset) on the chart: its speed as a multiple of MOG2's and its F."""

    key: Tuple[str, Optional[str]]  # (method, preset); preset None = the method's defaults
    ratio: float
    f: float

    @property
    def label(self) -> str:
        method, preset = self.key
        return f"{method} {preset}" if preset else method


class ChartError(Exception):
    """A file the chart cannot use; the message names it."""


# --------------------------------------------------------------------------------------------
# reading the benchmarks' files


def _key(method: str, preset: Optional[str], preset_method: Optional[str] = None
         ) -> Tuple[str, Optional[str]]:
    """A point's key. The preset of the engine timed by ``bench --presets`` is always named
    (its defaults are ``balanced``); any other method's default preset is left unnamed."""
    if method == preset_method:
        return method, preset or DEFAULT_PRESET
    return method, None if preset in (None, DEFAULT_PRESET) else preset


def _load(path: Path) -> dict:
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise ChartError(f"{path}: cannot read it as JSON ({err})") from None


def _clip(report: dict) -> dict:
    """The part of a bench report that holds the frame size and the machine."""
    return report["clip"] if isinstance(report.get("clip"), dict) else report


def read_timing(paths: Iterable[Path]) -> Tuple[Dict[tuple, float], str, List[dict]]:
    """``({key: fps / MOG2's fps}, the presets' engine, [the files' JSON])`` from files of
    ``bgsub bench --presets --json`` and ``bgsub bench --json``; a point timed in several files
    (repeated runs on a busy host) gets the median of its ratios."""
    reports = [(path, _load(path)) for path in paths]
    sizes = {(_clip(r).get("width"), _clip(r).get("height")) for _, r in reports}
    if len(sizes) > 1:
        raise ChartError(f"the timing files are of different frame sizes: {sorted(sizes)}")
    preset_method = next((r["method"] for _, r in reports if "method" in r), "grbm")
    ratios: Dict[tuple, List[float]] = {}
    for path, report in reports:
        try:
            found = _ratios(report, preset_method)
        except (KeyError, TypeError, ValueError, ZeroDivisionError) as err:
            raise ChartError(f"{path}: not a `bgsub bench --json` file ({err!r})") from None
        for key, ratio in found.items():
            ratios.setdefault(key, []).append(ratio)
    medians = {key: float(statistics.median(runs)) for key, runs in ratios.items()}
    return medians, preset_method, [r for _, r in reports]


def _ratios(report: dict, preset_method: str) -> Dict[tuple, float]:
    """One report's ratios to MOG2: per preset from ``bench --presets``, per method from
    ``bench`` (which must have timed MOG2)."""
    if "method" in report:  # bench --presets: each preset beside MOG2 in the same rounds
        found = {_key(report["method"], r["preset"], preset_method):
                 float(r["fps"]) / float(r["baseline_fps"]) for r in report["results"]}
        found[_key(BASELINE, None)] = 1.0
        return found
    fps = {r["method"]: float(r["fps"]) for r in report["results"]}
    if BASELINE not in fps:
        raise KeyError(f"{BASELINE} was not timed, so nothing can be a multiple of it")
    return {_key(m, None, preset_method): v / fps[BASELINE] for m, v in fps.items()}


def read_accuracy(specs: Iterable[str], which: str, preset_method: str
                  ) -> Dict[tuple, float]:
    """``{key: mean F}`` from ``[KEY=]FILE`` arguments naming ``benchmarks/accuracy.py --json``
    files; files of another set or of one half are refused (KEY: ``method`` or
    ``method:preset``)."""
    found: Dict[tuple, float] = {}
    for spec in specs:
        name, _, file = spec.partition("=")
        if not file or not re.fullmatch(r"[\w-]+(:[\w-]+)?", name):
            name, file = "", spec
        data = _load(Path(file))
        try:
            args, mean = data["args"], float(data["mean"])
            method, preset = args["method"], args.get("preset")
            if name:
                method, _, preset = name.partition(":")
            elif args.get("param"):
                print(f"speed_chart: {file} was run with -p {' -p '.join(args['param'])}; "
                      f"it is drawn as {method} {preset or ''}".rstrip(), file=sys.stderr)
            if args["set"] != which or args.get("half", "all") != "all":
                raise ChartError(f"{file}: set {args['set']}, half {args.get('half')}; the chart "
                                 f"shows --set {which} --half all")
        except (KeyError, TypeError, ValueError) as err:
            raise ChartError(f"{file}: not a benchmarks/accuracy.py --json file "
                             f"({err!r})") from None
        found[_key(method, preset or None, preset_method)] = mean
    return found


def join_points(ratios: Dict[tuple, float], scores: Dict[tuple, float]) -> List[Point]:
    """The points both timed and scored, slowest first; a point with only one of the two is
    named on stderr and left out."""
    for key in sorted(set(ratios) ^ set(scores), key=str):
        what = "no accuracy file" if key in ratios else "no timing"
        print(f"speed_chart: {Point(key, 0, 0).label} left out ({what})", file=sys.stderr)
    points = [Point(key, ratios[key], scores[key]) for key in ratios if key in scores]
    if not points:
        raise ChartError("no method is both timed and scored: nothing to draw")
    return sorted(points, key=lambda p: p.ratio)


def describe(reports: Sequence[dict], which: str) -> str:
    """The chart's footnote: frame size, machine and UTC dates of the timing."""
    machines = [_clip(r)["machine"] for r in reports]
    dates = sorted(m["date"][:16].replace("T", " ") for m in machines)
    when = dates[0] if dates[0] == dates[-1] else f"{dates[0]} to {dates[-1][-5:]}"
    loads = sorted(m["load_average"] for m in machines if m.get("load_average") is not None)
    low, high = (f"{loads[0]:.1f}", f"{loads[-1]:.1f}") if loads else ("", "")
    load = "" if not loads else f", load {low}" if low == high else f", load {low}-{high}"
    clip = _clip(reports[0])
    return (f"timing: bgsub bench, {clip['width']}x{clip['height']}, per-frame step, "
            f"{machines[0]['cpu']}, {when} UTC{load}; "
            f"F: benchmarks/accuracy.py --set {which}")


# --------------------------------------------------------------------------------------------
# drawing


def x_range(ratios: Sequence[float]) -> Tuple[float, float]:
    """The log axis's ends: 1-2-5 values around the ratios, with room for the labels."""
    steps = sorted(m * 10.0 ** e for e in range(-3, 4) for m in (1, 2, 5))
    low = max([s for s in steps if s <= min(ratios) / 1.25] or steps[:1])
    high = min([s for s in steps if s >= max(ratios) * 1.6] or steps[-1:])
    return low, high


def to_pixel(ratio: float, f: float, xr: Tuple[float, float]) -> Tuple[int, int]:
    """Where ``(ratio, f)`` falls on the canvas (x log-scaled over ``xr``, y from 0 to 1)."""
    span = math.log(xr[1]) - math.log(xr[0])
    x = LEFT + (math.log(ratio) - math.log(xr[0])) / span * (WIDTH - LEFT - RIGHT)
    y = HEIGHT - BOTTOM - f * (HEIGHT - TOP - BOTTOM)
    return int(round(x)), int(round(y))


def _text(img: np.ndarray, text: str, org: Tuple[int, int], scale: float = 0.5,
          colour: Tuple[int, int, int] = INK, thickness: int = 1) -> None:
    cv2.putText(img, text, org, FONT, scale, colour, thickness, cv2.LINE_AA)


def draw_axes(img: np.ndarray, xr: Tuple[float, float], x_title: str, y_title: str) -> None:
    """Grid, ticks and titles of both axes."""
    bottom, right = HEIGHT - BOTTOM, WIDTH - RIGHT
    for k in range(11):
        _, y = to_pixel(1.0, k / 10, xr)
        cv2.line(img, (LEFT, y), (right, y), GRID, 1)
        _text(img, f"{k / 10:.1f}", (LEFT - 38, y + 5), 0.45)
    ticks = [m * 10.0 ** e for e in range(-3, 4) for m in (1, 2, 5)]
    for tick in [t for t in ticks if xr[0] <= t <= xr[1]]:
        x, _ = to_pixel(tick, 0.0, xr)
        cv2.line(img, (x, TOP), (x, bottom), GRID, 1)
        label = f"{tick:g}x"
        (w, _), _ = cv2.getTextSize(label, FONT, 0.45, 1)
        _text(img, label, (x - w // 2, bottom + 20), 0.45)
    cv2.rectangle(img, (LEFT, TOP), (right, bottom), INK, 1)
    (w, _), _ = cv2.getTextSize(x_title, FONT, 0.5, 1)
    _text(img, x_title, ((LEFT + right - w) // 2, bottom + 45))
    (w, h), _ = cv2.getTextSize(y_title, FONT, 0.5, 1)
    strip = np.full((h + 10, w + 4, 3), 255, np.uint8)
    _text(strip, y_title, (2, h + 3))
    strip = cv2.rotate(strip, cv2.ROTATE_90_COUNTERCLOCKWISE)
    top = max(0, (TOP + bottom - strip.shape[0]) // 2)
    img[top:top + strip.shape[0], 12:12 + strip.shape[1]] = strip


def colours(points: Sequence[Point], preset_method: str) -> Dict[tuple, Tuple[int, int, int]]:
    """A colour per point: the presets their shades, MOG2, KNN and ``compensated`` theirs, any
    other method the next of :data:`OTHER_COLOURS`."""
    others = iter(OTHER_COLOURS * (1 + len(points) // len(OTHER_COLOURS)))

    def colour(method: str, preset: Optional[str]) -> Tuple[int, int, int]:
        if method == preset_method:
            return PRESET_COLOURS.get(preset, PRESET_COLOURS[DEFAULT_PRESET])
        if preset is None and method in METHOD_COLOURS:
            return METHOD_COLOURS[method]
        return next(others)

    return {p.key: colour(*p.key) for p in points}


def _free_spot(box: Tuple[int, int, int, int], taken: List[Tuple[int, int, int, int]]
               ) -> Tuple[int, int, int, int]:
    """``box`` (x, y, w, h), moved down then up a line at a time until it overlaps no box in
    ``taken`` and stays inside the plot."""
    x, y, w, h = box
    for shift in [0, *[s * d for s in range(1, 12) for d in (h + 4, -(h + 4))]]:
        top = y + shift
        inside = TOP < top and top + h < HEIGHT - BOTTOM
        if inside and not any(x < a + c and a < x + w and top < b + d and b < top + h
                              for a, b, c, d in taken):
            return x, top, w, h
    return box


def draw_points(img: np.ndarray, points: Sequence[Point], xr: Tuple[float, float],
                preset_method: str) -> None:
    """The presets joined by a line, every point a dot labelled with its name and figures."""
    colour = colours(points, preset_method)
    curve = [to_pixel(p.ratio, p.f, xr) for p in points if p.key[0] == preset_method]
    if len(curve) > 1:
        cv2.polylines(img, [np.array(curve, np.int32)], False, (200, 160, 120), 1, cv2.LINE_AA)
    taken: List[Tuple[int, int, int, int]] = []
    for p in points:
        x, y = to_pixel(p.ratio, p.f, xr)
        cv2.circle(img, (x, y), 7, colour[p.key], -1, cv2.LINE_AA)
        taken.append((x - 8, y - 8, 16, 16))
    for p in points:
        x, y = to_pixel(p.ratio, p.f, xr)
        text = f"{p.label}: {p.ratio:.2f}x, F {p.f:.3f}"
        (w, h), _ = cv2.getTextSize(text, FONT, 0.45, 1)
        left = x + 12 if x + 12 + w < WIDTH - RIGHT else x - 12 - w
        bx, by, bw, bh = _free_spot((left, y - h // 2 - 2, w, h + 4), taken)
        taken.append((bx, by, bw, bh))
        cv2.rectangle(img, (bx - 2, by), (bx + bw + 2, by + bh), WHITE, -1)  # over the grid
        _text(img, text, (bx, by + bh - 3), 0.45, colour[p.key])


def _draw_footnote(img: np.ndarray, footnote: str, scale: float = 0.42) -> None:
    """``footnote`` under the x axis, on two lines when one is wider than the canvas."""
    lines = [footnote]
    if cv2.getTextSize(footnote, FONT, scale, 1)[0][0] > WIDTH - LEFT - 10:
        head, _, tail = footnote.partition("; ")
        lines = [head + ";", tail]
    for k, line in enumerate(lines):
        _text(img, line, (LEFT, HEIGHT - 40 + 18 * k), scale)


def draw_chart(points: Sequence[Point], preset_method: str, footnote: str,
               which: str = "real") -> np.ndarray:
    """The whole chart as a BGR image of ``HEIGHT`` x ``WIDTH``."""
    img = np.full((HEIGHT, WIDTH, 3), 255, np.uint8)
    xr = x_range([p.ratio for p in points])
    draw_axes(img, xr, f"frames per second as a multiple of {BASELINE.upper()}'s in the same run"
                       " (log scale)", f"{which} development F (mean of the families)")
    draw_points(img, points, xr, preset_method)
    title = f"Speed and accuracy: the presets of {preset_method} beside other methods"
    _text(img, title, (LEFT, 35), 0.65, INK, 2)
    _draw_footnote(img, footnote)
    return img


# --------------------------------------------------------------------------------------------


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--timing", nargs="+", required=True, type=Path, metavar="FILE",
                        help="`bgsub bench --presets --json` and `bgsub bench --json` output")
    parser.add_argument("--accuracy", nargs="+", required=True, metavar="[KEY=]FILE",
                        help="`benchmarks/accuracy.py --json` files; KEY (method or "
                             "method:preset) names a file's point instead of its arguments")
    parser.add_argument("--set", default="real", help="the accuracy files' set (default: real)")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "speed_accuracy.png")
    args = parser.parse_args(argv)
    try:
        ratios, preset_method, reports = read_timing(args.timing)
        points = join_points(ratios, read_accuracy(args.accuracy, args.set, preset_method))
    except ChartError as err:
        print(f"speed_chart: {err}", file=sys.stderr)
        return 2
    img = draw_chart(points, preset_method, describe(reports, args.set), args.set)
    if not cv2.imwrite(str(args.output), img, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        print(f"speed_chart: cannot write {args.output}", file=sys.stderr)
        return 2
    for p in points:
        print(f"{p.label:<16} {p.ratio:6.2f}x MOG2   F {p.f:.3f}")
    print(f"wrote {args.output} ({args.output.stat().st_size // 1024} KB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
