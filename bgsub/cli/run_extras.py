"""Options of ``bgsub run`` beyond masks and pictures: ``--config`` (engine parameters from a
TOML file), ``--json`` (the run's summary for scripts) and ``--objects`` (tracked objects)."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any, Dict, Optional, Tuple

from bgsub.cli.param_file import read_config
from bgsub.errors import InputError
from bgsub.io.loop import RunStats
from bgsub.objects import TrackerConfig


def add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", metavar="FILE.toml", default=None,
                        help="parameters and preset from a TOML file; -p overrides")
    parser.add_argument("--json", action="store_true",
                        help="print the run's (or batch's) summary as JSON on stdout")
    parser.add_argument("--objects", metavar="FILE", default=None,
                        help="also the tracked objects: .jsonl or .csv (MOT)")
    parser.add_argument("--min-object-area", type=int, default=None, metavar="PX",
                        help=f"smallest object in pixels (default: {TrackerConfig.min_area})")


def engine_settings(args: argparse.Namespace, method: str) -> Tuple[Optional[str], Dict[str, Any]]:
    """``(preset, params)`` of the engine: the preset --preset names, else the --config file's;
    the file's parameters, then --param's over them."""
    from bgsub.cli.compare import parse_method_params  # (METHOD.KEY=VALUE too, as compare)

    given = parse_method_params(args.param, [method]).get(method, {})
    if not args.config:
        return args.preset, given
    preset, params = read_config(args.config, method)
    return args.preset or preset, {**params, **given}


def tracker_config(args: argparse.Namespace) -> TrackerConfig:
    """The tracker's settings from --min-object-area; refused without --objects."""
    if args.min_object_area is None:
        return TrackerConfig()
    if not args.objects:
        raise InputError("--min-object-area needs --objects FILE")
    try:
        return TrackerConfig(min_area=args.min_object_area)
    except ValueError as err:
        raise InputError(f"--min-object-area: {err}") from None


def print_summary(stats: RunStats, *, method: str, outputs: Dict[str, str],
                  codecs: Optional[Dict[str, str]] = None) -> None:
    """The run's summary as one JSON object on stdout. ``statuses`` counts frames per status
    (``ok`` included) for engines that report one, and is empty for the others;
    ``video_codecs`` names the codec of each picture video (``{"vis": "h264"}``)."""
    statuses: Dict[str, int] = {}
    if stats.has_status:
        statuses = {"ok": stats.frames * len(stats.engines) - stats.not_ok,
                    **dict(stats.statuses)}
    fps = stats.fps if math.isfinite(stats.fps) else None
    print(json.dumps({"method": method, "frames": stats.frames,
                      "seconds": round(stats.seconds, 3), "fps": fps and round(fps, 2),
                      "complete": stats.complete, "statuses": statuses,
                      "outputs": outputs, "video_codecs": dict(codecs or {})}), flush=True)
