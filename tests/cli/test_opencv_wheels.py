"""The warning when OpenCV's GUI and headless wheels are both installed, and the documented
install path beside opencv-python."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import pytest

from bgsub.cli import main, opencv_wheels

ROOT = Path(__file__).resolve().parents[2]


def _metadata(*installed):
    """A fake ``importlib.metadata.version`` that knows only ``installed``."""
    def version(name):
        if name not in installed:
            raise importlib.metadata.PackageNotFoundError(name)
        return "4.10.0"
    return version


@pytest.mark.parametrize("installed", [
    ("opencv-python-headless",), ("opencv-python",), ("opencv-contrib-python",), (),
])
def test_one_opencv_wheel_is_no_clash(installed):
    assert opencv_wheels.clash_message(_metadata(*installed)) is None


def test_gui_and_headless_wheels_together_get_the_fix():
    message = opencv_wheels.clash_message(_metadata("opencv-python", "opencv-python-headless"))
    assert "opencv-python and opencv-python-headless are installed together" in message
    assert "pip uninstall -y opencv-python opencv-python-headless; pip install opencv-python" \
        in message


def test_the_contrib_wheels_clash_too():
    message = opencv_wheels.clash_message(_metadata("opencv-contrib-python",
                                                    "opencv-contrib-python-headless"))
    assert "pip install opencv-contrib-python " in message


def test_the_command_warns_once_per_process(monkeypatch, capsys):
    monkeypatch.setattr(opencv_wheels, "_warned", False)
    monkeypatch.setattr(importlib.metadata, "version",
                        _metadata("opencv-python", "opencv-python-headless"))
    for _ in range(2):
        main(["methods"])
    err = capsys.readouterr().err
    assert err.count("bgsub: warning: opencv-python and opencv-python-headless") == 1


def test_the_documented_requirements_are_the_dependencies_but_opencv():
    tomllib = pytest.importorskip("tomllib")
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    listed = [line.strip() for line in (ROOT / "requirements-without-opencv.txt").read_text()
              .splitlines() if line.strip() and not line.startswith("#")]
    without = [r for r in declared if not r.startswith("opencv")]
    assert [r.replace('"', "'") for r in listed] == [r.replace('"', "'") for r in without]
    assert len(without) == len(declared) - 1
    readme = (ROOT / "README.md").read_text()
    assert "pip install --no-deps -e . && pip install -r requirements-without-opencv.txt" \
        in readme
