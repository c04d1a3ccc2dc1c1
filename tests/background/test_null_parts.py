"""The null parts of the moving-camera engine's path: each leaves the frame as the engine would
without the part."""

import numpy as np

from bgsub.background.compensated import CompensatedBackground
from bgsub.background.exposure import same_exposure
from bgsub.background.still_switch import NoStillSwitch
from bgsub.engines.roi import WHOLE_FRAME, RegionOfInterest
from bgsub.motion.result import NO_MOTION


def test_without_exposure_matching_the_frame_is_compared_as_it_came():
    frame = np.full((8, 10, 3), 200, np.uint8)
    model = CompensatedBackground()
    model.restart(np.full((8, 10, 3), 100, np.uint8))
    exposed, gain = same_exposure(frame, model)
    assert exposed is frame and gain == 1.0


def test_without_the_still_camera_switch_the_compensated_score_stands():
    switch = NoStillSwitch()
    frame = np.zeros((8, 10), np.uint8)
    switch.restart(frame)
    switch.update(frame, np.zeros((8, 10), bool), -1.0)
    assert switch.judge(frame, NO_MOTION) is None and not switch.camera_still


def test_the_whole_frame_leaves_fits_results_and_young_pixels_alone():
    young = np.zeros((8, 10), bool)
    fit = object()
    assert WHOLE_FRAME.restrict_fit(fit) is fit
    assert WHOLE_FRAME.restrict(NO_MOTION, (8, 10)) is NO_MOTION
    assert WHOLE_FRAME.unwatched(young) is young


def test_a_region_counts_the_pixels_outside_it_as_unwatched():
    inside = np.zeros((8, 10), bool)
    inside[2:6, 3:7] = True
    region = RegionOfInterest(inside.astype(np.uint8) * 255)
    unwatched = region.unwatched(np.zeros((8, 10), bool))
    np.testing.assert_array_equal(unwatched, ~inside)
