"""Completion records: how a batch knows which outputs are complete, so a rerun skips them.

An output's file alone cannot say it is complete: the sinks give a partial output its final name
when a run is interrupted (it stays valid and playable). So each input of a batch has a small
JSON record, ``OUTDIR/.bgsub-batch/NAME.json``, written (atomically) by the job that makes the
input's outputs:

* ``"status": "running"`` before the first output is opened;
* ``"status": "complete"`` once every frame went through and every output was closed, with the
  frames written.

Both hold the *settings* the outputs were made with: the input (its resolved path, and for a
file its size and modification time, for a folder its modification time), the method, the
engine parameters given, the frame range and size, the ways of writing not left at their
defaults (``writing``: codec, min object area) and the output paths. A rerun of the batch
(:func:`decide`) then

* skips an input whose record is complete, made with the same settings, and whose outputs all
  exist;
* redoes an input whose record is ``running`` (a batch stopped while it ran: its outputs are
  partial) or complete but missing an output (one now asked for, or deleted);
* keeps, without ``--overwrite``, the outputs of an input whose complete record holds other
  settings (another method, parameter or way of writing, or an input changed since): the input is skipped with
  a reason that names what changed;
* refuses, without ``--overwrite``, an input whose outputs exist with no record at all (not made
  by a batch): replacing those would destroy results nothing can tell are stale.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple

from bgsub.io.sinks import write_atomically

#: What :func:`decide` tells the batch to do with an input (KEEP: skip it, its complete outputs
#: made with other settings kept).
RUN, SKIP, REDO, KEEP = "run", "skip", "redo", "keep"


def input_identity(path: str) -> Dict[str, Any]:
    """The input as a record holds it: resolved path, and size and modification time when it
    exists (a glob pattern: the pattern only)."""
    location = Path(path)
    identity: Dict[str, Any] = {"path": str(location.resolve()) if location.exists() else path}
    try:
        stat = location.stat()
    except OSError:
        return identity
    if location.is_file():
        identity["bytes"] = stat.st_size
    identity["modified_ns"] = stat.st_mtime_ns
    return identity


def _plain(value: Any) -> Any:
    """``value`` as it comes back from JSON (tuples as lists), so settings compare equal."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def settings(*, input_path: str, method: str, params: Mapping[str, Any],
             source: Mapping[str, Any]) -> Dict[str, Any]:
    """The settings a record holds and a rerun compares (outputs apart)."""
    return _plain({"input": input_identity(input_path), "method": method,
                   "params": dict(params), "source": dict(source)})


def read(path: str) -> Optional[Dict[str, Any]]:
    """The record at ``path``, or ``None`` when there is none or it cannot be read as one."""
    try:
        with open(path, encoding="utf-8") as fh:
            record = json.load(fh)
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def write(path: str, *, status: str, settings: Mapping[str, Any], outputs: Mapping[str, str],
          frames: int = 0) -> None:
    """Write the record of one input (replacing the previous one atomically)."""
    record = {"status": status, "settings": dict(settings), "outputs": dict(outputs),
              "frames": int(frames)}
    data = (json.dumps(record, indent=1, sort_keys=True) + "\n").encode("utf-8")
    write_atomically(Path(path), data, what="the batch record")


def _exists(path: str) -> bool:
    location = Path(path)
    if location.is_dir():
        return any(name.startswith("bin") and name.endswith(".png")
                   for name in os.listdir(location))
    return location.is_file()


def _changes(old: Any, new: Any, prefix: str = "") -> List[str]:
    """``["stride 8 -> 12", ...]``: the settings that differ between two records' settings
    (nested dictionaries flattened; the input's identity is one change)."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return [] if old == new else [f"{prefix} {_shown(old)} -> {_shown(new)}"]
    changes: List[str] = []
    for key in sorted(set(old) | set(new), key=str):
        if old.get(key) == new.get(key):
            continue
        if key == "input":
            changes.append("the input changed since")
        elif key in ("params", "source", "writing"):
            changes += _changes(old.get(key) or {}, new.get(key) or {})
        else:
            changes += _changes(old.get(key), new.get(key), f"{prefix}.{key}" if prefix else key)
    return changes


def _shown(value: Any) -> str:
    return "default" if value is None else str(value)


def decide(record_path: str, *, settings: Mapping[str, Any], outputs: Mapping[str, str],
           overwrite: bool) -> Tuple[str, Optional[str]]:
    """What to do with one input: ``(RUN | SKIP | REDO, None)``; ``(KEEP, reason)`` for complete
    outputs made with other settings (skipped; ``reason`` names the changes:
    ``"made with other settings (stride 8 -> 12): --overwrite redoes it"``); or
    ``(RUN, reason)`` when it must not run (outputs that are not this batch's to replace).

    ``REDO`` means the input's outputs are this batch's own and may be replaced.
    """
    record = read(record_path)
    existing = [path for path in outputs.values() if _exists(path)]
    if overwrite:
        return (REDO if existing or record else RUN), None
    if record is None:
        if existing:
            return RUN, (f"{existing[0]} already exists and no batch record says it is "
                         "complete (--overwrite replaces it)")
        return RUN, None
    if record.get("status") != "complete":
        return REDO, None
    if record.get("settings") != _plain(dict(settings)):
        changes = ", ".join(_changes(record.get("settings"), _plain(dict(settings))))
        return KEEP, (f"made with other settings{f' ({changes})' if changes else ''}: "
                      "--overwrite redoes it")
    recorded = record.get("outputs") or {}
    if all(recorded.get(kind) == path and _exists(path) for kind, path in outputs.items()):
        return SKIP, None
    return REDO, None
