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
import math
import numbers
from dataclasses import dataclass
from typing import Any, Dict, Iterable, Optional

import numpy as np

from bgsub.errors import InputError

__all__ = ["Param", "setting", "check_settings", "config_params"]

_KEY = "bgsub.param"

_C_INT_MAX = 2**31 - 1


_KIND_NAMES = {bool: "yes/no (1/0, true/false, on/off)", int: "an integer", float: "a number",
               str: "text"}


@dataclass(frozen=True)
class Param:
    """One tunable parameter of an engine: its default (which also fixes its type) and meaning.

    ``choices`` lists the allowed values of a text parameter; ``low`` / ``high`` bound a number
    (inclusive) and ``above`` bounds it from below, exclusive (a rate that must be positive).
    """

    default: Any
    help: str
    choices: Optional[tuple] = None
    low: Optional[float] = None
    high: Optional[float] = None
    above: Optional[float] = None

    def parse(self, name: str, text: str) -> Any:
        """Convert the command-line text ``text`` to this parameter's type."""
        kind = type(self.default)
        try:
            if kind is bool:
                lowered = text.strip().lower()
                if lowered not in {"1", "0", "true", "false", "yes", "no", "on", "off"}:
                    raise ValueError(text)
                value: Any = lowered in {"1", "true", "yes", "on"}
            elif kind is int:
                value = int(text)
            elif kind is float:
                value = float(text)
            else:
                value = text
        except ValueError:
            raise InputError(f"parameter {name!r} takes {_KIND_NAMES.get(kind, kind.__name__)}, "
                             f"not {text!r}") from None
        self.check(name, value)
        return value

    def check(self, name: str, value: Any) -> None:
        """Raise :class:`InputError` when ``value`` is not of this parameter's type (that of
        its default; an integer is also a number), not finite, or outside ``choices`` or the
        bounds. A parameter whose default is not a bool, int, float or str (a model object)
        takes any value."""
        self._check_type(name, value)
        if self.choices is not None and value not in self.choices:
            allowed = ", ".join(map(str, self.choices))
            raise InputError(f"parameter {name!r} must be one of {allowed}, not {value!r}")
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            return
        if not math.isfinite(value):
            raise InputError(f"parameter {name!r} must be a finite number, not {value!r}")
        if isinstance(value, int) and not -_C_INT_MAX <= value <= _C_INT_MAX:
            # Engines hand their integers to OpenCV, whose C ints cannot hold more.
            raise InputError(f"parameter {name!r} is too large: {value}")
        if self.low is not None and not value >= self.low:
            raise InputError(f"parameter {name!r} must be at least {self.low:g}, not {value!r}")
        if self.high is not None and not value <= self.high:
            raise InputError(f"parameter {name!r} must be at most {self.high:g}, not {value!r}")
        if self.above is not None and not value > self.above:
            raise InputError(f"parameter {name!r} must be greater than {self.above:g}, "
                             f"not {value!r}")


    def _check_type(self, name: str, value: Any) -> None:
        kind = type(self.default)
        if kind is bool:
            ok = isinstance(value, (bool, np.bool_))
        elif kind is int:
            # Not a float, even 3.0: the engines would truncate 1.7 to 1 without a word.
            ok = isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))
        elif kind is float:
            ok = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
        elif kind is str:
            # A model parameter may also take the object itself (a GatedRBM) from Python.
            ok = isinstance(value, str) or self.choices is None
        else:
            ok = True
        if not ok:
            raise InputError(f"parameter {name!r} takes {_KIND_NAMES.get(kind, kind.__name__)}, "
                             f"not {value!r}")


def setting(default: Any, help: str, *, low: Optional[float] = None,
            high: Optional[float] = None, above: Optional[float] = None,
            choices: Optional[tuple] = None) -> Any:
    """A dataclass field with ``default`` and its :class:`Param` (meaning
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
    """The :class:`Param` of each :func:`setting` field of ``config_type``
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
            continue  # a default is valid (and engines build configs every frame)
        try:
            param.check(name, value)
        except InputError as err:
            raise InputError(f"{type(config).__name__}: {err}") from None
