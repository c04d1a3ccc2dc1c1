"""The motion front end of the moving-camera engine: what it must provide, what it may.

A front end measures local motion between consecutive frames and has the camera's motion fitted
to it; the engine (:class:`bgsub.engines.moving.MovingCameraEngine`) does everything else. It
must provide

* :meth:`MotionFrontEnd.measure` ``(prev, cur, *, prior, fit) -> MotionResult``: the motion
  from the previous frame to the current one, each as :meth:`~MotionFrontEnd.frame_data` made
  it; ``fit`` (a :class:`CameraFit`) fits the camera motion to vectors;

and may provide

* :meth:`~MotionFrontEnd.frame_data` ``(gray)``: what it keeps of a frame (default: the gray
  image itself), cheap;
* :meth:`~MotionFrontEnd.prepare` ``(data)``: work on a frame that only the *next* pair needs,
  done in the engine's second thread while this pair is measured (``overlap=1``);
* :meth:`~MotionFrontEnd.check_size` ``(gray)``: refuse, on the first frame, a stream it cannot
  read at all;
* :meth:`~MotionFrontEnd.read_layer` ``(prev, cur, result, *, prior, layer, fit)``: read the pair
  again for a near layer of a 3-D scene that moves beyond its reach from ``prior`` (default:
  ``result`` as it is);
* :meth:`~MotionFrontEnd.flow_colour` ``(shape)``: a picture of the last measured motion for
  ``debug_image``.

Its settings are a frozen dataclass (``config_type``, fields declared with
:func:`bgsub.settings.setting`), from which its engine's parameters are generated; it may replace
defaults of the engine's stages (``stage_defaults``) and name sets of parameter values
(``presets``: ``fast``, ``balanced``, ``accurate``). :func:`bgsub.engines.moving.register_frontend`
registers the engine that uses it::

    class MyFrontEnd(MotionFrontEnd):
        name, description = "mine", "moving camera: my motion vectors"

        def measure(self, prev, cur, *, prior, fit):
            points, disp = my_vectors(prev, cur)            # (N, 2) float32 each
            weights = np.ones(len(points), np.float32)
            return MotionResult(points, disp, weights, fit(points, disp, weights, cur.shape))

    register_frontend(MyFrontEnd)
    engine = bgsub.create_engine("mine")
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import MappingProxyType
from typing import Any, ClassVar, Dict, Mapping, Optional, Tuple

import numpy as np

from bgsub.camera.config import CameraFit
from bgsub.camera.near_layer import NearLayer
from bgsub.motion.result import NO_MOTION, MotionResult
from bgsub.settings import Param, config_params

__all__ = ["MotionResult", "MotionFrontEnd", "CameraFit", "NO_MOTION"]


class MotionFrontEnd(ABC):
    """Base class of the motion front ends (see the module docstring for the contract)."""

    #: The engine's registered name and its one-line description (``bgsub methods``).
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    #: The front end's settings: a frozen dataclass of :func:`~bgsub.settings.setting` fields.
    config_type: ClassVar[Optional[type]] = None
    #: Defaults of the engine's stage settings (by field name) that this front end replaces.
    stage_defaults: ClassVar[Mapping[str, Any]] = {}
    #: The engine's parameters most users tune (``bgsub methods NAME``; ``--all`` lists every
    #: one): the stages' few, to which a front end adds its own.
    common_params: ClassVar[Tuple[str, ...]] = ("work_width", "smooth", "threshold", "overlap",
                                                "learning_rate")
    #: The engine's named presets (``--preset``, ``create_engine(name, preset=...)``): preset
    #: name -> the parameter values it sets over the defaults; ``balanced`` is the defaults.
    presets: ClassVar[Mapping[str, Mapping[str, Any]]] = MappingProxyType({
        "fast": {"work_width": 160, "edge_radius": 0},  # motion and mask at half size, no edges
        "balanced": {},
        "accurate": {"work_width": 480},  # more of the frame's detail
    })

    def __init__(self, config: Any = None) -> None:
        if config is None and self.config_type is not None:
            config = self.config_type()
        self.config = config

    @classmethod
    def params(cls) -> Dict[str, Param]:
        """The engine parameters of the front end's settings (generated from ``config_type``)."""
        return config_params(cls.config_type) if cls.config_type is not None else {}

    @classmethod
    def from_params(cls, **values: Any) -> "MotionFrontEnd":
        """The front end with the settings :meth:`params` names (``bgsub run --param``)."""
        return cls(cls.config_type(**values) if cls.config_type is not None else None)

    @abstractmethod
    def measure(self, prev: Any, cur: Any, *, prior: Optional[np.ndarray],
                fit: CameraFit) -> MotionResult:
        """The motion from ``prev`` to ``cur`` (as :meth:`frame_data` made them); ``prior``
        is the camera's last good motion ((3, 3) float64, working size) or None."""

    def frame_data(self, gray: np.ndarray) -> Any:
        """What the front end keeps of a frame (``gray``: (h, w) uint8, working size, not
        modified later); cheap: the expensive part goes to :meth:`prepare`."""
        return gray

    def prepare(self, data: Any) -> None:
        """Work on a frame that only the *next* pair needs (it is that pair's first frame),
        done in place on ``data`` while this frame's motion is measured."""

    def read_layer(self, prev: Any, cur: Any, result: MotionResult, *, prior: np.ndarray,
                   layer: NearLayer, fit: CameraFit) -> MotionResult:
        """``result`` (what :meth:`measure` found from ``prior``) with the vectors of a second
        read, pre-warped by ``layer.prior(prior)``, where they read the near ``layer`` better
        (:mod:`bgsub.camera.near_layer`); ``result`` itself (the same object) where the second
        read takes nothing, as by default."""
        return result

    def check_size(self, gray: np.ndarray) -> None:
        """Raise :class:`~bgsub.errors.InputError` when frames of ``gray``'s (working) size
        cannot be read at all; called on the first frame, before any mask is returned."""

    def flow_colour(self, shape: tuple) -> Optional[np.ndarray]:
        """A colour-coded ``(h, w, 3) uint8`` picture of the last measured local motion, or
        None."""
        return None

    def colour_scale(self) -> Optional[float]:
        """The speed (px/frame) :meth:`flow_colour` shows at full saturation, for the picture's
        colour-wheel legend; None: no legend."""
        return None
