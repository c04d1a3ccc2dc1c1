"""The camera stage's settings (:class:`CameraConfig`, one for the whole camera-motion decision)
and the RANSAC fit it hands the motion front end (:class:`CameraFit`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bgsub.motion.global_motion import AUTO, FIT_MODELS, MOTION_MODEL_HELP, GlobalMotion, \
    fit_global_motion
from bgsub.settings import check_settings, setting

__all__ = ["CameraConfig", "CameraFit"]


@dataclass(frozen=True)
class CameraConfig:
    """The camera-motion stage: the RANSAC fit to the front end's vectors, which fits it
    refuses (``min_extent``) and which motion it holds back (``still_below``). The defaults
    are the ``grbm`` engine's: with the coarsest level read to convergence, its vectors
    support a homography at a 1 px inlier distance."""

    motion_model: str = setting(AUTO, MOTION_MODEL_HELP, choices=FIT_MODELS)
    ransac_threshold: float = setting(1.0, "RANSAC inlier distance in working-size pixels",
                                      above=0)
    min_extent: float = setting(0.33, "a camera motion must be seen across at least this "
                                      "fraction of the frame's width or height; one seen only "
                                      "on a smaller region (a textured object over a blank "
                                      "background) is taken as the object's, and the camera as "
                                      "still (0 = off)", low=0, high=1)
    still_below: float = setting(0.25, "camera motion that moves no frame corner by more than "
                                       "this (working px) is held back and added to the next "
                                       "frame's: a still camera's sub-pixel reading noise "
                                       "would resample (blur) the model every frame (0 = warp "
                                       "every frame)", low=0)
    flat_read: float = setting(0.6, "when the middle 80 % of the fit's inlier weight (each "
                                    "way) lies in a box whose sides are under this share of "
                                    "the frame's, and the rest of the frame is flat, the rest "
                                    "is read densely for the camera's translation: a subject "
                                    "the camera follows over sky, fog or calm water, the only "
                                    "thing the patches read (0 = off)", low=0, high=1)
    flat_correlation: float = setting(0.5, "a dense read of a flat background (flat_read) is "
                                           "the camera's motion when its correlation is at "
                                           "least this and it differs from the fit by over a "
                                           "pixel", low=0, high=1)

    def __post_init__(self) -> None:
        check_settings(self)


class CameraFit:
    """The camera-motion fit a front end applies to its vectors: RANSAC of the ``config``'s
    ``motion_model`` with inlier distance ``ransac_threshold`` (working-size px)."""

    def __init__(self, config: CameraConfig) -> None:
        self.config = config

    def __call__(self, points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                 shape: tuple) -> GlobalMotion:
        """The motion of ``(N, 2)`` ``points`` moved by ``disp``, with ``(N,)`` ``weights``,
        in an ``(h, w)`` frame."""
        return fit_global_motion(points, points + disp, weights=weights,
                                 model=self.config.motion_model,
                                 threshold=self.config.ransac_threshold,
                                 frame_size=(shape[1], shape[0]))
