"""Sinks: where masks and pictures go, and the loop that feeds an engine's masks into them.

* :func:`open_mask_sink` -- foreground masks, ``(H, W) uint8`` 0/255, as a lossless video
  (``.mkv`` / ``.avi``: FFV1, so 0 and 255 come back exactly) or a CDnet-style folder of
  ``binNNNNNN.png`` (numbered from the input frame, so ``bin000123.png`` is the mask of
  ``in000123.jpg``); ``.mp4`` works too but is lossy (a warning says so).
* :class:`VideoSink` -- colour pictures (flow visualisation, side-by-side comparisons) as a video
  common players open: ``.mp4`` (mp4v), ``.avi`` (MJPG) or ``.mkv`` (FFV1). This OpenCV build
  cannot encode H.264, so mp4v in ``.mp4`` is the most widely playable choice.
* :class:`VisSink` -- the input with its mask overlaid (red tint and outline) beside the mask.
* :func:`process` -- stream frames through an engine into these sinks (what ``bgsub run`` does).

Every sink is a context manager that writes under a temporary name in the output's folder and
renames it to the final name when closed. Closing also happens when the ``with`` block ends by
an exception or Ctrl-C, so a partial video is still a valid, playable file; the sink then says on
stderr that the output is partial and how many frames it holds. An existing output is refused
(:class:`bgsub.errors.OutputError`) unless ``overwrite=True``. A full disk stops the run with a
:class:`bgsub.errors.ProcessingError` naming the output; a video it left unplayable is removed,
never given its final name.
"""

from __future__ import annotations

import contextlib
import errno
import io
import math
import numbers
import os
import re
import shutil
import signal
import sys
import threading
import time
import uuid
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from abc import ABC, abstractmethod
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Tuple, Union

import numpy as np

from bgsub.errors import BgsubError, OutputError, ProcessingError, given_path
from bgsub.io.loop import RunStats, hold_interrupts  # noqa: F401 (re-exported)
from bgsub.io.sources import quiet_opencv
from bgsub.io.writers import process  # noqa: F401 (re-exported)

import cv2  # noqa: E402,I100 (bgsub.io.sources sets FFmpeg's log level before cv2 starts FFmpeg)

PathLike = Union[str, "os.PathLike[str]"]

#: Mask video codecs by extension: FFV1 is lossless, mp4v is not (masks come back blurred).
MASK_VIDEO_CODECS = {".mkv": "FFV1", ".avi": "FFV1", ".mp4": "mp4v", ".mov": "mp4v"}

#: Picture video codecs by extension, chosen to play in common players.
PICTURE_VIDEO_CODECS = {".mp4": "mp4v", ".mov": "mp4v", ".avi": "MJPG", ".mkv": "FFV1"}

_LOSSY_CODECS = {"mp4v", "MJPG"}

_MASK_NAME = re.compile(r"bin\d{6}\.png")
_PARTIAL_MASK_NAME = re.compile(r"\.bin\d{6}\.partial\.png")


def _say(message: str) -> None:
    print(f"bgsub: {message}", file=sys.stderr, flush=True)


def _reason(exc_type: Optional[type]) -> str:
    return "interrupted" if exc_type is not None and issubclass(exc_type, KeyboardInterrupt) \
        else "stopped by an error"


def is_video_path(path: PathLike) -> bool:
    """True when ``path``'s extension makes :func:`open_mask_sink` write a video."""
    return Path(path).suffix.lower() in MASK_VIDEO_CODECS


def _write_error(path: Path, what: str, err: OSError) -> BgsubError:
    """The error for a failed write of ``what`` to ``path``: a full disk (or quota) is a
    :class:`ProcessingError`, as for videos; any other cause an :class:`OutputError`."""
    if err.errno == errno.ENOSPC:
        return ProcessingError(f"{path}: the disk is full, cannot write {what}")
    if err.errno == getattr(errno, "EDQUOT", None):
        return ProcessingError(f"{path}: the disk quota is exceeded, cannot write {what}")
    return OutputError(f"{path}: cannot write {what} ({err.strerror or err})")


def _partial_path(path: Path) -> Path:
    # Same folder (so the final rename is atomic) and same extension (OpenCV picks the container
    # from it); the leading dot hides it from most file listings while it is being written.
    return path.with_name(f".{path.stem}.partial{path.suffix}")


def _why_not_writable(path: Path) -> str:
    """``"cannot create a file there (reason); "`` when the system refuses a new file at
    ``path`` (which must not exist), else ``""``: a writer library's failure names no cause,
    and a folder can refuse files although it looks writable (``/proc``)."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as err:
        return f"cannot create a file there ({err.strerror or err}); "
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(path)
    return ""


def _output_path(path: PathLike) -> Path:
    return Path(given_path(path, what="output", hint="a file or folder name", error=OutputError))


def _check_writable_folder(folder: Path, output: Path) -> None:
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if existing.exists() and not existing.is_dir():  # afile/sub/m.mkv: name the file
        raise OutputError(f"{output}: {existing} is not a folder")
    if not folder.is_dir():
        raise OutputError(f"{output}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        read_only = getattr(os, "ST_RDONLY", None)  # POSIX only
        reason = ("on a read-only file system"
                  if read_only is not None and os.statvfs(folder).f_flag & read_only
                  else "not writable (permission denied)")
        raise OutputError(f"{output}: cannot write there, the folder {folder} is {reason}")


def check_file_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that a file (a report, a model) can be written at ``path``; return it as a
    :class:`Path`. :class:`OutputError` when it is a folder, exists (without ``overwrite``),
    or its folder is missing or read-only. Nothing is written."""
    output = _output_path(path)
    if output.is_dir():
        raise OutputError(f"{output}: is a folder; give a file name")
    if output.exists() and not overwrite:
        raise OutputError(f"{output}: already exists (--overwrite, or overwrite=True, replaces "
                          "it)")
    _check_writable_folder(output.parent, output)  # Path("x").parent is Path(".")
    return output


def write_atomically(path: Path, data: bytes, *, what: str) -> None:
    """Write ``data`` under a temporary name in the same folder, then rename it to ``path``.

    A failed write (disk full, read-only folder) never leaves a partial file, nor destroys the
    file it was to replace; the error names the system's reason. The file gets the usual
    permissions (``0o666`` less the umask), not the ``0o600`` of ``tempfile.mkstemp``.
    """
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.part")
    try:
        # O_EXCL: a fresh file of our own; mode 0o666 is reduced by the umask, as for open().
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as err:
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None


def names_a_folder(path: PathLike) -> bool:
    """True when ``path`` is an existing folder or ends in a path separator (``out.v2/``):
    :class:`Path` drops a trailing slash, so look at the text as given."""
    text = os.fspath(path)
    return Path(text).is_dir() or text.endswith(tuple(filter(None, (os.sep, os.altsep))))


def check_video_output(path: PathLike, *, overwrite: bool = False,
                       codecs: Optional[dict] = None) -> Path:
    """Check that a video can be written at ``path``; return it as a :class:`Path`.

    Raises :class:`OutputError` when it exists (without ``overwrite``), is a folder, has an
    extension with no codec in ``codecs`` (default: :data:`PICTURE_VIDEO_CODECS`), or its folder
    is missing or read-only. Nothing is written.
    """
    codecs = PICTURE_VIDEO_CODECS if codecs is None else codecs
    output = _output_path(path)
    if output.suffix.lower() not in codecs:
        known = ", ".join(sorted(codecs))
        raise OutputError(f"{output}: cannot write a video with this extension (use {known})")
    if output.is_dir():
        raise OutputError(f"{output}: is a folder, not a video file")
    return check_file_output(output, overwrite=overwrite)


def check_mask_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that :func:`open_mask_sink` can write masks at ``path``; nothing is written.

    A name with a mask video extension (:data:`MASK_VIDEO_CODECS`) is a video; a name without an
    extension, an existing folder, or a name ending in a slash is a folder of PNGs; any other
    extension is refused. A mask folder "exists" when it already holds ``binNNNNNN.png`` masks;
    an empty or unrelated folder is fine. Raises :class:`OutputError` otherwise (see
    :func:`check_video_output`).
    """
    output = _output_path(path)
    suffix = output.suffix.lower()
    if suffix in MASK_VIDEO_CODECS:
        return check_video_output(output, overwrite=overwrite, codecs=MASK_VIDEO_CODECS)
    if suffix and not names_a_folder(path):
        # masks.txt, mask.png, masks.webm: a file was meant, and a folder of that name would
        # surprise. A dotted folder name is still fine when it exists or ends in a slash.
        raise OutputError(
            f"{output}: cannot write masks to a {suffix} file; give a video ending in .mkv or "
            ".avi (lossless) or .mp4 or .mov (lossy), or a folder for binNNNNNN.png masks: a "
            f"name without an extension, or one ending in a slash ({output.name}/)"
        )
    if output.exists() and not output.is_dir():
        raise OutputError(f"{output}: is a file, not a folder for masks")
    if output.is_dir():
        if not overwrite and any(_MASK_NAME.fullmatch(p.name) for p in output.iterdir()):
            raise OutputError(f"{output}: already holds masks (binNNNNNN.png); use --overwrite "
                              "to replace them")
        _check_writable_folder(output, output)
    else:
        ancestor = output.parent
        while not ancestor.exists() and ancestor != ancestor.parent:
            ancestor = ancestor.parent
        _check_writable_folder(ancestor, output)
    return output


# --------------------------------------------------------------------------------------------
# Video files
# --------------------------------------------------------------------------------------------


class _VideoFile:
    """One ``cv2.VideoWriter`` written under a temporary name and renamed when closed."""

    def __init__(self, path: Path, *, codec: str, fps: float, is_color: bool) -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise OutputError(f"{path}: invalid frame rate {fps!r} for a video")
        self.path = path
        self.codec = codec
        self.fps = float(fps)
        self.is_color = is_color
        self.size: Optional[Tuple[int, int]] = None  # (width, height) once open
        self.frames_written = 0
        self._temp = _partial_path(path)
        self._writer: Optional[cv2.VideoWriter] = None
        self._first_failed: Optional[int] = None  # the frame OpenCV said it could not write
        #: An error has said what became of the file (its sink adds no "partial" line then).
        self.told = False

    def open(self, width: int, height: int) -> None:
        try:
            if self._temp.exists():  # left by a run that was killed outright
                self._temp.unlink()
        except OSError as err:
            raise OutputError(f"{self.path}: cannot replace {self._temp} ({err.strerror})") \
                from None
        # OpenCV's FFmpeg writer silently drops the last column or row of an odd size: open it
        # one pixel larger and pad each picture (write) so nothing is lost.
        width, height = int(width), int(height)
        with quiet_opencv():
            writer = cv2.VideoWriter(str(self._temp), cv2.CAP_FFMPEG,
                                     cv2.VideoWriter_fourcc(*self.codec), self.fps,
                                     (width + width % 2, height + height % 2), self.is_color)
        if not writer.isOpened():
            writer.release()
            with contextlib.suppress(OSError):
                self._temp.unlink()
            why = _why_not_writable(self._temp) or (
                "the disk is full; " if _free_bytes(self._temp.parent) < _DISK_FULL_BYTES else "")
            raise OutputError(f"{self.path}: {why}OpenCV cannot open a {self.codec} video writer "
                              f"for {width}x{height} frames here")
        self._writer = writer
        self.size = (width, height)  # of the pictures written; the file's is padded to even

    def write(self, image: np.ndarray) -> None:
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
        done = (f"the video was finished with the {_frames(n - 1)} before it" if n > 1
                else "nothing was written")
        raise ProcessingError(f"{self.path}: the video writer failed at frame {n}; {done}")

    def _problem(self) -> Optional[str]:
        """Why the finished temporary file may not hold every frame, or None when it reads."""
        if _free_bytes(self.path.parent) < _DISK_FULL_BYTES:
            return "the disk is full"
        if self._first_failed is not None:
            return f"the video writer failed at frame {self._first_failed}"
        if _readable_frames(self._temp, 1) == 0:  # (an mp4 whose index was never written)
            return "the video writer could not finish the file"
        return None

    def close(self) -> None:
        """Finish the file and move it to its final name (removed if it holds no frame).

        When the writer failed (a full disk: OpenCV's writes fail with only a log line), the
        frames the file holds are counted: a file that does not read is removed, one cut short
        is kept; either way a :class:`ProcessingError` says which. A file that does not play
        never gets the final name.
        """
        if self._writer is None:
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
        held = n if problem is None else _readable_frames(self._temp, n)
        if held == 0:
            with contextlib.suppress(OSError):
                self._temp.unlink()
            raise ProcessingError(f"{self.path}: {problem}; the unfinished video would not play, "
                                  f"so it was removed (it was to hold {_frames(n)})")
        try:
            os.replace(self._temp, self.path)
        except OSError as err:
            raise OutputError(f"{self.path}: cannot move the finished video here "
                              f"({err.strerror}); it is at {self._temp}") from None
        if held < n:
            raise ProcessingError(f"{self.path}: {problem}; the video is valid but holds only "
                                  f"{held} of the {_frames(n)} written to it")
        self.told = False


#: Less free space than this after a video is finished means its last writes failed.
_DISK_FULL_BYTES = 64 * 1024


def _frames(n: int) -> str:
    return f"{n} frame{'s' * (n != 1)}"


def _readable_frames(path: Path, limit: int) -> int:
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


def _free_bytes(folder: Path) -> int:
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return _DISK_FULL_BYTES  # unknown: assume it was fine


def _even(image: np.ndarray) -> np.ndarray:
    """``image`` with its last row / column repeated where its size is odd (see open())."""
    h, w = image.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return image
    return cv2.copyMakeBorder(image, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)


def _check_image(image: np.ndarray, *, ndims: Tuple[int, ...], what: str) -> None:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in ndims \
            or (image.ndim == 3 and image.shape[2] != 3):
        shape = getattr(image, "shape", None)
        dtype = getattr(image, "dtype", type(image).__name__)
        wanted = " or ".join(_SHAPES[n] for n in ndims)
        raise ValueError(f"{what} must be a uint8 array of shape {wanted}, got shape {shape} "
                         f"dtype {dtype}")


_SHAPES = {2: "(H, W)", 3: "(H, W, 3)"}


def _check_size(path: Path, width: Any, height: Any, what: str) -> None:
    """:class:`OutputError` unless ``width`` and ``height`` are whole numbers of at least 1."""
    for value in (width, height):
        # (A whole float is fine: cv2.VideoCapture.get(CAP_PROP_FRAME_WIDTH) gives 320.0.)
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and math.isfinite(value) and float(value).is_integer() and value >= 1):
            raise OutputError(f"{path}: cannot write {what} of {width}x{height} pixels; "
                              "width and height must be whole numbers of at least 1")


def _binary_mask(mask: Any) -> np.ndarray:
    """``mask`` as ``(H, W) uint8`` 0/255 (a bool mask: True -> 255); ``ValueError`` for any
    other dtype, shape or values (a 0/1 mask would read as all background)."""
    if isinstance(mask, np.ndarray) and mask.dtype == bool:
        mask = mask.view(np.uint8) * np.uint8(255)
    _check_image(mask, ndims=(2,), what="a mask")
    if np.count_nonzero(mask) != np.count_nonzero(mask == 255):
        found = np.unique(mask[(mask != 0) & (mask != 255)])[:3].tolist()
        raise ValueError(f"a mask must hold only 0 (background) and 255 (foreground), not "
                         f"{', '.join(map(str, found))}; multiply a 0/1 mask by 255 or give a "
                         "bool mask")
    return mask


class _Sink(ABC):
    """What every sink shares: a context manager that finishes its output once, and says on
    stderr what an output holds when the run stopped early."""

    path: Path
    _finished = False

    @property
    @abstractmethod
    def frames_written(self) -> int:
        """Frames written so far."""

    @abstractmethod
    def close(self) -> None:
        """Finish the output (also after an interruption: the partial output stays valid)."""

    def finish(self, *, error: Optional[BaseException] = None, complete: bool = False) -> None:
        """Finish the output once and, when ``error`` stopped the run, say what it holds.

        Parameters
        ----------
        error : exception, optional
            What stopped the run (``KeyboardInterrupt`` for Ctrl-C or a signal), or None when
            it ended normally.
        complete : bool
            Every frame of the run is in this output (the frames ran out): an error after that
            (another output failing as it is finished) does not make it partial.

        A failure to finish the output raises when ``error`` is None; otherwise the run's own
        error is the one to report, and this output's failure gets its line on stderr. Later
        calls (and leaving a ``with`` block after this) do nothing.
        """
        if self._finished:
            return
        self._finished = True
        try:
            self.close()
        except BgsubError as err:
            if error is None:
                raise
            _say(f"error: {err}")
            return
        interrupted = isinstance(error, KeyboardInterrupt)
        # A sink that never got a frame because opening a later output failed stays silent: the
        # error itself is the one line the user needs.
        if error is not None and (self.frames_written or interrupted) and not self._told():
            _say(self._partial_message(_reason(type(error)), complete=complete))

    def _told(self) -> bool:
        """Whether an error has already said what became of the output."""
        return False

    def _partial_message(self, reason: str, *, complete: bool) -> str:
        n = self.frames_written
        if n == 0:
            return f"{self.path}: not written ({reason} before the first frame)"
        if complete:
            run = "the run was interrupted" if reason == "interrupted" else f"the run {reason}"
            return f"{self.path} is complete: {run} after writing all {_frames(n)}"
        return f"{self.path} is partial ({reason}) but valid: it holds {_frames(n)}"

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.finish(error=exc)


# --------------------------------------------------------------------------------------------
# Masks
# --------------------------------------------------------------------------------------------


class MaskSink(_Sink):
    """Where ``(H, W) uint8`` 0/255 masks go; built by :func:`open_mask_sink`.

    Attributes
    ----------
    path : Path
        The final output (video file or folder).
    width, height : int
        The mask size every :meth:`write` must have.
    frames_written : int
        Masks written so far.
    """

    def __init__(self, path: Path, *, width: int, height: int) -> None:
        _check_size(path, width, height, "masks")
        self.path = path
        self.width = int(width)
        self.height = int(height)

    def write(self, mask: np.ndarray, index: Optional[int] = None) -> None:
        """Write the next mask.

        Parameters
        ----------
        mask : (H, W) uint8 or bool array
            0 = background, 255 = foreground (bool: True = foreground); ``H, W`` = this sink's
            ``height, width``.
        index : int, optional
            0-based index of the input frame the mask belongs to; it names the PNG
            (``bin{index + 1:06d}.png``). Videos ignore it (frames follow the order written).
            ``None`` numbers masks 1, 2, ... in the order written.

        Raises
        ------
        ValueError
            A mask of another dtype or size, or with values other than 0 and 255.
        """
        mask = _binary_mask(mask)
        if mask.shape != (self.height, self.width):
            raise ValueError(f"a mask must be {self.width}x{self.height} for {self.path}, got "
                             f"{mask.shape[1]}x{mask.shape[0]}")
        self._write(mask, index)

    @abstractmethod
    def _write(self, mask: np.ndarray, index: Optional[int]) -> None:
        """Write one validated mask."""


class MaskVideoSink(MaskSink):
    """Masks as a gray video: lossless FFV1 in ``.mkv``/``.avi``, lossy mp4v in ``.mp4``."""

    def __init__(self, path: Path, *, width: int, height: int, fps: float) -> None:
        super().__init__(path, width=width, height=height)
        if width % 2 or height % 2:
            # A padded or cropped mask would no longer match its frame or its ground truth.
            raise OutputError(
                f"{path}: {width}x{height} masks cannot be written to a video (OpenCV's video "
                f"writer drops the last column or row of an odd size); write them as a folder "
                f"of PNGs or resize the input to an even size (--width {width - width % 2})")
        codec = MASK_VIDEO_CODECS[path.suffix.lower()]
        self._video = _VideoFile(path, codec=codec, fps=fps, is_color=False)
        self._video.open(width, height)
        if codec in _LOSSY_CODECS:
            _say(f"warning: {path}: {codec} is lossy, mask values will not stay exactly 0/255; "
                 "use .mkv or .avi (lossless FFV1) or a folder of PNGs for exact masks")

    @property
    def frames_written(self) -> int:
        return self._video.frames_written

    def _write(self, mask: np.ndarray, index: Optional[int]) -> None:
        self._video.write(mask)

    def close(self) -> None:
        self._video.close()

    def _told(self) -> bool:
        return self._video.told


class MaskFolderSink(MaskSink):
    """Masks as CDnet-style ``binNNNNNN.png`` files in a folder (created if missing).

    Each PNG is written under a hidden temporary name and renamed, so every ``bin*.png`` in the
    folder is complete at any moment, including after Ctrl-C. Writing file by file rather than to
    a temporary folder renamed at the end lets the output be an existing folder (say, one that
    holds other results) without moving or deleting anything but its old masks.
    """

    def __init__(self, path: Path, *, width: int, height: int) -> None:
        super().__init__(path, width=width, height=height)
        try:
            path.mkdir(parents=True, exist_ok=True)
            for old in path.iterdir():  # check_mask_output refused these unless overwrite=True
                if _MASK_NAME.fullmatch(old.name) or _PARTIAL_MASK_NAME.fullmatch(old.name):
                    old.unlink()
        except OSError as err:
            raise OutputError(f"{path}: cannot prepare the mask folder ({err.strerror})") from None
        self._count = 0
        self._last: Optional[str] = None

    @property
    def frames_written(self) -> int:
        return self._count

    def _write(self, mask: np.ndarray, index: Optional[int]) -> None:
        number = (self._count if index is None else int(index)) + 1
        name = f"bin{number:06d}.png"
        temp = self.path / f".bin{number:06d}.partial.png"
        ok, png = cv2.imencode(".png", mask)
        if not ok:
            raise OutputError(f"{self.path / name}: OpenCV cannot encode the mask as a PNG")
        # Python's file writes, not cv2.imwrite: imwrite says True even when nothing reached the
        # disk (a full disk left empty PNGs), a write or close here raises the system's error.
        try:
            try:
                with open(temp, "wb") as fh:
                    fh.write(png.tobytes())
                os.replace(temp, self.path / name)
            except BaseException:
                with contextlib.suppress(OSError):
                    temp.unlink()
                raise
        except OSError as err:
            raise _write_error(self.path / name, "the mask", err) from None
        self._count += 1
        self._last = name

    def close(self) -> None:
        pass  # every PNG is already complete

    def _partial_message(self, reason: str, *, complete: bool) -> str:
        if self._count == 0 or complete:
            return super()._partial_message(reason, complete=complete)
        s = "s" * (self._count != 1)
        return f"{self.path} is partial ({reason}) but valid: it holds {self._count} mask{s}, " \
               f"the last {self._last}"


def open_mask_sink(path: PathLike, *, width: int, height: int, fps: float,
                   overwrite: bool = False) -> MaskSink:
    """Open where masks of ``width`` x ``height`` go.

    Parameters
    ----------
    path : str or path
        ``.mkv`` / ``.avi``: a lossless FFV1 gray video; ``.mp4`` / ``.mov``: a lossy mp4v video
        (warns); no extension (or an existing folder, or a trailing slash): a folder of
        ``binNNNNNN.png`` (created if missing). Any other extension is refused.
    width, height : int
        Size of the masks to be written.
    fps : float
        Frame rate of a mask video (ignored for folders).
    overwrite : bool
        Replace an existing video, or the ``binNNNNNN.png`` masks of an existing folder.

    Returns
    -------
    MaskSink
        A context manager; ``write(mask (H, W) uint8, index)`` per frame.

    Raises
    ------
    OutputError
        The output exists (without ``overwrite``), has an extension that is no mask video, its
        folder is missing or read-only, ``width`` or ``height`` is not a whole number of at
        least 1, or the video writer cannot be opened.
    """
    output = check_mask_output(path, overwrite=overwrite)
    if output.suffix.lower() in MASK_VIDEO_CODECS:
        return MaskVideoSink(output, width=width, height=height, fps=fps)
    return MaskFolderSink(output, width=width, height=height)


# --------------------------------------------------------------------------------------------
# Pictures
# --------------------------------------------------------------------------------------------


class VideoSink(_Sink):
    """A colour video of pictures: ``.mp4`` (mp4v), ``.avi`` (MJPG) or ``.mkv`` (FFV1).

    Parameters
    ----------
    path : str or path
        The video to write.
    fps : float
        Its frame rate.
    width, height : int, optional
        Picture size; when not given, the first picture written fixes it.
    overwrite : bool
        Replace an existing file.
    """

    def __init__(self, path: PathLike, *, fps: float, width: Optional[int] = None,
                 height: Optional[int] = None, overwrite: bool = False) -> None:
        self.path = check_video_output(path, overwrite=overwrite)
        if width is not None or height is not None:
            _check_size(self.path, width, height, "pictures")
        codec = PICTURE_VIDEO_CODECS[self.path.suffix.lower()]
        self._video = _VideoFile(self.path, codec=codec, fps=fps, is_color=True)
        self._blanks = 0  # pictures skipped before the size was known
        if width is not None and height is not None:
            self._video.open(width, height)

    @property
    def frames_written(self) -> int:
        return self._video.frames_written

    def write(self, image: np.ndarray) -> None:
        """Write the next picture, ``(H, W, 3)`` BGR or ``(H, W)`` gray uint8, all the same size."""
        _check_image(image, ndims=(2, 3), what="a picture")
        if image.ndim == 2:
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        height, width = image.shape[:2]
        if self._video.size is None:
            self._video.open(width, height)
            for _ in range(self._blanks):
                self._video.write(np.zeros_like(image))
            self._blanks = 0
        elif self._video.size != (width, height):
            w, h = self._video.size
            raise ValueError(f"pictures for {self.path} must all be {w}x{h}, got {width}x{height}")
        self._video.write(image)

    def write_blank(self) -> None:
        """A frame with no picture: written black, so the video stays in step with the input."""
        if self._video.size is None:
            self._blanks += 1
        else:
            w, h = self._video.size
            self._video.write(np.zeros((h, w, 3), np.uint8))

    def close(self) -> None:
        if self._video.size is None and self._blanks:
            _say(f"{self.path}: not written, there was no picture to write")
            self._blanks = 0
        self._video.close()

    def _told(self) -> bool:
        return self._video.told


def render_overlay(frame: np.ndarray, mask: np.ndarray, *,
                   color: Tuple[int, int, int] = (0, 0, 255), alpha: float = 0.45) -> np.ndarray:
    """The frame with its mask tinted and outlined, beside the mask.

    Parameters
    ----------
    frame : (H, W, 3) BGR or (H, W) gray uint8 array
    mask : (H, W) uint8 array, 0 = background, nonzero = foreground
    color : BGR colour of the tint and outline (default red)
    alpha : strength of the tint

    Returns
    -------
    (H, 2 * W, 3) uint8 array: overlay on the left, the mask on the right.
    """
    if frame.ndim == 2:
        frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    foreground = (mask > 0).astype(np.uint8)
    tinted = cv2.addWeighted(frame, 1.0 - alpha, np.full_like(frame, color), alpha, 0.0)
    overlay = frame.copy()
    cv2.copyTo(tinted, foreground, overlay)  # tint only under the mask (10x faster than np.where)
    contours, _ = cv2.findContours(foreground, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(overlay, contours, -1, color, 1, cv2.LINE_AA)
    return np.hstack([overlay, cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR)])


class VisSink(_Sink):
    """A video of each input frame with its mask overlaid, beside the mask (``2W x H``).

    Parameters
    ----------
    path : str or path
        ``.mp4`` (mp4v), ``.avi`` (MJPG) or ``.mkv`` (FFV1).
    width, height : int
        Size of the input frames (the video is ``2 * width`` wide).
    fps : float
        Frame rate.
    overwrite : bool
        Replace an existing file.
    """

    def __init__(self, path: PathLike, *, width: int, height: int, fps: float,
                 overwrite: bool = False) -> None:
        _check_size(_output_path(path), width, height, "frames")
        self._video = VideoSink(path, fps=fps, width=2 * int(width), height=int(height),
                                overwrite=overwrite)
        self.path = self._video.path
        self.width, self.height = int(width), int(height)

    @property
    def frames_written(self) -> int:
        return self._video.frames_written

    def write(self, frame: np.ndarray, mask: np.ndarray) -> None:
        """Write ``frame`` ((H, W, 3) BGR or (H, W) gray uint8) with its ``mask`` ((H, W)
        uint8 0/255, or bool), both of this sink's ``height, width``; ``ValueError`` otherwise."""
        _check_image(frame, ndims=(2, 3), what="a frame")
        mask = _binary_mask(mask)
        if frame.shape[:2] != (self.height, self.width) or mask.shape != frame.shape[:2]:
            raise ValueError(f"a frame and its mask must both be {self.width}x{self.height} for "
                             f"{self.path}, got {frame.shape[1]}x{frame.shape[0]} and "
                             f"{mask.shape[1]}x{mask.shape[0]}")
        self._video.write(render_overlay(frame, mask))

    def close(self) -> None:
        self._video.close()

    def _told(self) -> bool:
        return self._video._told()


class MotionSink(_Sink):
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
        self._temp = _partial_path(self.path)
        self._count = 0
        try:
            # Unbuffered: each row is on disk (or refused) when write() returns.
            self._file: Optional[Any] = open(self._temp, "wb", buffering=0)
        except OSError as err:
            raise _write_error(self.path, "the camera motion", err) from None
        try:
            _write_all(self._file, _npy_header(0))
        except OSError as err:
            self._file.close()
            self._file = None
            with contextlib.suppress(OSError):
                self._temp.unlink()
            raise _write_error(self.path, "the camera motion", err) from None

    @property
    def frames_written(self) -> int:
        return self._count

    def write(self, matrix: Optional[np.ndarray]) -> None:
        """Add the motion of the next frame: ``(3, 3)``, or None (not measured: NaN)."""
        row = np.full((3, 3), np.nan) if matrix is None else np.asarray(matrix, np.float64)
        try:
            _write_all(self._file, np.ascontiguousarray(row.reshape(3, 3), "<f8").tobytes())
        except OSError as err:  # close() drops the part of the row that got in
            raise _write_error(self.path, "the camera motion", err) from None
        self._count += 1

    def close(self) -> None:
        if self._file is None:
            return
        fh, self._file = self._file, None
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
        except OSError as err:
            raise _write_error(self.path, "the camera motion", err) from None
        finally:
            with contextlib.suppress(OSError):
                self._temp.unlink()  # (gone once renamed)


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


def check_motion_output(path: PathLike, *, overwrite: bool = False) -> Path:
    """Check that a motion file (``.npy``) can be written at ``path``; nothing is written."""
    output = check_file_output(path, overwrite=overwrite)
    if output.suffix.lower() != ".npy":
        raise OutputError(f"{output}: a motion file is a .npy array; give a name ending in .npy")
    return output
