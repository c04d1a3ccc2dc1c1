"""report.html of `bgsub compare` (bgsub.evaluation.html_report), its frames
(bgsub.evaluation.report_frames) and the ground-truth tile of side_by_side.mp4."""

from __future__ import annotations

import base64
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path
from typing import Dict, List, Optional, Tuple

import cv2
import numpy as np
import pytest

from bgsub.cli import main
from bgsub.engines import create_engine
from bgsub.evaluation.compare import compare_methods
from bgsub.evaluation.groundtruth import open_ground_truth
from bgsub.evaluation.html_report import bar_chart_svg
from bgsub.evaluation.report_frames import FRAMES_SHOWN, ReportFrames, spread
from bgsub.evaluation.side_by_side import NO_TRUTH_BGR, TileLayout, truth_picture
from bgsub.io.h264 import h264_available
from bgsub.io.loop import FrameLoop
from helpers import SCENE_H, SCENE_W, write_box_clip, write_gt_sequence, write_input_sequence

METHODS = ["framediff", "mog2"]


class Page(HTMLParser):
    """What a test asks of the page: table rows (cells' text) by the table's class (``rows``:
    the metrics table's), the classes of each row, svg elements, images (src, alt), videos (src)
    and any address other than a data: URI that the page names."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.tables: Dict[str, List[List[str]]] = {}
        self.row_classes: Dict[str, List[str]] = {}
        self._table = ""
        self.svgs = 0
        self.images: List[Tuple[str, str]] = []
        self.videos: List[str] = []
        self.fetched: List[str] = []
        self._in_body_row = False
        self._in_tbody = False
        self._cell: Optional[List[str]] = None
        self.feed(text)

    def handle_starttag(self, tag: str, attrs) -> None:
        attrs = dict(attrs)
        if tag == "table":
            self._table = attrs.get("class", "")
        elif tag == "tbody":
            self._in_tbody = True
        elif tag == "tr" and self._in_tbody:
            self.tables.setdefault(self._table, []).append([])
            self.row_classes.setdefault(self._table, []).append(attrs.get("class", ""))
        elif tag == "td" and self._in_tbody:
            self._cell = []
        elif tag == "svg":
            self.svgs += 1
        elif tag == "img":
            self.images.append((attrs.get("src", ""), attrs.get("alt", "")))
        elif tag == "video":
            self.videos.append(attrs.get("src", ""))
        for key in ("src", "href"):
            if key in attrs and not attrs[key].startswith("data:"):
                self.fetched.append(attrs[key])

    def handle_endtag(self, tag: str) -> None:
        if tag == "tbody":
            self._in_tbody = False
        elif tag == "td" and self._cell is not None:
            self.tables[self._table][-1].append("".join(self._cell))
            self._cell = None

    @property
    def rows(self) -> List[List[str]]:
        return self.tables.get("metrics", [])

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


def decode(src: str) -> np.ndarray:
    """The picture of a ``data:image/...;base64,`` address."""
    head, _, data = src.partition(",")
    assert head in ("data:image/png;base64", "data:image/jpeg;base64"), head
    image = cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_UNCHANGED)
    assert image is not None
    return image


@pytest.fixture
def single(tmp_path: Path) -> Path:
    """A compare run on one sequence with ground truth; returns its report folder."""
    sequence = write_input_sequence(tmp_path / "famA_one", n_frames=12)
    out = tmp_path / "out"
    assert main(["compare", str(sequence), "-m", ",".join(METHODS), "-o", str(out), "-q",
                 "--skip-first", "--mask-format", "none"]) == 0
    return out


def test_report_table_has_one_row_per_method(single: Path) -> None:
    page = Page((single / "report.html").read_text())
    assert [row[2] for row in page.rows] == METHODS
    assert all(row[0] == "famA_one" for row in page.rows)


def test_report_has_a_chart_and_fetches_nothing_from_the_network(single: Path) -> None:
    text = (single / "report.html").read_text()
    page = Page(text)
    assert page.svgs == 1 and "<rect" in text
    assert page.fetched == ["side_by_side.mp4"]  # the video beside it, by a relative address
    assert (single / "side_by_side.mp4").is_file()
    assert "<link" not in text and "<script" not in text


def test_report_images_decode_input_truth_and_each_mask(single: Path) -> None:
    page = Page((single / "report.html").read_text())
    labels = ["input", "ground truth", *METHODS]
    assert len(page.images) == FRAMES_SHOWN * len(labels)
    for k, (src, alt) in enumerate(page.images):
        assert alt.startswith(labels[k % len(labels)] + ", frame ")
        image = decode(src)
        assert image.shape[:2] == (SCENE_H, SCENE_W)
        if k % len(labels):  # ground truth and masks: 0/255 only
            assert set(np.unique(image)) <= {0, 255}


def test_report_frames_are_scored_ones_and_spread(tmp_path: Path) -> None:
    sequence = write_input_sequence(tmp_path / "seq", n_frames=40)
    report = compare_methods(sequence, methods=["framediff"], skip_first=True)
    (shown,) = report.frames
    numbers = [tiles.number for tiles in shown.frames]
    assert len(numbers) == FRAMES_SHOWN and numbers == sorted(set(numbers))
    assert numbers[0] >= 2 and numbers[-1] - numbers[0] >= 20


def test_report_frames_of_a_long_input_stay_few_and_spread() -> None:
    frames = ReportFrames(["framediff"])
    rng = np.random.default_rng(0)
    pictures = ((k, rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)) for k in range(500))
    FrameLoop({"framediff": create_engine("framediff")}, [frames]).run(pictures)
    numbers = [t.number for t in frames.result(name="x", family="").frames]
    assert len(numbers) == FRAMES_SHOWN
    assert numbers[0] > 1 and numbers[-1] > 400 and numbers == sorted(numbers)


def test_spread_keeps_the_last_and_spaces_evenly() -> None:
    assert spread(list(range(10)), 3) == [3, 6, 9]
    assert spread([1, 2], 3) == [1, 2]


def test_report_without_ground_truth_shows_input_and_masks_and_speed(tmp_path: Path) -> None:
    clip = write_box_clip(tmp_path / "clip.mkv")
    out = tmp_path / "out"
    compare_methods(clip, methods=METHODS, report_dir=out, masks="none", video=False)
    text = (out / "report.html").read_text()
    page = Page(text)
    assert [alt.split(",")[0] for _, alt in page.images[:3]] == ["input", *METHODS]
    assert "frames per second" in text and page.svgs == 1
    assert [row[2] for row in page.rows] == METHODS


def test_dataset_report_charts_per_method_sequence_and_family_and_escapes_names(
        tmp_path: Path) -> None:
    root = tmp_path / "data"
    write_input_sequence(root / "fam<b>&x_one", seed=0)
    write_input_sequence(root / "famB_two", seed=1)
    out = tmp_path / "out"
    compare_methods(root, methods=METHODS, report_dir=out, masks="none", video=False)
    text = (out / "report.html").read_text()
    page = Page(text)
    assert page.svgs == 3  # overall, per sequence, per family
    assert "fam<b>" not in text and "fam&lt;b&gt;&amp;x_one" in text
    names = [row[0] for row in page.rows]
    assert names[:4] == ["fam<b>&x_one"] * 2 + ["famB_two"] * 2  # the parser unescapes
    assert "overall" in names


def test_report_plays_an_h264_side_by_side_and_links_an_mp4v_one(tmp_path: Path) -> None:
    sequence = write_input_sequence(tmp_path / "seq")
    compare_methods(sequence, methods=["framediff"], report_dir=tmp_path / "m", masks="none",
                    video_codec="mp4v")
    page = Page((tmp_path / "m" / "report.html").read_text())
    assert page.videos == [] and page.fetched == ["side_by_side.mp4"]
    if h264_available():
        compare_methods(sequence, methods=["framediff"], report_dir=tmp_path / "h",
                        masks="none", video_codec="h264")
        page = Page((tmp_path / "h" / "report.html").read_text())
        assert page.videos == ["side_by_side.mp4"]


def test_dataset_report_links_each_sequences_video(tmp_path: Path) -> None:
    root = tmp_path / "data"
    write_input_sequence(root / "cat" / "one", seed=0)
    write_input_sequence(root / "cat" / "two", seed=1)
    out = tmp_path / "out"
    compare_methods(root, methods=["framediff"], report_dir=out, masks="none",
                    video_codec="mp4v")
    page = Page((out / "report.html").read_text())
    assert page.fetched == ["cat/one/side_by_side.mp4", "cat/two/side_by_side.mp4"]
    assert all((out / path).is_file() for path in page.fetched)


def test_no_report_option_writes_no_page(tmp_path: Path) -> None:
    sequence = write_input_sequence(tmp_path / "seq")
    out = tmp_path / "out"
    assert main(["compare", str(sequence), "-m", "framediff", "-o", str(out), "-q",
                 "--no-report", "--no-video", "--mask-format", "none"]) == 0
    assert not (out / "report.html").exists() and (out / "report.txt").is_file()


def test_bar_chart_draws_one_bar_per_known_value() -> None:
    svg = bar_chart_svg("F", [("a", [("m1", 0.5), ("m2", float("nan"))])], ["m1", "m2"],
                        top=1.0)
    assert svg.count("<rect") == 1 + 2  # one bar, two legend swatches
    assert "m2: n/a" in svg


# --------------------------------------------------------------------------------------------
# The ground-truth tile
# --------------------------------------------------------------------------------------------


def test_truth_picture_shows_labels_as_gray_levels_and_marks_missing_frames(
        tmp_path: Path) -> None:
    labels = np.array([[0, 50, 85, 170, 255]], np.uint8).repeat(4, axis=0)
    gt = open_ground_truth(write_gt_sequence(tmp_path / "gt", {1: labels}))
    picture = truth_picture(gt, 1)
    assert picture.shape == (4, 5, 3)
    assert (picture[..., 0] == labels).all() and (picture[..., 2] == labels).all()
    assert (truth_picture(gt, 2) == np.array(NO_TRUTH_BGR, np.uint8)).all()


def test_truth_picture_marks_outside_roi_bmp_as_85(tmp_path: Path) -> None:
    labels = np.full((4, 6), 255, np.uint8)
    roi = np.zeros((4, 6), np.uint8)
    roi[:, :3] = 255
    gt = open_ground_truth(write_gt_sequence(tmp_path / "gt", {1: labels}, roi=roi))
    picture = truth_picture(gt, 1)[..., 0]
    assert (picture[:, :3] == 255).all() and (picture[:, 3:] == 85).all()


def test_side_by_side_has_a_ground_truth_tile(tmp_path: Path) -> None:
    # seed=10: the square 10 rows lower than by default, below the tile's label.
    sequence = write_input_sequence(tmp_path / "seq", n_frames=6, seed=10)
    out = tmp_path / "out"
    compare_methods(sequence, methods=["framediff"], report_dir=out, masks="none", html=False)
    layout = TileLayout.for_frames(SCENE_W, SCENE_H, ["input", "ground truth", "framediff"])
    capture = cv2.VideoCapture(str(out / "side_by_side.mp4"))
    for _ in range(4):
        ok, picture = capture.read()
    capture.release()
    assert ok and picture.shape == (layout.height, layout.width, 3)
    tile = cv2.cvtColor(picture[:, layout.tile_width:2 * layout.tile_width], cv2.COLOR_BGR2GRAY)
    truth = cv2.imread(str(sequence / "groundtruth" / "gt000004.png"), cv2.IMREAD_GRAYSCALE)
    y, x = np.nonzero(truth)
    # A lossy video: inside the square (away from its edges) and below it.
    assert tile[y.min() + 2:y.max() - 1, x.min() + 2:x.max() - 1].mean() > 200
    assert tile[y.max() + 3:, :].mean() < 30


# --------------------------------------------------------------------------------------------
# In a real browser
# --------------------------------------------------------------------------------------------


def _chromium() -> Optional[str]:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


@pytest.mark.skipif(_chromium() is None, reason="no Chromium on PATH")
def test_report_renders_in_headless_chromium(single: Path, tmp_path: Path) -> None:
    shot = tmp_path / "shot.png"
    subprocess.run([_chromium(), "--headless", "--no-sandbox", "--disable-gpu",
                    "--hide-scrollbars", f"--screenshot={shot}", "--window-size=1000,1400",
                    (single / "report.html").resolve().as_uri()],
                   check=True, timeout=120, capture_output=True)
    picture = cv2.imread(str(shot))
    assert picture is not None and picture.shape[:2] == (1400, 1000)
    # Not blank: the page's text, bars and frames (dark mask tiles, coloured bars) show.
    assert picture.std() > 30
    assert (picture.min(axis=2) < 60).mean() > 0.02  # dark pixels: text, black mask tiles
    bars = np.all(np.abs(picture.astype(int) - [178, 114, 0]) < 8, axis=2)  # #0072b2 (BGR)
    assert bars.sum() > 200
