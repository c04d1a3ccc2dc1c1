"""The compare report leads with the answer: methods ranked by F, the best marked, grbm
highlighted, the settings as a table, F explained; rendered in headless Chromium when it is
installed."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from bgsub.evaluation.compare import compare_methods
from bgsub.evaluation.compare_report import ComparisonReport, ComparisonRow
from bgsub.evaluation.html_report import METRICS_SENTENCE, render_html
from bgsub.evaluation.metrics import Metrics
from bgsub.evaluation.report_frames import THUMB_WIDTH
from helpers import write_input_sequence
from test_html_report import Page

CHROMIUM = Path("/usr/bin/chromium")


def _row(method: str, f: float, *, name: str = "seq", level: str = "sequence") -> ComparisonRow:
    metrics = Metrics(recall=f, specificity=1.0, fpr=0.0, fnr=1 - f, pwc=0.0, precision=f,
                      f_measure=f)
    return ComparisonRow(level=level, name=name, family="fam", method=method, frames=10,
                         seconds=0.5, eval_frames=10, metrics=metrics)


def _report(**scores: float) -> ComparisonReport:
    return ComparisonReport(input="seq", methods=list(scores),
                            rows=[_row(m, f) for m, f in scores.items()])


def test_methods_are_ranked_by_f_best_first_and_unscored_last():
    report = _report(mog2=0.3, knn=math.nan, grbm=0.9, framediff=0.5)
    assert [row.method for row in report.ranking()] == ["grbm", "framediff", "mog2", "knn"]


def test_a_dataset_is_ranked_by_its_overall_means():
    report = ComparisonReport(input="data", methods=["grbm", "mog2"],
                              rows=[_row("grbm", 0.2, name="a"), _row("mog2", 0.9, name="a"),
                                    _row("grbm", 0.9, name="b"), _row("mog2", 0.1, name="b")],
                              overall=[_row("grbm", 0.55, name="overall", level="overall"),
                                       _row("mog2", 0.5, name="overall", level="overall")])
    assert [(row.method, row.level) for row in report.ranking()] == [("grbm", "overall"),
                                                                      ("mog2", "overall")]


def test_several_inputs_without_means_are_not_ranked():
    report = ComparisonReport(input="x", methods=["mog2"],
                              rows=[_row("mog2", 0.5, name="a"), _row("mog2", 0.4, name="b")])
    assert report.ranking() == []
    assert "ranked by F" not in report.to_text()


def test_the_page_leads_with_the_ranking_and_marks_the_best():
    text = render_html(_report(mog2=0.3, grbm=0.9, knn=0.5))
    page = Page(text)
    assert [row[1] for row in page.tables["answer"]] == ["grbm best", "knn", "mog2"]
    assert page.row_classes["answer"][0] == "best ours"
    assert text.index('class="answer"') < text.index("<h2>Charts</h2>")
    assert METRICS_SENTENCE in text


def test_grbm_is_highlighted_when_another_method_is_best():
    page = Page(render_html(_report(mog2=0.95, grbm=0.9)))
    assert page.row_classes["answer"] == ["best", "ours"]
    assert page.row_classes["metrics"] == ["sequence", "sequence ours"]


def test_the_settings_are_a_readable_table():
    report = _report(mog2=0.3)
    report.settings = {"start": 0, "stop": None, "skip_first": True,
                       "params": {"mog2": {"history": 200}, "knn": {}}}
    page = Page(render_html(report))
    assert page.tables["settings"] == [["start", "0"], ["stop", "-"], ["skip first", "yes"],
                                       ["params", "mog2: history=200"]]
    text = report.to_text()
    assert "settings: start: 0; stop: -; skip first: yes; params: mog2: history=200" in text
    assert "{" not in text


def test_the_text_report_leads_with_the_ranking():
    lines = _report(mog2=0.3, grbm=0.9).to_text().splitlines()
    assert lines[2] == "ranked by F: grbm 0.900 (best), mog2 0.300"


def test_every_thumbnail_is_shown_at_one_width():
    text = render_html(_report(mog2=0.3))
    assert f"figure img {{ width: {THUMB_WIDTH}px; height: auto; }}" in text


@pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Chromium (/usr/bin/chromium)")
def test_the_report_renders_in_chromium(tmp_path):
    sequence = write_input_sequence(tmp_path / "seq")
    out = tmp_path / "out"
    compare_methods(sequence, methods=["framediff", "mog2"], report_dir=out, masks="none",
                    video_codec="mp4v")
    shot = tmp_path / "page.png"
    subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu",
                    f"--screenshot={shot}", "--window-size=1200,1600",
                    (out / "report.html").as_uri()], capture_output=True, timeout=120)
    picture = cv2.imread(str(shot))
    assert picture is not None and picture.shape[:2] == (1600, 1200)
    # The page drew something: text, tables and pictures, not a blank or error page.
    assert len(np.unique(picture.reshape(-1, 3), axis=0)) > 50
