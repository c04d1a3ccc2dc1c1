"""The foreground decision's learning mask (bgsub.background.fusion.Fusion.learn_slowly)."""

import cv2
import numpy as np
import pytest

from bgsub.background.fusion import Fusion, FusionConfig
from bgsub.errors import InputError

H, W = 96, 128


def _open_outline():
    """The outline of a 16 x 16 object, 3 px thick and open at its bottom: the mask of an object
    whose flat inside matched the background and was missed, (H, W) uint8 0/255."""
    mask = np.zeros((H, W), np.uint8)
    cv2.rectangle(mask, (50, 30), (66, 46), 255, 3)
    mask[44:49, 55:61] = 0  # the gap: a hole-filling step would not reach the inside
    return mask


@pytest.mark.parametrize("learn_close, inside_slow", [(17, True), (0, False)])
def test_a_missed_inside_of_an_object_learns_slowly(learn_close, inside_slow):
    mask = _open_outline()
    slow = Fusion(FusionConfig(learn_close=learn_close)).learn_slowly(mask, None)
    assert slow[mask > 0].all()
    assert slow[33:44, 53:64].all() == inside_slow
    assert not slow[:, :46].any() and not slow[:, 71:].any()  # nothing beyond the object grows


def test_where_the_motion_agrees_with_the_camera_the_inside_learns_at_the_normal_rate():
    mask = _open_outline()
    violation = np.full((H, W), 0.5, np.float32)
    violation[:, :58] = 0.0  # the left part moves with the camera: a ghost, to heal
    slow = Fusion(FusionConfig(learn_close=17)).learn_slowly(mask, violation)
    assert not slow[:, :58].any()
    assert slow[33:44, 58:64].all()


def test_learn_close_is_checked():
    with pytest.raises(InputError, match="learn_close"):
        FusionConfig(learn_close=-1)
