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


def describe_shape(shape: tuple) -> str:
    """A frame shape as a user reads it: ``"320x240 gray"`` for (H, W) or (H, W, 1),
    ``"320x240 BGR"`` for (H, W, 3), ``"320x240 with 4 channels"`` otherwise."""
    c = shape[2] if len(shape) == 3 else 1
    kind = "gray" if c == 1 else "BGR" if c == 3 else f"with {c} channels"
    return f"{shape[1]}x{shape[0]} {kind}"
