"""``bgsub bench --presets``: the speed of each preset of an engine beside MOG2's, timed in one
process with the two alternating (so a busy host slows both alike), and the development F of
each preset as ``benchmarks/accuracy.py --json`` recorded it."""

from __future__ import annotations

import json
import statistics
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional

from bgsub.engines import get_engine_spec
from bgsub.engines.base import BALANCED
from bgsub.errors import InputError
from bgsub.evaluation.bench import BenchReport, _count, time_engine, machine_info, make_clip

#: The engine every preset is timed against.
BASELINE = "mog2"
#: The sets of ``benchmarks/accuracy.py --set`` shown as columns.
ACCURACY_SETS = ("real", "generated")


@dataclass(frozen=True)
class PresetResult:
    """One preset: its median fps, MOG2's median fps over the same rounds, and its development
    F by set (``{"real": F, "generated": F}``, those recorded)."""

    preset: str
    values: Dict[str, Any]
    fps: float
    baseline_fps: float
    accuracy: Dict[str, float] = field(default_factory=dict)

    @property
    def ratio(self) -> float:
        """fps as a multiple of MOG2's."""
        return self.fps / max(self.baseline_fps, 1e-9)


@dataclass
class PresetReport:
    """All of :func:`bench_presets`'s figures and the machine they were measured on."""

    method: str
    clip: BenchReport
    results: List[PresetResult] = field(default_factory=list)

    def to_dict(self) -> Dict[str, Any]:
        """A JSON-serialisable view of the report."""
        return {"method": self.method, "clip": asdict(self.clip),
                "results": [{**asdict(r), "x_mog2": r.ratio} for r in self.results]}

    def to_text(self) -> str:
        """One table: a row per preset."""
        c = self.clip
        header = f"{'preset':<10}{'fps':>8}{'x MOG2':>8}{'real F':>8}{'gen. F':>8}  values"
        lines = [f"bgsub bench --presets: {self.method}, {_count(c.frames, 'frame')} of "
                 f"{c.width}x{c.height}, {_count(c.repeats, 'round')} alternating with "
                 f"{BASELINE}; clip: {c.clip}",
                 c.note, "", header, "-" * len(header)]
        for r in self.results:
            scores = "".join(f"{r.accuracy[s]:>8.3f}" if s in r.accuracy else f"{'-':>8}"
                             for s in ACCURACY_SETS)
            values = ", ".join(f"{k}={v}" for k, v in r.values.items()) or "(the defaults)"
            lines.append(f"{r.preset:<10}{r.fps:>8.1f}{r.ratio:>8.2f}{scores}  {values}")
        lines += ["", c.machine.to_text()]
        return "\n".join(lines)


def read_accuracy(paths: Iterable[Any]) -> Dict[str, Dict[str, float]]:
    """``{preset: {set: mean F}}`` from files ``benchmarks/accuracy.py --json`` wrote (its
    ``args`` say the set and preset, none = balanced); :class:`InputError` for a file that is
    not one."""
    found: Dict[str, Dict[str, float]] = {}
    for path in paths:
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
            args, mean = data["args"], float(data["mean"])
            which = str(args["set"])
        except (OSError, ValueError, TypeError, KeyError) as err:
            raise InputError(f"{path}: not a benchmarks/accuracy.py --json file ({err})") from None
        found.setdefault(args.get("preset") or BALANCED, {})[which] = mean
    return found


def bench_presets(*, method: str = "grbm", width: int = 320, height: int = 240,
                  frames: int = 50, repeats: int = 3,
                  params: Optional[Mapping[str, Any]] = None, seed: int = 0,
                  accuracy: Optional[Mapping[str, Mapping[str, float]]] = None) -> PresetReport:
    """Time every preset of ``method`` and MOG2 on one generated clip (``frames`` timed frames
    of ``width`` x ``height``), ``repeats`` rounds, each round every preset then MOG2 on fresh
    engines; ``params`` override every preset's values; ``accuracy``: :func:`read_accuracy`'s."""
    spec = get_engine_spec(method)
    if not spec.presets:
        spec.preset_values(BALANCED)  # refused: one line naming the engines that have presets
    if frames < 1 or repeats < 1:
        raise InputError("bench: --max-frames and --repeats must be at least 1")
    chosen = {name: {**spec.preset_values(name), **(params or {})} for name in spec.presets}
    for values in chosen.values():  # bad parameters fail before any timing
        getattr(spec.create(**values), "close", lambda: None)()
    clip, description = make_clip(width=width, height=height, n_frames=frames + 1, seed=seed)
    runs: Dict[str, List[float]] = {name: [] for name in [*chosen, BASELINE]}
    for _ in range(repeats):
        for name, values in [*chosen.items(), (BASELINE, {})]:
            engine_name = BASELINE if name == BASELINE else method
            runs[name].append(frames / max(time_engine(engine_name, values, clip), 1e-9))
    base = float(statistics.median(runs[BASELINE]))
    report = PresetReport(method, BenchReport(width=width, height=height, frames=frames,
                                              repeats=repeats, clip=description,
                                              machine=machine_info()))
    for name in chosen:
        report.results.append(PresetResult(name, dict(spec.presets[name]),
                                           float(statistics.median(runs[name])), base,
                                           dict((accuracy or {}).get(name, {}))))
    return report
