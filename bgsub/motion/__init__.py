"""Motion between frames: patch motion read by the gated RBM coarse to fine
(:func:`estimate_flow`, configured by :class:`FlowConfig`), the camera motion RANSAC fits to it
(:mod:`bgsub.motion.global_motion`) and NCC block matching as a classical reference
(:mod:`bgsub.motion.blockmatch`)."""

from bgsub.motion.config import FlowConfig  # noqa: F401
from bgsub.motion.flowfield import (  # noqa: F401
    FlowEstimate,
    FramePyramid,
    MotionRangeWarning,
    dense_from_patches,
    estimate_flow,
    model_range,
    prepare_first_frame,
    pyramid_reach,
)

__all__ = ["FlowConfig", "FlowEstimate", "FramePyramid", "MotionRangeWarning",
           "dense_from_patches", "estimate_flow", "model_range", "prepare_first_frame",
           "pyramid_reach"]
