"""``bgsub methods``: the registered engines, their parameters, defaults and meaning."""

from __future__ import annotations

import argparse
import json
import textwrap
from typing import Any, Dict, List, Optional

from bgsub.engines import EngineSpec, available_engines, default_method, get_engine_spec

_DESCRIPTION = """\
List the background-subtraction engines (the values of `bgsub run --method`), which one is the
default, and the parameters each takes (set with `--param KEY=VALUE`), with default and meaning:
the few most users tune, or with --all every one, grouped by stage; and the named presets
(`--preset NAME`) of those that have them. Engines marked "static camera only" are the classical
baselines."""

_EPILOG = """\
examples:
  bgsub methods                       every engine and its common parameters
  bgsub methods grbm --all            every parameter of grbm, grouped by stage
  bgsub methods mog2 --json           machine-readable, every parameter
  bgsub run samples/pan.mp4 -o mog2_masks.mkv --method mog2 --param var_threshold=25
"""


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "methods",
        help="list the engines and their parameters",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("name", nargs="?", default=None, metavar="METHOD",
                        help="show only this engine")
    parser.add_argument("--all", action="store_true",
                        help="every parameter, grouped by stage (default: the common ones)")
    parser.add_argument("--json", action="store_true",
                        help="print the list as JSON (every parameter, each marked common or not)")
    parser.set_defaults(handler=run)


def describe(spec: EngineSpec, *, is_default: bool) -> Dict[str, Any]:
    """One engine as plain data: name, description, default flag, parameters."""
    return {
        "name": spec.name,
        "description": spec.description,
        "default": is_default,
        "params": {
            key: {
                "default": p.default,
                "type": type(p.default).__name__,
                "help": p.help,
                "common": spec.is_common(key),
                "stage": stage,
                **({"choices": list(p.choices)} if p.choices is not None else {}),
                **{bound: getattr(p, bound) for bound in ("low", "high", "above")
                   if getattr(p, bound) is not None},
            }
            for (key, p), stage in zip(spec.params.items(), stage_names(spec))
        },
        "presets": {name: dict(values) for name, values in spec.presets.items()},
    }


# The titles of the moving-camera engine's stages (bgsub.engines.config.STAGES), by class name.
_STAGE_TITLES = {"EngineConfig": "engine (frame size, mask edges, threads, blank frames)",
                 "CameraConfig": "camera motion (RANSAC fit)",
                 "BackgroundConfig": "background model",
                 "ForegroundConfig": "foreground policies (exposure, scene cuts, still camera)",
                 "FusionConfig": "foreground decision",
                 "OverlayConfig": "frame-fixed overlays (logo, watermark, timestamp)"}


def stage_names(spec: EngineSpec) -> List[str]:
    """The stage of each of ``spec``'s parameters, in order: for a moving-camera engine (one
    that takes every stage setting) its front end's, each stage's title, or "inputs" for those
    after the stages; for any other engine "" throughout."""
    import dataclasses

    from bgsub.engines.config import STAGES

    stage_of = {f.name: _STAGE_TITLES.get(stage.__name__, stage.__name__)
                for stage in STAGES for f in dataclasses.fields(stage)}
    if not set(stage_of) <= set(spec.params):
        return [""] * len(spec.params)
    names, seen_stage = [], False
    for key in spec.params:
        seen_stage = seen_stage or key in stage_of
        names.append(stage_of.get(key) or ("inputs" if seen_stage else
                                           f"motion front end ({spec.name})"))
    return names


def _format_value(value: Any) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _bounds_text(p: Dict[str, Any]) -> str:
    """A parameter's range as text: ">=1", "0-1", ">0" (no spaces, so it never wraps; empty
    when unbounded)."""
    low, high, above = p.get("low"), p.get("high"), p.get("above")
    if low is not None and high is not None:
        return f"{low:g}-{high:g}"
    parts = [f">={low:g}"] if low is not None else []
    parts += [f">{above:g}"] if above is not None else []
    parts += [f"<={high:g}"] if high is not None else []
    return ",".join(parts)


def _param_lines(params: Dict[str, Dict[str, Any]]) -> List[str]:
    """Each parameter as ``key=default  meaning (range)``, the meaning wrapped beside it."""
    lines: List[str] = []
    keys = [f"{k}={_format_value(p['default'])}" for k, p in params.items()]
    width = max((len(k) for k in keys), default=0)
    for key, p in zip(keys, params.values()):
        help_text = p["help"]
        if "choices" in p:
            help_text += " (one of: " + ", ".join(map(_format_value, p["choices"])) + ")"
        bounds = _bounds_text(p)
        if bounds:
            help_text += f" ({bounds})"
        wrapped = textwrap.wrap(help_text, width=max(40, 96 - width - 6)) or [""]
        lines.append(f"    {key:<{width}}  {wrapped[0]}")
        lines.extend(f"    {'':<{width}}  {more}" for more in wrapped[1:])
    return lines


def format_text(entries: List[Dict[str, Any]], *, every: bool = False) -> str:
    """Human-readable listing of :func:`describe` entries: the common parameters of each, or
    with ``every`` all of them under their stage's title."""
    lines: List[str] = []
    for entry in entries:
        mark = " (default)" if entry["default"] else ""
        lines.append(f"{entry['name']}{mark}: {entry['description']}")
        params = entry["params"]
        if not params:
            lines.append("    (no parameters)")
        if not every:
            shown = {k: p for k, p in params.items() if p["common"]}
            lines.extend(_param_lines(shown))
            if len(shown) < len(params):
                lines.append(f"    (the common {len(shown)} of {len(params)} parameters: "
                             f"`bgsub methods {entry['name']} --all` shows all of them)")
        else:
            for stage in dict.fromkeys(p["stage"] for p in params.values()):
                if stage:
                    lines.append(f"  {stage}:")
                lines.extend(_param_lines({k: p for k, p in params.items()
                                           if p["stage"] == stage}))
        lines.extend(_preset_lines(entry["presets"]))
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def _preset_lines(presets: Dict[str, Dict[str, Any]]) -> List[str]:
    """The presets (``--preset NAME``), each with the values it sets; none for an engine
    without presets."""
    if not presets:
        return []
    width = max(len(name) for name in presets)
    return ["  presets (--preset NAME; -p overrides their values):"] + [
        f"    {name:<{width}}  " + (", ".join(f"{k}={_format_value(v)}" for k, v in values.items())
                                   or "the defaults")
        for name, values in presets.items()]


def run(args: argparse.Namespace) -> int:
    default: Optional[str]
    try:
        default = default_method()
    except StopIteration:  # no engine registered at all
        default = None
    # `is not None`: an empty name (say, an unset shell variable) is an unknown method, not "all".
    specs = [get_engine_spec(args.name)] if args.name is not None else available_engines()
    specs.sort(key=lambda spec: spec.name != default)  # the default first; stable otherwise
    entries = [describe(s, is_default=s.name == default) for s in specs]
    if args.json:
        print(json.dumps(entries, indent=2))
    else:
        print(format_text(entries, every=args.all), end="")
    return 0
