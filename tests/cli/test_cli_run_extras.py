"""`bgsub run --objects / --json / --config` end to end on a small generated clip whose
objects are known (bgsub.samples.render_frames), with test engines."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.engines import Engine, Param, register_engine
from bgsub.objects import find_regions
from bgsub.samples import SceneSpec, render_frames
from helpers import read_frames

N = 40


class _Oracle(Engine):
    """The exact ground truth of each frame of the clip (looked up by the frame's bytes);
    status "empty" on frames without foreground."""

    truth: dict = {}

    def __init__(self) -> None:
        self.last_status = "ok"

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        mask = self.truth[image.tobytes()]
        self.last_status = "ok" if mask.any() else "empty"
        return mask


class _Recording(_Oracle):
    """The oracle, remembering the parameters it was built with."""

    built: dict = {}

    def __init__(self, **params) -> None:
        super().__init__()
        _Recording.built = params


class _Stopping(_Oracle):
    """The oracle, acting as if Ctrl-C came while its sixth frame was processed."""

    def __init__(self) -> None:
        super().__init__()
        self.seen = 0

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        self.seen += 1
        if self.seen == 6:
            raise KeyboardInterrupt
        return super().apply(image)


register_engine("_test_oracle", "test: the clip's ground truth")(_Oracle)
register_engine("_test_stopping", "test: Ctrl-C at the sixth frame")(_Stopping)
register_engine("_test_recording", "test: records its parameters", params={
    "count": Param(3, "an integer", low=1),
    "rate": Param(0.5, "a number", low=0.0, high=1.0),
    "flag": Param(False, "a switch"),
})(_Recording)


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """A PNG folder of a generated pan with two objects; its masks (0/255) by frame."""
    folder = tmp_path_factory.mktemp("clip")
    masks = []
    spec = SceneSpec("pan", seed=0, width=160, height=120, n_frames=N, n_objects=2)
    for k, (image, gt, _) in enumerate(render_frames(spec)):
        cv2.imwrite(str(folder / f"in{k + 1:06d}.png"), image)
        mask = np.where(gt > 127, 255, 0).astype(np.uint8)
        _Oracle.truth[image.tobytes()] = mask
        masks.append(mask)
    return folder, masks


def _run(clip, tmp_path, *extra):
    folder, _ = clip
    return main(["run", str(folder), "-o", str(tmp_path / "masks"), "-m", "_test_oracle",
                 "-q", *map(str, extra)])


def _jsonl(path: Path) -> list:
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_objects_jsonl_holds_the_known_objects(clip, tmp_path):
    assert _run(clip, tmp_path, "--objects", tmp_path / "o.jsonl",
                "--min-object-area", 20) == 0
    lines = _jsonl(tmp_path / "o.jsonl")
    assert [line["frame"] for line in lines] == list(range(1, N + 1))
    for line, mask in zip(lines, clip[1]):
        regions = find_regions(mask, min_area=20)
        assert [o["box"] for o in line["objects"]] == [list(box) for box, _, _ in regions]
        assert [o["area"] for o in line["objects"]] == [area for _, area, _ in regions]
    assert {o["id"] for line in lines for o in line["objects"]} == {1, 2}


def test_min_object_area_leaves_small_objects_out(clip, tmp_path):
    assert _run(clip, tmp_path, "--objects", tmp_path / "o.jsonl",
                "--min-object-area", 100000) == 0
    assert all(line["objects"] == [] for line in _jsonl(tmp_path / "o.jsonl"))


def test_objects_csv_is_the_motchallenge_layout(clip, tmp_path):
    assert _run(clip, tmp_path / "a", "--objects", tmp_path / "o.jsonl") == 0
    assert _run(clip, tmp_path / "b", "--objects", tmp_path / "o.csv") == 0
    rows = list(csv.reader((tmp_path / "o.csv").open()))
    expected = [[str(line["frame"]), str(o["id"]), *map(str, o["box"]), "1", "-1", "-1", "-1"]
                for line in _jsonl(tmp_path / "o.jsonl") for o in line["objects"]]
    assert rows == expected and rows


def test_vis_draws_the_boxes_and_ids(clip, tmp_path):
    assert _run(clip, tmp_path / "a", "--vis", tmp_path / "plain.mkv") == 0
    assert _run(clip, tmp_path / "b", "--vis", tmp_path / "boxes.mkv",
                "--objects", tmp_path / "o.jsonl") == 0
    plain, boxes = read_frames(tmp_path / "plain.mkv"), read_frames(tmp_path / "boxes.mkv")
    assert len(plain) == len(boxes) == N
    for frame_a, frame_b, line in zip(plain, boxes, _jsonl(tmp_path / "o.jsonl")):
        changed = np.any(frame_a != frame_b, axis=2)
        near = np.zeros_like(changed)
        for o in line["objects"]:  # the box and its id's label above it
            x, y, w, h = o["box"]
            near[max(y - 12, 0):y + h + 1, max(x - 1, 0):x + w + 12] = True
        assert changed.any() == bool(line["objects"])
        assert not (changed & ~near).any()


def test_json_prints_one_summary_object(clip, tmp_path, capsys):
    assert _run(clip, tmp_path, "--json", "--objects", tmp_path / "o.csv") == 0
    out = capsys.readouterr().out
    summary = json.loads(out)
    empty = sum(not mask.any() for mask in clip[1])
    assert out.count("\n") == 1
    assert summary["frames"] == N and summary["complete"] is True
    assert summary["statuses"] == {"ok": N - empty, "empty": empty}
    assert summary["outputs"] == {"masks": str(tmp_path / "masks"),
                                  "objects": str(tmp_path / "o.csv")}
    assert summary["method"] == "_test_oracle" and summary["fps"] > 0


def test_json_after_ctrl_c_says_what_the_partial_outputs_hold(clip, tmp_path, capsys):
    folder, _ = clip
    code = main(["run", str(folder), "-o", str(tmp_path / "masks"), "-m", "_test_stopping",
                 "-q", "--json", "--objects", str(tmp_path / "o.jsonl")])
    summary = json.loads(capsys.readouterr().out)
    assert code == 130
    assert summary["frames"] == 5 and summary["complete"] is False
    assert len(_jsonl(tmp_path / "o.jsonl")) == 5
    assert len(list((tmp_path / "masks").glob("bin*.png"))) == 5


def _run_config(clip, tmp_path, text, *extra):
    (tmp_path / "c.toml").write_text(text)
    folder, _ = clip
    return ["run", folder, "-o", tmp_path / "masks", "-m", "_test_recording", "-q",
            "--stop", "2", "--config", tmp_path / "c.toml", *extra]


def test_config_file_sets_parameters_and_param_overrides_it(clip, tmp_path):
    argv = _run_config(clip, tmp_path, "count = 7\nrate = 1\nflag = true\n", "-p", "count=9")
    assert main([str(a) for a in argv]) == 0
    assert _Recording.built == {"count": 9, "rate": 1.0, "flag": True}


@pytest.mark.parametrize("text, key, says", [
    ("count = \n", None, "not valid TOML"),
    ("cuont = 2\n", "'cuont'", "unknown parameter"),
    ("rate = 2.5\n", "'rate'", "at most"),
    ("flag = [1]\n", "'flag'", "an array"),
    ("count = \"many\"\n", "'count'", "integer"),
])
def test_config_errors_name_the_file_and_key(clip, tmp_path, bgsub_error, text, key, says):
    line = bgsub_error(_run_config(clip, tmp_path, text))
    assert f"{tmp_path / 'c.toml'}:" in line and says in line
    assert key is None or key in line
    assert not (tmp_path / "masks").exists()


def test_objects_file_of_another_kind_is_refused(clip, tmp_path, bgsub_error):
    folder, _ = clip
    line = bgsub_error(["run", folder, "-o", tmp_path / "masks", "-m", "_test_oracle",
                        "--objects", tmp_path / "o.txt"])
    assert ".jsonl" in line and ".csv" in line
    assert not (tmp_path / "masks").exists()


def test_min_object_area_needs_objects(clip, tmp_path, bgsub_error):
    folder, _ = clip
    line = bgsub_error(["run", folder, "-o", tmp_path / "masks", "-m", "_test_oracle",
                        "--min-object-area", 5])
    assert "--objects" in line
