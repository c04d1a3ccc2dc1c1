"""One video file written through OpenCV under a temporary name, renamed when finished.

:class:`VideoFile` is what the mask and picture video sinks write through: it pads odd sizes
(OpenCV's FFmpeg writer drops the last column or row), notices a full disk (OpenCV's writes
then fail with only a log line) and never gives a video that does not play its final name.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
from pathlib import Path
from typing import Any, Optional, Tuple

import numpy as np

from bgsub.errors import OutputError, ProcessingError
from bgsub.io.h264 import H264Writer
from bgsub.io.outputs import OutputClaim, frames_text, partial_path, why_not_writable
from bgsub.io.sources import quiet_opencv

import cv2  # noqa: E402,I100 (bgsub.io.sources sets FFmpeg's log level before cv2 starts FFmpeg)


class VideoFile:
    """One video written under a temporary name and renamed when closed: through
    ``cv2.VideoWriter`` with the FourCC ``codec``, or through PyAV when ``codec`` is
    ``"h264"`` (:class:`bgsub.io.h264.H264Writer`; ``is_color`` must then be True).

    The temporary name is claimed (:class:`OutputClaim`) from construction to :meth:`close`,
    so a second run writing the same output is refused rather than deleting this one's file.
    """

    def __init__(self, path: Path, *, codec: str, fps: float, is_color: bool,
                 overwrite: bool = False) -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise OutputError(f"{path}: invalid frame rate {fps!r} for a video")
        self.path = path
        self.codec = codec
        self.fps = float(fps)
        self.is_color = is_color
        self.size: Optional[Tuple[int, int]] = None  # (width, height) once open
        self.frames_written = 0
        self._temp = partial_path(path)
        self._writer: Any = None  # cv2.VideoWriter or H264Writer
        self._first_failed: Optional[int] = None  # the frame OpenCV said it could not write
        #: An error has said what became of the file (its sink adds no "partial" line then).
        self.told = False
        self._claim = OutputClaim(self._temp, output=path, overwrite=overwrite)

    def open(self, width: int, height: int) -> None:
        """Start the video for ``width`` x ``height`` pictures; :class:`OutputError` (and the
        claim released) when OpenCV cannot."""
        # OpenCV's FFmpeg writer silently drops the last column or row of an odd size: open it
        # one pixel larger and pad each picture (write) so nothing is lost.
        width, height = int(width), int(height)
        size = (width + width % 2, height + height % 2)
        with quiet_opencv():
            if self.codec == "h264":
                writer: Any = H264Writer(self._temp, fps=self.fps, size=size)
            else:
                writer = cv2.VideoWriter(str(self._temp), cv2.CAP_FFMPEG,
                                         cv2.VideoWriter_fourcc(*self.codec), self.fps, size,
                                         self.is_color)
        if not writer.isOpened():
            writer.release()
            with contextlib.suppress(OSError):
                self._temp.unlink()
            why = why_not_writable(self._temp) or (
                "the disk is full; " if free_bytes(self._temp.parent) < DISK_FULL_BYTES else "")
            self._claim.release()
            maker = "PyAV" if self.codec == "h264" else "OpenCV"
            raise OutputError(f"{self.path}: {why}{maker} cannot open a {self.codec} video writer "
                              f"for {width}x{height} frames here")
        self._writer = writer
        self.size = (width, height)  # of the pictures written; the file's is padded to even

    def write(self, image: np.ndarray) -> None:
        """Add ``image``, ``(H, W)`` gray or ``(H, W, 3)`` BGR uint8 as the video was opened
        for; a write OpenCV reports failed finishes the video and raises
        :class:`ProcessingError`."""
        assert self._writer is not None, "write() before open()"
        # A failed write (full disk) would log an OpenCV warning for every frame from then on.
        with quiet_opencv():
            ok = self._writer.write(_even(image))
        if ok is not False:  # (OpenCV 4 returns None: close() finds out)
            self.frames_written += 1
            return
        # OpenCV 5 says a write failed (a full disk): stop here, not write on into nothing.
        self._first_failed = n = self.frames_written + 1
        self.close()  # raises when the file holds less than the frames before
        self.told = True
        done = (f"the video was finished with the {frames_text(n - 1)} before it" if n > 1
                else "nothing was written")
        raise ProcessingError(f"{self.path}: the video writer failed at frame {n}; {done}")

    def _problem(self) -> Optional[str]:
        """Why the finished temporary file may not hold every frame, or None when it reads."""
        if free_bytes(self.path.parent) < DISK_FULL_BYTES:
            return "the disk is full"
        if self._first_failed is not None:
            return f"the video writer failed at frame {self._first_failed}"
        if readable_frames(self._temp, 1) == 0:  # (an mp4 whose index was never written)
            return "the video writer could not finish the file"
        return None

    def close(self) -> None:
        """Finish the file and move it to its final name (removed if it holds no frame).

        When the writer failed (a full disk: OpenCV's writes fail with only a log line), the
        frames the file holds are counted: a file that does not read is removed, one cut short
        is kept; either way a :class:`ProcessingError` says which. A file that does not play
        never gets the final name. The claim on the temporary name ends here.
        """
        try:
            self._finish()
        finally:
            self._claim.release()

    def _finish(self) -> None:
        if self._writer is None:
            if self.size is None and self._claim.held:  # never opened: the empty claimed file
                with contextlib.suppress(OSError):
                    self._temp.unlink()
            return
        with quiet_opencv():
            self._writer.release()
        self._writer = None
        n = self.frames_written
        if n == 0:
            with contextlib.suppress(OSError):
                self._temp.unlink()
            return
        self.told = True  # (unless it ends well, below)
        problem = self._problem()
        held = n if problem is None else readable_frames(self._temp, n)
        if held == 0:
            with contextlib.suppress(OSError):
                self._temp.unlink()
            raise ProcessingError(f"{self.path}: {problem}; the unfinished video would not play, "
                                  f"so it was removed (it was to hold {frames_text(n)})")
        try:
            os.replace(self._temp, self.path)
        except OSError as err:
            raise OutputError(f"{self.path}: cannot move the finished video here "
                              f"({err.strerror}); it is at {self._temp}") from None
        if held < n:
            raise ProcessingError(f"{self.path}: {problem}; the video is valid but holds only "
                                  f"{held} of the {frames_text(n)} written to it")
        self.told = False


#: Less free space than this after a video is finished means its last writes failed.
DISK_FULL_BYTES = 64 * 1024


def readable_frames(path: Path, limit: int) -> int:
    """How many frames of the video at ``path`` decode, counting up to ``limit``."""
    with quiet_opencv():
        capture = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        try:
            count = 0
            while count < limit and capture.isOpened() and capture.grab():
                count += 1
            return count
        finally:
            capture.release()


def free_bytes(folder: Path) -> int:
    """Free bytes on the file system of ``folder`` (:data:`DISK_FULL_BYTES` when unknown)."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return DISK_FULL_BYTES  # unknown: assume it was fine


def _even(image: np.ndarray) -> np.ndarray:
    """``image`` with its last row / column repeated where its size is odd (see open())."""
    h, w = image.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return image
    return cv2.copyMakeBorder(image, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
