"""Shared fixtures. Real data in ../shared/data is optional: tests using it skip when absent."""

from __future__ import annotations

import signal
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def pytest_configure(config) -> None:
    # A suite started in the background by a script (`cmd &`, nohup) inherits Ctrl-C ignored,
    # and Python then raises no KeyboardInterrupt: the tests of interrupted runs need it.
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def shared_data() -> Path:
    """Path to ../shared/data; skips the test when it is not there (as on a user's machine)."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not available at {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture
def bgsub_error(capsys):
    """``bgsub_error(argv)``: run the ``bgsub`` command line, check that it failed with exit
    status 2 and exactly one ``bgsub: error:`` line on stderr, and return that line."""
    from bgsub.cli import main

    def run(argv) -> str:
        code = main([str(a) for a in argv])
        err = capsys.readouterr().err
        assert code == 2, err
        assert err.startswith("bgsub: error:") and err.count("\n") == 1
        return err

    return run


@pytest.fixture
def own_engines():
    """Engines a test registers are removed when it ends (the built-in ones are loaded first,
    so that they stay registered whichever test imports them)."""
    from bgsub.engines import available_engines, base

    available_engines()
    before = set(base._REGISTRY)
    yield
    for name in set(base._REGISTRY) - before:
        del base._REGISTRY[name]
