"""Engine parameters from a TOML file (``bgsub run --config FILE.toml``).

The file holds ``name = value`` pairs, the names that ``--param`` takes (``bgsub methods
METHOD`` lists them), with TOML's types (``history = 200``, ``shadows = false``, ``model =
"natural"``); a string is read as ``--param`` reads its text. ``preset = "fast"`` names the
preset the other values adjust, as ``--preset`` does. Each error is one line naming the file and
the key.
"""

from __future__ import annotations

import datetime
import sys
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

from bgsub.engines import get_engine_spec
from bgsub.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser, from the package index (a declared dependency on Python < 3.11)
    import tomli as tomllib


def _load(path: Path) -> Dict[str, Any]:
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder; give a .toml file") from None
    except OSError as err:
        raise InputError(f"{path}: cannot read it ({err.strerror or err})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: not valid TOML: {err}") from None


def _value(param: Any, name: str, value: Any) -> Any:
    """``value`` from the file checked (and, for text, parsed) as ``param`` wants it."""
    if isinstance(value, (dict, list, datetime.date, datetime.time)):
        kind = {dict: "a table", list: "an array"}.get(type(value), "a date or time")
        raise InputError(f"takes one number, true/false or string, not {kind}")
    if isinstance(value, str):
        return param.parse(name, value)
    if isinstance(param.default, float) and isinstance(value, int) \
            and not isinstance(value, bool):
        value = float(value)  # `rate = 1` for a float parameter
    param.check(name, value)
    return value


def read_config(path: Any, method: str) -> Tuple[Optional[str], Dict[str, Any]]:
    """``(preset, params)`` of engine ``method`` in the TOML file ``path``: the preset its
    ``preset`` key names (None without one) and the parameters of its other keys;
    :class:`InputError` naming the file (and the key) for a missing or malformed file, an
    unknown key, a bad value or a preset the engine does not have."""
    path = Path(path)
    spec = get_engine_spec(method)
    preset: Optional[str] = None
    params: Dict[str, Any] = {}
    for key, value in _load(path).items():
        name = key.replace("-", "_")
        try:
            if name == "preset":
                preset = _preset(spec, value)
            elif name in spec.params:
                params[name] = _value(spec.params[name], name, value)
            else:
                raise InputError(spec.unknown_param(name))
        except InputError as err:
            raise InputError(f"{path}: key {key!r}: {err}") from None
    return preset, params


def _preset(spec: Any, value: Any) -> str:
    """``value`` checked as the name of one of ``spec``'s engine presets."""
    if not isinstance(value, str):
        raise InputError(f"takes a preset name in quotes (preset = \"fast\"), not {value!r}")
    spec.preset_values(value)  # (an unknown name, or an engine without presets, is refused)
    return value
