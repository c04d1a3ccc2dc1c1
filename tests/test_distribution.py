"""What a plain ``pip install .`` ships: licence, metadata, typing marker, dependencies, the
sample video, and one clear line when OpenCV cannot be imported."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bgsub.cli import main
from bgsub.samples import bundled_sample

ROOT = Path(__file__).resolve().parents[1]
# The module each declared distribution installs.
_MODULE_OF = {"opencv-python-headless": "cv2", "numpy": "numpy", "tqdm": "tqdm",
              "tomli": "tomli"}


def _pyproject() -> dict:
    tomllib = pytest.importorskip("tomllib")
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def _distribution(requirement: str) -> str:
    return requirement.split(";")[0].split(">")[0].split("=")[0].split("<")[0].strip()


def _imported_third_party() -> set:
    """Top-level modules that bgsub's code imports, other than the standard library's."""
    found = set()
    for path in (ROOT / "bgsub").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
    return {name for name in found
            if name != "bgsub" and name not in sys.stdlib_module_names}


def test_license_is_mit_and_declared():
    project = _pyproject()["project"]
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert project["license"] == {"text": "MIT"}
    assert "License :: OSI Approved :: MIT License" in project["classifiers"]
    assert "urls" not in project  # no public home to point at


def test_declared_dependencies_are_the_imported_ones():
    project = _pyproject()["project"]
    declared = {_MODULE_OF[_distribution(r)] for r in project["dependencies"]}
    # The `train` extra (imported only to retrain the natural model), the `dask` extra
    # (imported only for --scheduler) and the `h264` extra (PyAV, for H.264 picture videos).
    optional = {"skimage", "distributed", "av"}
    assert project["optional-dependencies"]["h264"] == ["av>=14"]
    assert _imported_third_party() - optional == declared


def test_typing_marker_and_sample_are_package_data():
    setuptools = _pyproject()["tool"]["setuptools"]
    assert (ROOT / "bgsub" / "py.typed").is_file()
    assert "py.typed" in setuptools["package-data"]["bgsub"]
    assert setuptools["package-dir"]["bgsub.data"] == "samples"
    assert "*.mp4" in setuptools["package-data"]["bgsub.data"]
    assert bundled_sample().read_bytes() == (ROOT / "samples" / "pan.mp4").read_bytes()


def test_samples_pan_copies_the_bundled_video(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["samples", "--pan", "-q"]) == 0
    assert (tmp_path / "samples" / "pan.mp4").read_bytes() == bundled_sample().read_bytes()
    assert main(["samples", "elsewhere", "--pan", "-q"]) == 0
    assert (tmp_path / "elsewhere" / "pan.mp4").is_file()


def test_samples_pan_refuses_an_existing_file(tmp_path, bgsub_error):
    (tmp_path / "pan.mp4").write_bytes(b"mine")
    line = bgsub_error(["samples", str(tmp_path), "--pan"])
    assert "already exists" in line and "--overwrite" in line
    assert (tmp_path / "pan.mp4").read_bytes() == b"mine"


def _run_without_opencv(tmp_path, body: str) -> subprocess.CompletedProcess:
    fake = tmp_path / "fake" / "cv2"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text(body)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(fake.parent), str(ROOT)]))
    return subprocess.run([sys.executable, "-m", "bgsub", "methods"], capture_output=True,
                          text=True, env=env, timeout=120)


@pytest.mark.parametrize("body", [
    'raise ImportError("libGL.so.1: cannot open shared object file")',
    'raise ModuleNotFoundError("No module named \'cv2\'", name="cv2")',
])
def test_broken_opencv_is_one_line(tmp_path, body):
    done = _run_without_opencv(tmp_path, body)
    assert done.returncode == 1
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("bgsub: error: cannot import cv2 (")
    assert "opencv-python-headless" in lines[0] and "Traceback" not in done.stderr
