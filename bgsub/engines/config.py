"""Settings of the moving-camera engine around its stages (:class:`EngineConfig`).

With the camera stage's (:class:`~bgsub.camera.config.CameraConfig`), the background model's
(:class:`~bgsub.background.compensated.BackgroundConfig`), the foreground policies'
(:class:`~bgsub.background.foreground.ForegroundConfig`), the fusion's
(:class:`~bgsub.background.fusion.FusionConfig`), the overlay detection's
(:class:`~bgsub.background.overlay.OverlayConfig`) and the front end's settings they make an
engine's parameters: :func:`engine_params` generates its ``Param`` table from their fields,
:func:`stage_configs` builds them back from parameter values.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Dict, Mapping

from bgsub.background.compensated import BackgroundConfig
from bgsub.background.foreground import ForegroundConfig
from bgsub.background.fusion import FusionConfig
from bgsub.background.overlay import OverlayConfig
from bgsub.camera.config import CameraConfig
from bgsub.camera.parallax import ParallaxConfig
from bgsub.engines.base import LEARNING_RATE, Param
from bgsub.errors import InputError
from bgsub.settings import check_settings, config_params, setting

__all__ = ["MIN_WORK_WIDTH", "CameraConfig", "EngineConfig", "ForegroundConfig", "STAGES",
           "engine_params", "stage_configs"]

# The narrowest working frame: a few 13x13 patches across, so a motion can be read at all.
# Resizing to ``work_width`` never makes the short side smaller than this either.
MIN_WORK_WIDTH = 32


@dataclass(frozen=True)
class EngineConfig:
    """The engine around its stages: frame size, the mask's placement on the frame's edges,
    threads, smoothing, the frames it does not process (blank) and the default learning
    rate."""

    work_width: int = setting(320, "process frames resized to this width (0 = input size, else "
                                   f"at least {MIN_WORK_WIDTH}), but never to a height below "
                                   f"{MIN_WORK_WIDTH}; the mask is returned at the input size",
                              low=0)
    edge_radius: int = setting(8, "the fused mask is placed on the frame's own colour edges "
                                  "by a guided filter with windows of this radius (working "
                                  "px), and scaled up to the input size along them (0 = the "
                                  "fused mask, scaled up bilinearly)", low=0, high=64)
    edge_eps: float = setting(0.001, "guided-filter windows (edge_radius) whose colour "
                                     "variance (values in [0, 1]) is well below this keep the "
                                     "fused mask's mean rather than follow the frame's edges",
                              above=0)
    edge_step: int = setting(2, "the guided filter (edge_radius) is fitted on the mask and "
                                "frame shrunk by this factor and scaled back up (the fast "
                                "guided filter: 2 fits a quarter of the pixels)", low=1, high=8)
    colour_cut: int = setting(0, "after placement, GrabCut adds to the mask the pixels within "
                                 "this radius (px of the frame shrunk to at most 480 wide) "
                                 "that its colour model gives to the objects: their flat "
                                 "parts, which show no motion (0 = off; its time grows "
                                 "with the objects: up to 2.5x a frame's)",
                              low=0, high=64)
    lookback: int = setting(30, "before its first mask the engine reads this many frames "
                                "ahead, when its caller has them (bgsub run and compare "
                                "do), and a twin of it runs them backwards: the first masks, "
                                "those the twin has seen more of the scene for, are the twin's "
                                "(0 = off: a model that starts at frame 1 gives no mask for it "
                                "and weak ones after)", low=0)
    threads: int = setting(1, "BLAS and OpenCV worker threads while a frame is processed (0 = "
                              "as configured; more threads are slower for these small frames)",
                           low=0)
    overlap: int = setting(1, "1 = update the background and prepare the frame for the next "
                              "pair in a second thread while the motion is measured (same "
                              "masks, faster on 2 or more cores); 0 = one thread", low=0, high=1)
    smooth: float = setting(0.0, "Gaussian blur (sigma, working px) of each frame before it "
                                 "is measured and compared: for noisy or heavily compressed "
                                 "footage, whose pixel noise otherwise reads as motion and as "
                                 "background differences (1 suits sensor noise of 6 gray "
                                 "levels or JPEG quality 25; 0 = off)", low=0, high=8)
    min_contrast: float = setting(4.0, "frames whose gray standard deviation is below this are "
                                       "blank or textureless: empty mask, model kept", low=0)
    learning_rate: float = setting(LEARNING_RATE.default, LEARNING_RATE.help,
                                   high=LEARNING_RATE.high)

    def __post_init__(self) -> None:
        check_settings(self)
        if 0 < self.work_width < MIN_WORK_WIDTH:
            raise InputError(f"parameter 'work_width' must be 0 (the input's width) or at "
                             f"least {MIN_WORK_WIDTH}, not {self.work_width!r}")


#: The engine's stage settings, in the order of its parameter table.
STAGES = (EngineConfig, CameraConfig, ParallaxConfig, BackgroundConfig, ForegroundConfig,
          FusionConfig, OverlayConfig)


def engine_params(front_params: Mapping[str, Param],
                  stage_defaults: Mapping[str, Any]) -> Dict[str, Param]:
    """The ``Param`` table of an engine: the front end's ``front_params``, then every stage
    setting, with ``stage_defaults`` (a front end's) replacing some defaults."""
    table = dict(front_params)
    for stage in STAGES:
        names = [f.name for f in dataclasses.fields(stage)]
        clash = set(names) & set(table)
        if clash:
            raise ValueError(f"{stage.__name__} and the front end both have {sorted(clash)}")
        table.update(config_params(stage, **{k: v for k, v in stage_defaults.items()
                                             if k in names}))
    unknown = set(stage_defaults) - set(table)
    if unknown:
        raise ValueError(f"stage_defaults names no stage setting: {sorted(unknown)}")
    return table


def stage_configs(values: Mapping[str, Any],
                  stage_defaults: Mapping[str, Any] = {}) -> Dict[type, Any]:
    """``{stage type: its settings}`` from parameter ``values`` (unnamed fields take
    ``stage_defaults``, then the stage's own default); names no stage has are ignored."""
    out = {}
    for stage in STAGES:
        names = {f.name for f in dataclasses.fields(stage)}
        chosen = {k: v for k, v in stage_defaults.items() if k in names}
        chosen.update({k: v for k, v in values.items() if k in names})
        out[stage] = stage(**chosen)
    return out
