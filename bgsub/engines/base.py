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

import difflib
import functools
import importlib
import numbers
import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

import cv2
import numpy as np

from bgsub.engines.roi import ROI_HELP, RegionOfInterest
from bgsub.errors import InputError, describe_shape
from bgsub.settings import Param

# The built-in engines, in the order they are listed, and the module whose import registers
# each: a command imports only its engine's (the classical engines start without the
# moving-camera stack), and `import bgsub` stays light.
_BUILTIN_ENGINES = {"mog2": "bgsub.engines.baselines", "knn": "bgsub.engines.baselines",
                    "framediff": "bgsub.engines.baselines", "grbm": "bgsub.engines.moving",
                    "compensated": "bgsub.engines.moving"}

#: The engine ``bgsub run`` (and :func:`create_engine`) uses when no method is named.
DEFAULT_METHOD = "grbm"


def opencv_keywords(apply: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    """Decorate an engine's ``apply`` so it also takes OpenCV's keyword spelling:
    ``apply(frame, learningRate=0.01)`` as in code written for ``cv2.BackgroundSubtractor``,
    and so its mask is cleared outside the engine's region of interest (:attr:`Engine.roi`)."""

    @functools.wraps(apply)
    def wrapper(self: "Engine", image: np.ndarray, fgmask: Optional[np.ndarray] = None,
                learning_rate: float = -1.0, *,
                learningRate: Optional[float] = None) -> np.ndarray:  # noqa: N803 (OpenCV's)
        if learningRate is not None:
            if learning_rate != -1.0:
                raise InputError("give learning_rate or OpenCV's learningRate, not both")
            learning_rate = learningRate
        roi = getattr(self, "roi", None)
        if roi is None:
            return apply(self, image, fgmask, learning_rate)
        if isinstance(image, np.ndarray) and image.ndim >= 2:
            roi.at(image.shape)  # a region of another aspect ratio: refused before any change
        mask = apply(self, image, fgmask, learning_rate)
        roi.clear_outside(mask)
        return mask

    if wrapper.__doc__ is None:
        wrapper.__doc__ = Engine.apply.__doc__  # help(engine.apply) shows the shared contract
    return wrapper


def check_frame(image: Any, *, shape: Optional[tuple] = None) -> np.ndarray:
    """Validate one input frame of an engine; the checks every engine's ``apply`` starts with.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) uint8 array
    shape : (H, W) or (H, W, 3), optional
        The shape of the stream's earlier frames as this function returned them: a frame of
        another size, or gray after colour (or colour after gray), is refused (an engine's
        model is of one size and kind; a new stream needs a new engine).

    Returns
    -------
    ``image``, its ``(H, W)`` view when it has one channel, or its BGR copy when it has four
    (an alpha channel, as ``cv2.IMREAD_UNCHANGED`` reads a PNG).
    """
    if not isinstance(image, np.ndarray) or image.ndim == 0:
        what = ("a single number" if isinstance(image, (np.generic, np.ndarray))
                else type(image).__name__)
        raise InputError(f"engine input must be a uint8 numpy image, not {what}")
    if image.dtype != np.uint8:
        hint = (": scale it to 8 bits first, e.g. (frame >> 8).astype(np.uint8)"
                if image.dtype == np.uint16 else "")
        raise InputError(f"engine input must be a uint8 image, not {image.dtype}{hint}")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4))):
        raise InputError(f"engine input must be (H, W) gray, (H, W, 3) BGR or (H, W, 4) BGRA, "
                         f"not shape {tuple(image.shape)}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise InputError(f"engine input is empty (shape {image.shape})")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    elif image.ndim == 3 and image.shape[2] == 4:
        image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    if shape is not None and image.shape != tuple(shape):
        raise InputError(f"frames changed from {describe_shape(tuple(shape))} to "
                         f"{describe_shape(image.shape)} (a new stream needs a new engine)")
    return image


def check_learning_rate(learning_rate: Any, *, default: float = -1.0) -> float:
    """``learning_rate`` as a float in [0, 1], or negative (automatic); a negative one is
    replaced by ``default``, the engine's ``learning_rate`` parameter."""
    if isinstance(learning_rate, (bool, np.bool_)) or not isinstance(learning_rate, numbers.Real):
        raise InputError(f"learning_rate must be a number, not {learning_rate!r}")
    rate = float(learning_rate)
    if not np.isfinite(rate) or rate > 1.0:
        raise InputError(f"learning_rate must be in [0, 1] or negative (automatic), not {rate}")
    return float(default) if rate < 0 else rate


def check_fgmask(fgmask: Any, shape: tuple) -> None:
    """Refuse an ``fgmask`` output buffer that is not a ``shape`` (H, W) uint8 array; called
    before the engine learns the frame, so a refused call leaves the engine as it was."""
    if fgmask is None:
        return
    if not isinstance(fgmask, np.ndarray) or fgmask.dtype != np.uint8 or fgmask.shape != shape:
        got = (f"{fgmask.dtype} {fgmask.shape}" if isinstance(fgmask, np.ndarray)
               else type(fgmask).__name__)
        raise InputError(f"fgmask must be a {tuple(shape)} uint8 array, not {got}")
    if not fgmask.flags.writeable:
        raise InputError("fgmask is read-only; give a writeable array (or none: apply returns "
                         "the mask)")


class Engine(ABC):
    """A background subtractor with OpenCV's ``BackgroundSubtractor`` shape.

    Implementations decorate ``apply`` with :func:`opencv_keywords` and start it with
    :func:`check_frame`, :func:`check_learning_rate` and :func:`check_fgmask`, so every engine
    refuses the same inputs with the same words before it changes state.

    Optional capabilities (see :data:`CAPABILITIES`): an engine that has one defines the
    attribute annotated below; one that has not leaves it undefined, and callers ask
    :func:`supports` rather than guessing.
    """

    #: ``"ok"`` or ``"fallback: <reason>"`` for the last frame.
    last_status: str
    #: The camera motion from the previous frame to the last one: ``(3, 3) float64`` in input
    #: pixels, or None where none was measured (a property on the engines that have it).
    last_motion: Optional[np.ndarray]
    #: ``debug_image() -> Optional[(H, W, 3) uint8]``: a picture of what the engine saw.
    debug_image: Callable[[], Optional[np.ndarray]]
    #: ``prime(frames)``: learn the scene from a stream's first frames, up to ``lookback`` of
    #: them, before the first :meth:`apply` (:func:`bgsub.engines.lookback.primed`).
    prime: Callable[[Sequence[np.ndarray]], None]
    lookback: int
    #: The region watched (:class:`bgsub.engines.roi.RegionOfInterest`), None = the whole
    #: frame: set from the ``roi`` parameter every registered engine takes.
    roi: Optional[Any] = None

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
        image : (H, W, 3) BGR, (H, W, 4) BGRA or (H, W) gray uint8 array
            The next frame of the stream, of the same size as the earlier ones (a frame of
            another size raises :class:`~bgsub.errors.InputError`: a new stream needs a new
            engine). BGRA's alpha is dropped. Other depths (16-bit, float) are refused: scale
            them to 8 bits first (for 16-bit, ``(frame >> 8).astype(np.uint8)``).
        fgmask : (H, W) uint8 array, optional
            Written in place when given (as OpenCV does).
        learning_rate : float
            How fast the background model adapts, as in OpenCV: negative = the engine's own
            rate; 0 = do not update the model (it stays as it is while, say, a robot arm is in
            view); 1 = restart it from this frame; in between, the rate for every pixel. Also
            accepted as ``learningRate=``. The mask of a call at 1: ``mog2`` and ``knn`` (as
            OpenCV's) call the whole frame foreground, and ``knn`` the next three as well; the
            other engines compare the frame with the model they are about to discard.

        Returns
        -------
        (H, W) uint8 array with values 0 (background) and 255 (foreground).

        Raises
        ------
        InputError
            For an invalid frame, ``fgmask`` or ``learning_rate``, before the engine changes.
        """

    def get_background_image(self) -> Optional[np.ndarray]:
        """The current background estimate as an image like the input, or ``None``."""
        return None

    def close(self) -> None:
        """Release what the engine holds beyond its model (a worker thread), so that
        ``contextlib.closing(engine)`` works; the engine stays usable."""

    # OpenCV's camelCase names, so code written against cv2 runs as it is.
    def getBackgroundImage(self, backgroundImage: Optional[np.ndarray] = None  # noqa: N802,N803
                           ) -> Optional[np.ndarray]:
        """:meth:`get_background_image`; like OpenCV's, it also fills ``backgroundImage`` when
        that is an array of the background's shape and dtype (and returns it)."""
        image = self.get_background_image()
        if backgroundImage is None or image is None:
            return image
        if (not isinstance(backgroundImage, np.ndarray) or backgroundImage.shape != image.shape
                or backgroundImage.dtype != image.dtype):
            got = (f"{backgroundImage.dtype} {backgroundImage.shape}"
                   if isinstance(backgroundImage, np.ndarray) else type(backgroundImage).__name__)
            raise InputError(f"backgroundImage must be a {image.shape} {image.dtype} array, "
                             f"not {got}")
        backgroundImage[...] = image
        return backgroundImage


#: The optional capabilities of an engine, by attribute name, and what each gives.
CAPABILITIES = {
    "last_status": "a status after each frame ('ok' or 'fallback: <reason>')",
    "last_motion": "the estimated camera motion of the last frame",
    "debug_image": "a picture of what it saw (the motion field, inliers, camera fit)",
    "prime": "learns the scene from a stream's first frames (its lookback) before the first "
             "mask (bgsub.engines.lookback.primed)",
}


def supports(engine: Any, capability: str) -> bool:
    """Whether ``engine`` has the optional ``capability`` (a key of :data:`CAPABILITIES`)."""
    if capability not in CAPABILITIES:
        raise ValueError(f"unknown engine capability {capability!r}")
    if capability in ("debug_image", "prime"):
        return callable(getattr(engine, capability, None))
    return hasattr(engine, capability)


#: The ``learning_rate`` parameter every engine registers: the rate ``apply()`` uses when its
#: caller gives none (``bgsub run --param learning_rate=0.01``, as MOG2 users set it).
LEARNING_RATE = Param(-1.0, "background learning rate of every frame, as OpenCV's apply() takes "
                            "it: negative = the engine's own, 0 = never update the model, "
                            "1 = restart it every frame", high=1.0)


#: The ``roi`` parameter every registered engine takes (:mod:`bgsub.engines.roi`).
ROI = Param("", ROI_HELP)


def did_you_mean(word: str, names: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the name in ``names`` closest to ``word``, or ``""``."""
    close = difflib.get_close_matches(word, list(names), n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


#: The name of the preset that is an engine's defaults (``bgsub run --preset balanced``).
BALANCED = "balanced"


@dataclass(frozen=True)
class EngineSpec:
    """A registered engine: how to build it and what can be tuned."""

    name: str
    description: str
    factory: Callable[..., Engine]
    params: Dict[str, Param] = field(default_factory=dict)
    #: The parameters most users tune (``bgsub methods NAME`` shows these; ``--all`` every
    #: one); None = every parameter.
    common: Optional[Tuple[str, ...]] = None
    #: Named sets of parameter values (``create_engine(name, preset="fast")``): preset name ->
    #: ``{param: value}`` overrides of the defaults; empty for an engine without presets.
    presets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def is_common(self, name: str) -> bool:
        """Whether parameter ``name`` is one of the few most users tune."""
        return self.common is None or name in self.common

    def unknown_param(self, key: str) -> str:
        """The one-line message for a parameter ``key`` this engine does not take, with the
        closest name when one is close."""
        return (f"unknown parameter {key!r} for {self.name}{did_you_mean(key, self.params)} "
                f"(bgsub methods {self.name} --all lists them)")

    def preset_values(self, preset: Optional[str]) -> Dict[str, Any]:
        """The parameter values of ``preset`` (None: none, the defaults); :class:`InputError`,
        one line naming the known presets, for a name this engine has no preset of."""
        if preset is None:
            return {}
        if preset not in self.presets:
            if not self.presets:
                others = [spec.name for spec in available_engines() if spec.presets]
                where = f" ({', '.join(others)} have)" if others else ""
                raise InputError(f"method {self.name!r} has no presets{where}")
            raise InputError(f"unknown preset {preset!r} for {self.name}"
                             f"{did_you_mean(preset, self.presets)} (presets: "
                             f"{', '.join(self.presets)})")
        return dict(self.presets[preset])

    def create(self, preset: Optional[str] = None, **params: Any) -> Engine:
        """Build the engine with ``preset``'s values (:attr:`presets`), ``params`` over them;
        unknown or ill-typed parameters and unknown presets raise :class:`InputError`."""
        params = {**self.preset_values(preset), **params}
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            raise InputError(self.unknown_param(unknown[0]))
        values = {name: p.default for name, p in self.params.items()}
        for name, value in params.items():
            try:
                self.params[name].check(name, value)
            except InputError as err:
                raise InputError(f"{self.name}: {err}") from None
            values[name] = value
        roi = values.pop("roi") if self.params.get("roi") is ROI else ""
        region = None if isinstance(roi, str) and not roi else RegionOfInterest.from_value(roi)
        engine = self.factory(**values)
        if region is not None:
            engine.roi = region
        return engine


_REGISTRY: Dict[str, EngineSpec] = {}
_loaded = False
_loading = False
_load_lock = threading.RLock()


def register_engine(
    name: str, description: str, params: Optional[Dict[str, Param]] = None, *,
    common: Optional[Iterable[str]] = None,
    presets: Optional[Mapping[str, Mapping[str, Any]]] = None,
) -> Callable[[Callable[..., Engine]], Callable[..., Engine]]:
    """Decorator: register ``factory(**params) -> Engine`` under ``name``. Every engine also
    takes :data:`ROI` (``roi``), which the registry applies (:attr:`Engine.roi`), not the
    factory. ``common`` names the parameters most users tune (default: all of them);
    :class:`ValueError` for a name that is not a parameter. ``presets``: named sets of
    parameter values (:attr:`EngineSpec.presets`), each checked here."""

    def decorate(factory: Callable[..., Engine]) -> Callable[..., Engine]:
        table = dict(params or {})
        table.setdefault("roi", ROI)  # (an engine may take "roi" itself)
        chosen = None if common is None else tuple(common)
        stray = sorted(set(chosen or ()) - set(table))
        if stray:
            raise ValueError(f"engine {name!r}: common names no parameter: {stray}")
        named = {key: dict(values) for key, values in (presets or {}).items()}
        for key, values in named.items():
            for param, value in values.items():
                if param not in table:
                    raise ValueError(f"engine {name!r}: preset {key!r} sets no parameter "
                                     f"{param!r}")
                table[param].check(param, value)
        _REGISTRY[name] = EngineSpec(name, description, factory, table, chosen, named)
        return factory

    return decorate


def _load_builtins() -> None:
    # Under a lock: a thread that asks while another imports waits for every built-in engine
    # (it saw an empty registry before). The importing thread itself may ask again (a module
    # that looks an engine up while it is imported): it gets what is registered so far.
    global _loaded, _loading
    if _loaded:
        return
    with _load_lock:
        if _loaded or _loading:
            return
        _loading = True
        try:
            for module in dict.fromkeys(_BUILTIN_ENGINES.values()):
                importlib.import_module(module)
            _loaded = True
        finally:
            _loading = False


def available_engines() -> List[EngineSpec]:
    """All registered engines: the built-in ones in their order, then others in registration
    order."""
    _load_builtins()
    order = list(_BUILTIN_ENGINES)
    return sorted(_REGISTRY.values(),
                  key=lambda spec: order.index(spec.name) if spec.name in order else len(order))


def default_method() -> str:
    """Name of the engine used when none is asked for."""
    return DEFAULT_METHOD


def get_engine_spec(name: str) -> EngineSpec:
    """The registered engine called ``name``; :class:`InputError` if there is none. Of the
    built-in engines only ``name``'s module is imported."""
    if name not in _REGISTRY and name in _BUILTIN_ENGINES:
        importlib.import_module(_BUILTIN_ENGINES[name])
    if name not in _REGISTRY:
        _load_builtins()
    try:
        return _REGISTRY[name]
    except KeyError:
        names = [spec.name for spec in available_engines()]
        raise InputError(f"unknown method {name!r}{did_you_mean(name, names)} (available: "
                         f"{', '.join(names)})") from None


def create_engine(name: Optional[str] = None, preset: Optional[str] = None,
                  **params: Any) -> Engine:
    """Build the engine ``name`` (``None``: :func:`default_method`) with ``preset``'s values
    (``"fast"``, ``"balanced"``, ``"accurate"``: ``bgsub methods NAME`` lists an engine's;
    None: the defaults) and ``params`` over them."""
    spec = get_engine_spec(default_method() if name is None else name)
    return spec.create(preset, **params)


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
            raise InputError(spec.unknown_param(key))
        try:
            parsed[key] = spec.params[key].parse(key, text)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None
    return parsed
