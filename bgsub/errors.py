"""Errors a user can act on.

Every error bgsub raises on purpose is a :class:`BgsubError`; the CLI prints its message as one
line on stderr and exits with :attr:`BgsubError.exit_code` (2 for bad input or output, 1 for a
failure while processing). Anything else is a bug.
"""

from __future__ import annotations

import os
from typing import Union


class BgsubError(Exception):
    """Base class: a problem the user can fix; ``str(err)`` is the one-line message."""

    exit_code = 2


class InputError(BgsubError):
    """Missing, unreadable or inconsistent input (video, image folder, ground truth, options)."""


class OutputError(BgsubError):
    """An output that exists (without ``overwrite``) or cannot be written."""


class ModelError(BgsubError):
    """A model file that is missing, corrupt, truncated or does not fit the request."""


class ProcessingError(BgsubError):
    """A failure during processing, after the inputs were accepted."""

    exit_code = 1


def given_path(path: Union[str, "os.PathLike[str]"], *, what: str, hint: str,
               error: type = InputError) -> str:
    """``path`` as text; ``error`` when it is empty or blank, which ``Path`` would quietly read as
    the current folder (never what was meant). The message: "the {what} path is empty; give
    {hint}"."""
    text = os.fspath(path)
    if not text.strip():
        raise error(f"the {what} path is empty; give {hint}")
    return text
