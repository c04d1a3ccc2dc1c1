"""The Markdown documentation: sizes a reader can take in, a command reference that matches the
parsers, and Python examples that run."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from bgsub.cli import reference

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
MARKDOWN = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]

pytestmark = pytest.mark.skipif(not DOCS.is_dir(), reason="docs/ is not part of an installed package")


def _lines(path):
    return path.read_text(encoding="utf-8").splitlines()


@pytest.mark.parametrize("path", MARKDOWN, ids=lambda p: p.name)
def test_no_markdown_line_is_longer_than_200_characters(path):
    long = [n for n, line in enumerate(_lines(path), 1) if len(line) > 200]
    assert long == [], f"{path.name}: lines {long}"


def test_the_readme_is_at_most_200_lines():
    assert len(_lines(ROOT / "README.md")) <= 200


def test_benchmarks_is_at_most_250_lines():
    assert len(_lines(DOCS / "BENCHMARKS.md")) <= 250


def test_the_readme_picture_is_small_and_linked():
    picture = DOCS / "overlay.png"
    assert picture.stat().st_size < 200_000
    assert "](docs/overlay.png)" in (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_speed_chart_is_small_and_linked():
    picture = DOCS / "speed_accuracy.png"
    assert picture.stat().st_size < 200_000
    assert "](speed_accuracy.png)" in (DOCS / "BENCHMARKS.md").read_text(encoding="utf-8")


def _anchors(path):
    """The anchors GitHub gives the headings of the Markdown file ``path``."""
    headings = re.findall(r"^#+ (.*)$", path.read_text(encoding="utf-8"), re.M)
    return {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in headings}


@pytest.mark.parametrize("path", MARKDOWN, ids=lambda p: p.name)
def test_relative_links_lead_to_files_and_headings(path):
    text = path.read_text(encoding="utf-8")
    for target, anchor in re.findall(r"\]\(([^)#:]*)(?:#([^)]*))?\)", text):
        where = path.parent / target if target else path
        assert where.exists(), f"{path.name}: {target}"
        if anchor and where.suffix == ".md":
            assert anchor in _anchors(where), f"{path.name}: {target}#{anchor}"


def test_the_readme_points_at_no_shared_data():
    assert "../shared" not in (ROOT / "README.md").read_text(encoding="utf-8")


def test_the_command_reference_is_up_to_date():
    text = (DOCS / "cli.md").read_text(encoding="utf-8")
    assert reference.render(text) == text, "run python -m bgsub.cli.reference"


def test_the_command_reference_holds_every_commands_help():
    text = (DOCS / "cli.md").read_text(encoding="utf-8")
    for name in reference.parsers():
        assert f"<!-- help: {name} -->" in text


def test_a_stale_reference_is_found(tmp_path):
    stale = tmp_path / "cli.md"
    stale.write_text("# x\n<!-- help: methods -->\nold text\n<!-- end help -->\n")
    assert reference.main([str(stale), "--check"]) == 1
    assert reference.main([str(stale)]) == 0
    assert reference.main([str(stale), "--check"]) == 0
    assert "bgsub methods" in stale.read_text()


def test_the_python_api_examples_run(tmp_path, monkeypatch, own_engines):
    from bgsub.samples import bundled_sample

    (tmp_path / "samples").mkdir()
    shutil.copy(bundled_sample(), tmp_path / "samples" / "pan.mp4")
    monkeypatch.chdir(tmp_path)
    text = (DOCS / "python-api.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert len(blocks) >= 3
    namespace: dict = {}
    for block in blocks:
        exec(compile(block, "python-api.md", "exec"), namespace)  # noqa: S102 (the docs' own code)
    assert (tmp_path / "masks.mkv").exists()


def test_the_command_reference_states_how_masks_are_numbered():
    # the rule `bgsub run --help` points to
    text = " ".join((DOCS / "cli.md").read_text(encoding="utf-8").split())
    assert "Masks are numbered by position in the input" in text
    assert "starts again at `bin000001.png`" in text


def test_the_package_docstring_example_runs(tmp_path, monkeypatch):
    import textwrap

    import bgsub
    from bgsub.samples import bundled_sample

    (tmp_path / "samples").mkdir()
    shutil.copy(bundled_sample(), tmp_path / "samples" / "pan.mp4")
    monkeypatch.chdir(tmp_path)
    example = textwrap.dedent(bgsub.__doc__.split("::\n", 1)[1].split("\n\n``", 1)[0])
    namespace: dict = {}
    exec(compile(example, "bgsub.__doc__", "exec"), namespace)  # noqa: S102
    assert namespace["mask"].shape == (240, 320) and namespace["camera"].shape == (3, 3)
