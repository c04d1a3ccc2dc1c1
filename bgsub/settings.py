"""Configuration dataclasses whose fields carry their default, allowed range and meaning.

A stage's settings are one frozen dataclass; each field is declared with :func:`setting`, so the
one declaration gives the default, the bounds that :func:`check_settings` enforces and the help
text the engines' ``Param`` tables (``bgsub methods``, ``--param``) are generated from with
:func:`config_params`::

    @dataclass(frozen=True)
    class PyramidConfig:
        levels: int = setting(0, "pyramid levels (0 = automatic)", low=0)

        def __post_init__(self) -> None:
            check_settings(self)

    config_params(PyramidConfig)["levels"]    # Param(0, "pyramid levels (0 = automatic)", low=0)
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Dict, Iterable, Optional

from bgsub.engines.base import Param
from bgsub.errors import InputError

__all__ = ["setting", "check_settings", "config_params"]

_KEY = "bgsub.param"


def setting(default: Any, help: str, *, low: Optional[float] = None,
            high: Optional[float] = None, above: Optional[float] = None,
            choices: Optional[tuple] = None) -> Any:
    """A dataclass field with ``default`` and its :class:`~bgsub.engines.base.Param` (meaning
    ``help``; inclusive bounds ``low`` / ``high``, exclusive lower bound ``above``; the allowed
    values ``choices`` of a text setting) in its metadata."""
    param = Param(default, help, choices=choices, low=low, high=high, above=above)
    return dataclasses.field(default=default, metadata={_KEY: param})


@functools.lru_cache(maxsize=None)
def _params(config_type: type) -> Dict[str, Param]:
    # Cached: engines build configs every frame. (The dict is never handed out to be changed.)
    return {f.name: f.metadata[_KEY] for f in dataclasses.fields(config_type) if _KEY in f.metadata}


def config_params(config_type: type, names: Optional[Iterable[str]] = None,
                  **defaults: Any) -> Dict[str, Param]:
    """The :class:`~bgsub.engines.base.Param` of each :func:`setting` field of ``config_type``
    (a dataclass), in declaration order, or of ``names`` in their order; ``defaults`` replaces
    some defaults (same help text and bounds). :class:`KeyError` for a name that is not a
    setting."""
    params = _params(config_type)
    chosen = {name: params[name] for name in (params if names is None else names)}  # a copy
    for name, value in defaults.items():
        chosen[name] = dataclasses.replace(chosen[name], default=value)
    return chosen


def check_settings(config: Any) -> None:
    """Raise :class:`~bgsub.errors.InputError` (one line naming the class and the field) when a
    :func:`setting` field of the dataclass instance ``config`` is of another type than its
    default's or outside its bounds or choices."""
    for name, param in _params(type(config)).items():
        value = getattr(config, name)
        if type(value) is type(param.default) and value == param.default:
            continue  # a default is valid (and checking every field costs ~10 us each)
        try:
            param.check(name, value)
        except InputError as err:
            raise InputError(f"{type(config).__name__}: {err}") from None
