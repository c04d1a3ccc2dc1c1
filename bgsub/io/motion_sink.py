"""The motion sink: the camera motion of every frame as a ``(N, 3, 3) float64`` ``.npy``."""

from __future__ import annotations

import contextlib
import errno
import io
import os
from typing import Any, Optional

import numpy as np

from bgsub.io.outputs import (OutputClaim, PathLike, check_motion_output, partial_path,
                              write_error)
from bgsub.io.sink_base import Sink


class MotionSink(Sink):
    """The camera motion of every frame, as ``bgsub samples`` writes ``camera_motion.npy``: a
    ``(N, 3, 3) float64`` ``.npy`` file whose entry ``k`` maps pixel coordinates of frame
    ``k - 1`` to frame ``k`` (entry 0 the identity), NaN where the engine measured none.

    Rows go to a hidden ``.npy`` file as they come (memory stays flat); closing the sink puts
    their count in its header and gives it the final name, also after an interruption or a full
    disk (the frames so far). Plain file writes, no memory map: a full disk is an error to
    report, where writing to a memory map kills the process (SIGBUS).

    Parameters
    ----------
    path : str or path
        A ``.npy`` file.
    overwrite : bool
        Replace an existing file.
    """

    def __init__(self, path: PathLike, *, overwrite: bool = False) -> None:
        self.path = check_motion_output(path, overwrite=overwrite)
        self._temp = partial_path(self.path)
        self._count = 0
        self._claim = OutputClaim(self._temp, output=self.path, overwrite=overwrite)
        try:
            # Unbuffered: each row is on disk (or refused) when write() returns.
            self._file: Optional[Any] = open(self._temp, "wb", buffering=0)
        except OSError as err:
            self._drop()
            raise write_error(self.path, "the camera motion", err) from None
        try:
            _write_all(self._file, _npy_header(0))
        except OSError as err:
            self._file.close()
            self._file = None
            self._drop()
            raise write_error(self.path, "the camera motion", err) from None

    def _drop(self) -> None:
        """Remove the temporary file, then end the claim on its name."""
        with contextlib.suppress(OSError):
            self._temp.unlink()
        self._claim.release()

    @property
    def frames_written(self) -> int:
        return self._count

    def write(self, matrix: Optional[np.ndarray]) -> None:
        """Add the motion of the next frame: ``(3, 3)``, or None (not measured: NaN)."""
        row = np.full((3, 3), np.nan) if matrix is None else np.asarray(matrix, np.float64)
        try:
            _write_all(self._file, np.ascontiguousarray(row.reshape(3, 3), "<f8").tobytes())
        except OSError as err:  # close() drops the part of the row that got in
            raise write_error(self.path, "the camera motion", err) from None
        self._count += 1

    def close(self) -> None:
        if self._file is None:
            return
        fh, self._file = self._file, None
        renamed = False
        try:
            with fh:
                if self._count:
                    # The row count goes in the header, in place (it keeps its size, so a full
                    # disk does not refuse it); truncating drops what a failed write() left.
                    header = _npy_header(self._count)
                    fh.truncate(len(header) + self._count * _MOTION_ROW_BYTES)
                    fh.seek(0)
                    _write_all(fh, header)
            if self._count:
                os.replace(self._temp, self.path)
                renamed = True
        except OSError as err:
            raise write_error(self.path, "the camera motion", err) from None
        finally:
            if renamed:
                self._claim.release()
            else:
                self._drop()


#: Bytes of one frame's motion, a (3, 3) float64 matrix.
_MOTION_ROW_BYTES = 9 * 8


def _write_all(fh: Any, data: bytes) -> None:
    """``data`` to the unbuffered file ``fh``, which may take part of it per call."""
    view = memoryview(data)
    while view:
        written = fh.write(view)
        if not written:  # (a file system that takes nothing without saying why)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        view = view[written:]


def _npy_header(rows: int) -> bytes:
    """The ``.npy`` header of ``rows`` (3, 3) little-endian float64 matrices: 128 bytes for any
    count (numpy pads a version 1.0 header to a multiple of 64), so it is rewritten in place."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buffer, {"descr": "<f8", "fortran_order": False, "shape": (rows, 3, 3)})
    return buffer.getvalue()
