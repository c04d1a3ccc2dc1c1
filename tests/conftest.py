"""Shared fixtures. Real data in ../shared/data is optional: tests using it skip when absent."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


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
