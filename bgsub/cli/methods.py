"""``bgsub methods``: the registered engines, their parameters, defaults and meaning."""

from __future__ import annotations

import argparse
import json
import textwrap
from typing import Any, Dict, List, Optional

from bgsub.engines import EngineSpec, available_engines, default_method, get_engine_spec

_DESCRIPTION = """\
List the background-subtraction engines (the values of `bgsub run --method`), which one is the
default, and every parameter each takes (set with `--param KEY=VALUE`), with its default and
meaning. Engines marked "static camera only" are the classical baselines."""

_EPILOG = """\
examples:
  bgsub methods                       all engines and their parameters
  bgsub methods mog2                  one engine
  bgsub methods --json                machine-readable
  bgsub run clip.mp4 -o masks.mkv --method mog2 --param var_threshold=25
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
    parser.add_argument("--json", action="store_true", help="print the list as JSON")
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
                **({"choices": list(p.choices)} if p.choices is not None else {}),
                **{bound: getattr(p, bound) for bound in ("low", "high", "above")
                   if getattr(p, bound) is not None},
            }
            for key, p in spec.params.items()
        },
    }


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


def format_text(entries: List[Dict[str, Any]]) -> str:
    """Human-readable listing of :func:`describe` entries."""
    lines: List[str] = []
    for entry in entries:
        mark = " (default)" if entry["default"] else ""
        lines.append(f"{entry['name']}{mark}: {entry['description']}")
        params = entry["params"]
        if not params:
            lines.append("    (no parameters)")
        keys = [f"{k}={_format_value(p['default'])}" for k, p in params.items()]
        width = max((len(k) for k in keys), default=0)
        for key, (name, p) in zip(keys, params.items()):
            help_text = p["help"]
            if "choices" in p:
                help_text += " (one of: " + ", ".join(map(_format_value, p["choices"])) + ")"
            bounds = _bounds_text(p)
            if bounds:
                help_text += f" ({bounds})"
            wrapped = textwrap.wrap(help_text, width=max(40, 96 - width - 6)) or [""]
            lines.append(f"    {key:<{width}}  {wrapped[0]}")
            lines.extend(f"    {'':<{width}}  {more}" for more in wrapped[1:])
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


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
        print(format_text(entries), end="")
    return 0
