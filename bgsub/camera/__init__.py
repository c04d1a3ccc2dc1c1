"""The camera stage: every decision on the camera's motion between the front end's vectors and
the background model's warp (fit, small-region rule, hold-back, frozen registration, known
motion), with one config (:class:`CameraConfig`)."""

from bgsub.camera.config import CameraConfig, CameraFit
from bgsub.camera.known import KNOWN_MOTION_HELP, KnownMotion, NoKnownMotion, work_scale
from bgsub.camera.registration import FrozenModelRegistration
from bgsub.camera.rules import SMALL_REGION, MotionHoldBack, SmallRegionRule, spans_frame
from bgsub.camera.stage import CameraDecision, CameraStage

__all__ = ["CameraConfig", "CameraFit", "CameraDecision", "CameraStage", "KnownMotion",
           "NoKnownMotion", "KNOWN_MOTION_HELP", "work_scale", "FrozenModelRegistration",
           "SMALL_REGION", "MotionHoldBack", "SmallRegionRule", "spans_frame"]
