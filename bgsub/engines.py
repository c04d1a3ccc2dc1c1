"""Background-subtraction engines behind one interface, and the registry that names them.

Every engine has the shape of OpenCV's ``cv2.BackgroundSubtractor``, so a loop written for
``cv2.createBackgroundSubtractorMOG2()`` takes any bgsub engine unchanged::

    engine = bgsub.create_engine("grbm")
    for frame in frames:                      # (H, W, 3) or (H, W) uint8
        mask = engine.apply(frame)            # (H, W) uint8, 0 = background, 255 = foreground

Engines register themselves with :func:`register_engine`; the CLI (``bgsub run --method``,
``bgsub methods``) only ever goes through this registry, so a new engine needs no CLI change.
"""

from __future__ import annotations

import functools
import importlib
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterable, List, Optional

import numpy as np

from bgsub.errors import InputError

# Modules whose import registers the built-in engines (imported on first use of the registry,
# so `import bgsub` stays light).
_BUILTIN_MODULES = ("bgsub.baselines", "bgsub.pipeline")

#: The engine ``bgsub run`` (and :func:`create_engine`) uses when no method is named.
DEFAULT_METHOD = "grbm"


def opencv_keywords(apply: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """Decorate an engine's ``apply`` so it also takes OpenCV's keyword spelling:
    ``apply(frame, learningRate=0.01)`` as in code written for ``cv2.BackgroundSubtractor``."""

    @functools.wraps(apply)
    def wrapper(self: "Engine", image: np.ndarray, fgmask: Optional[np.ndarray] = None,
                learning_rate: float = -1.0, *,
                learningRate: Optional[float] = None) -> np.ndarray:  # noqa: N803 (OpenCV's)
        if learningRate is not None:
            if learning_rate != -1.0:
                raise InputError("give learning_rate or OpenCV's learningRate, not both")
            learning_rate = learningRate
        return apply(self, image, fgmask, learning_rate)

    return wrapper


class Engine(ABC):
    """A background subtractor with OpenCV's ``BackgroundSubtractor`` shape.

    Implementations decorate ``apply`` with :func:`opencv_keywords`."""

    @abstractmethod
    def apply(
        self,
        image: np.ndarray,
        fgmask: Optional[np.ndarray] = None,
        learning_rate: float = -1.0,
    ) -> np.ndarray:
        """Process the next frame and return its foreground mask.

        Parameters
        ----------
        image : (H, W, 3) BGR or (H, W) gray uint8 array
            The next frame of the stream.
        fgmask : (H, W) uint8 array, optional
            Written in place when given (as OpenCV does).
        learning_rate : float
            How fast the background model adapts, in [0, 1]; negative picks the engine's own
            rate (OpenCV's convention).

        Returns
        -------
        (H, W) uint8 array with values 0 (background) and 255 (foreground).
        """

    def get_background_image(self) -> Optional[np.ndarray]:
        """The current background estimate as an image like the input, or ``None``."""
        return None

    # OpenCV's camelCase names, so code written against cv2 runs as it is.
    def getBackgroundImage(self) -> Optional[np.ndarray]:  # noqa: N802 (OpenCV's name)
        return self.get_background_image()


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
        """Raise :class:`InputError` when ``value`` is outside ``choices`` or the bounds."""
        if self.choices is not None and value not in self.choices:
            allowed = ", ".join(map(str, self.choices))
            raise InputError(f"parameter {name!r} must be one of {allowed}, not {value!r}")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return
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


@dataclass(frozen=True)
class EngineSpec:
    """A registered engine: how to build it and what can be tuned."""

    name: str
    description: str
    factory: Callable[..., Engine]
    params: Dict[str, Param] = field(default_factory=dict)

    def create(self, **params: Any) -> Engine:
        """Build the engine; unknown or ill-typed parameters raise :class:`InputError`."""
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            known = ", ".join(self.params) or "none"
            raise InputError(
                f"method {self.name!r} has no parameter {unknown[0]!r} (its parameters: {known})"
            )
        values = {name: p.default for name, p in self.params.items()}
        for name, value in params.items():
            try:
                self.params[name].check(name, value)
            except InputError as err:
                raise InputError(f"{self.name}: {err}") from None
            values[name] = value
        return self.factory(**values)


_REGISTRY: Dict[str, EngineSpec] = {}
_loaded = False


def register_engine(
    name: str, description: str, params: Optional[Dict[str, Param]] = None
) -> Callable[[Callable[..., Engine]], Callable[..., Engine]]:
    """Decorator: register ``factory(**params) -> Engine`` under ``name``."""

    def decorate(factory: Callable[..., Engine]) -> Callable[..., Engine]:
        _REGISTRY[name] = EngineSpec(name, description, factory, dict(params or {}))
        return factory

    return decorate


def _load_builtins() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for module in _BUILTIN_MODULES:
        importlib.import_module(module)


def available_engines() -> List[EngineSpec]:
    """All registered engines, in registration order."""
    _load_builtins()
    return list(_REGISTRY.values())


def default_method() -> str:
    """Name of the engine used when none is asked for."""
    return DEFAULT_METHOD


def get_engine_spec(name: str) -> EngineSpec:
    """The registered engine called ``name``; :class:`InputError` if there is none."""
    _load_builtins()
    try:
        return _REGISTRY[name]
    except KeyError:
        known = ", ".join(_REGISTRY)
        raise InputError(f"unknown method {name!r} (available: {known})") from None


def create_engine(name: Optional[str] = None, **params: Any) -> Engine:
    """Build the engine ``name`` (default: :func:`default_method`) with ``params``."""
    return get_engine_spec(name or default_method()).create(**params)


def parse_params(name: str, pairs: Iterable[str]) -> Dict[str, Any]:
    """Parse ``["key=value", ...]`` from the command line against engine ``name``'s params."""
    spec = get_engine_spec(name)
    parsed: Dict[str, Any] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip().replace("-", "_")
        if not sep or not key:
            raise InputError(f"--param takes key=value, not {pair!r}")
        if key not in spec.params:
            known = ", ".join(spec.params) or "none"
            raise InputError(f"method {name!r} has no parameter {key!r} (its parameters: {known})")
        try:
            parsed[key] = spec.params[key].parse(key, text)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
    return parsed
