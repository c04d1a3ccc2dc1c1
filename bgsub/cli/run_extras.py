"""Options of ``bgsub run`` beyond masks and pictures: ``--config`` (engine parameters from a
TOML file), ``--json`` (the run's summary for scripts) and ``--objects`` (tracked objects)."""

from __future__ import annotations

import argparse
import json
import math
from typing import Any, Dict, Optional

from bgsub.cli.param_file import read_params
from bgsub.errors import InputError
from bgsub.io.loop import RunStats
from bgsub.objects import TrackerConfig


def add_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--config", metavar="FILE.toml", default=None,
                        help="engine parameters from a TOML file (`name = value`, the names "
                             "--param takes); --param overrides it")
    parser.add_argument("--json", action="store_true",
                        help="print the run's summary as one JSON object on stdout: frames, "
                             "seconds, fps, complete, statuses, outputs (a batch: its summary, "
                             "as --summary writes it)")
    parser.add_argument("--objects", metavar="FILE", default=None,
                        help="also write the objects of every frame, tracked across frames: "
                             ".jsonl (one JSON line per frame) or .csv (MOTChallenge); "
                             "--vis then draws their boxes and ids")
    parser.add_argument("--min-object-area", type=int, default=None, metavar="PX",
                        help=f"leave out objects of fewer pixels (default: "
                             f"{TrackerConfig.min_area}; with --objects)")


def engine_params(args: argparse.Namespace, method: str) -> Dict[str, Any]:
    """The engine's parameters: the --config file's, then --param's over them."""
    from bgsub.cli.compare import parse_method_params  # (METHOD.KEY=VALUE too, as compare)

    given = parse_method_params(args.param, [method]).get(method, {})
    return {**read_params(args.config, method), **given} if args.config else given


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
