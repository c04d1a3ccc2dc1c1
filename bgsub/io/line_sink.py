"""A text file written line by line: the base of the objects file and the per-frame statistics.

Lines go to a hidden partial file as they come and it takes the final name when the run ends,
also after Ctrl-C: each line is whole, so the file stays valid. A run that wrote no line leaves
no file.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Optional

from bgsub.io.outputs import OutputClaim, partial_path, write_error
from bgsub.io.sink_base import Sink


class LineSink(Sink):
    """A text file of one record (one or more whole lines) per frame.

    Parameters
    ----------
    path : Path
        The checked output path (its ``check_*_output`` has run).
    what : str
        What the file holds, as errors name it (``"the objects"``).
    header : str
        Written first (ends in a newline), or ``""``.
    overwrite : bool
        Replace an existing file.
    """

    def __init__(self, path: Path, *, what: str, header: str = "",
                 overwrite: bool = False) -> None:
        self.path = path
        self._what = what
        self._temp = partial_path(self.path)
        self._count = 0
        self._claim = OutputClaim(self._temp, output=self.path, overwrite=overwrite)
        try:
            self._file: Optional[Any] = open(self._temp, "w", encoding="utf-8", newline="")
            self._file.write(header)
        except OSError as err:
            self._claim.release()
            raise write_error(self.path, what, err) from None

    @property
    def frames_written(self) -> int:
        return self._count

    def write_record(self, text: str) -> None:
        """Add one frame's lines (``text`` ends in a newline, or is empty)."""
        try:
            self._file.write(text)
            self._file.flush()
        except OSError as err:
            raise write_error(self.path, self._what, err) from None
        self._count += 1

    def close(self) -> None:
        if self._file is None:
            return
        fh, self._file = self._file, None
        try:
            fh.close()
            if self._count:
                os.replace(self._temp, self.path)
            else:
                os.unlink(self._temp)
        except OSError as err:
            raise write_error(self.path, self._what, err) from None
        finally:
            self._claim.release()
