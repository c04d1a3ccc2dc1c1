"""Regions of a mask and their ids across frames (bgsub.objects.tracker)."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.objects import ObjectTracker, TrackerConfig, find_regions
from bgsub.samples import SceneSpec, render_frames

H, W = 60, 80


def _mask(*boxes):
    mask = np.zeros((H, W), np.uint8)
    for x, y, w, h in boxes:
        mask[y:y + h, x:x + w] = 255
    return mask


def test_regions_are_boxes_areas_and_centroids():
    regions = find_regions(_mask((10, 5, 8, 4), (40, 30, 3, 3)), min_area=1)
    assert regions == [((10, 5, 8, 4), 32, (13.5, 6.5)), ((40, 30, 3, 3), 9, (41.0, 31.0))]


def test_min_area_leaves_small_regions_out():
    tracker = ObjectTracker(TrackerConfig(min_area=10))
    assert [o.box for o in tracker.update(_mask((10, 5, 8, 4), (40, 30, 3, 3)))] == \
        [(10, 5, 8, 4)]


def test_ids_follow_two_moving_squares():
    tracker = ObjectTracker(TrackerConfig(min_area=1))
    for step in range(10):
        objects = tracker.update(_mask((2 + 4 * step, 5, 6, 6), (60 - 4 * step, 40, 6, 6)))
        by_row = {o.box[1]: o.id for o in objects}
        assert by_row == {5: 1, 40: 2}


def test_an_object_unseen_for_a_few_frames_keeps_its_id():
    tracker = ObjectTracker(TrackerConfig(min_area=1, max_gap=3))
    ids = []
    for step in range(8):
        hidden = step in (3, 4)  # occluded for two frames, moving on meanwhile
        objects = tracker.update(_mask() if hidden else _mask((2 + 5 * step, 20, 6, 6)))
        ids += [o.id for o in objects]
    assert ids == [1] * 6


def test_an_object_unseen_longer_than_max_gap_gets_a_new_id():
    tracker = ObjectTracker(TrackerConfig(min_area=1, max_gap=1))
    ids = [o.id for step in range(6)
           for o in tracker.update(_mask() if step in (2, 3) else _mask((10, 20, 6, 6)))]
    assert ids == [1, 1, 2, 2]


@pytest.mark.parametrize("field, value", [("min_area", 0), ("min_iou", 1.5),
                                          ("max_distance", -1.0), ("max_gap", -1)])
def test_config_refuses_values_out_of_range(field, value):
    with pytest.raises(ValueError, match=field):
        TrackerConfig(**{field: value})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scene_objects_keep_one_id_each_while_in_view(seed):
    # A generated pan with two objects, each crossing the view once: exact ground-truth masks.
    spec = SceneSpec("pan", seed=seed, width=160, height=120, n_frames=60, n_objects=2)
    tracker = ObjectTracker(TrackerConfig(min_area=20))
    frames_of = {}
    for k, scene in enumerate(render_frames(spec)):
        objects = tracker.update(scene.groundtruth)
        regions = find_regions(scene.groundtruth, min_area=20)
        assert [o.box for o in objects] == [box for box, _, _ in regions]
        for obj in objects:
            frames_of.setdefault(obj.id, []).append(k)
    assert len(frames_of) == 2
    for frames in frames_of.values():  # each id seen over one unbroken run of frames
        assert frames == list(range(frames[0], frames[-1] + 1))
