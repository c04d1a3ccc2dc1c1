"""The ``bgsub`` package itself: its lazily loaded public API is listed like the rest."""

from __future__ import annotations

import pydoc
import subprocess
import sys

import bgsub
from helpers import write_box_clip


def test_dir_lists_every_public_name():
    assert set(bgsub.__all__) <= set(dir(bgsub))


def test_help_shows_the_engine_api():
    text = pydoc.render_doc(bgsub, renderer=pydoc.plaintext)
    for name in ("create_engine", "register_engine", "available_engines", "Engine", "Param"):
        assert name in text


def test_dir_does_not_load_the_engine_api():
    # `import bgsub` stays cheap (the CLI's fast start and clean Ctrl-C rely on it).
    code = ("import sys, bgsub; names = dir(bgsub); print('create_engine' in names, "
            "'bgsub.engines' in sys.modules, 'numpy' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert done.stdout.split() == ["True", "False", "False"]


def _fresh(code: str) -> list:
    """What ``code`` prints, run in a fresh interpreter (nothing imported by other tests)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    return done.stdout.split()


_MOVING_STACK = "('bgsub.engines.moving', 'bgsub.motion', 'bgsub.model', 'bgsub.background')"


def test_a_classical_engine_starts_without_the_moving_camera_stack():
    # Start-up counts on short clips: a MOG2 engine imports none of grbm's code.
    code = ("import sys, bgsub; bgsub.create_engine('mog2'); "
            f"print([m for m in {_MOVING_STACK} if m in sys.modules] or 'none')")
    assert _fresh(code) == ["none"]


def test_a_classical_run_starts_without_the_moving_camera_stack(tmp_path):
    clip = write_box_clip(tmp_path / "clip.mkv", n=3)
    code = ("import sys; from bgsub.cli import main; "
            f"main(['run', {str(clip)!r}, '-m', 'mog2', '-o', {str(tmp_path / 'm')!r}, '-q']); "
            f"print([m for m in {_MOVING_STACK} if m in sys.modules] or 'none')")
    assert _fresh(code) == ["none"]


def test_every_engine_is_listed_in_one_order_however_the_first_was_loaded():
    code = ("import bgsub; bgsub.create_engine('{}'); "
            "print(*(spec.name for spec in bgsub.available_engines()))")
    first = _fresh(code.format("grbm"))
    assert first == _fresh(code.format("mog2"))
    assert first == ["mog2", "knn", "framediff", "grbm", "compensated"]
