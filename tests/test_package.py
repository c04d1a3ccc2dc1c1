"""The ``bgsub`` package itself: its lazily loaded public API is listed like the rest."""

from __future__ import annotations

import pydoc
import subprocess
import sys

import bgsub


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
