"""Frame sources: a video file, a folder of images or a glob pattern, behind one interface.

Every source streams: it holds one decoded frame at a time (listing file names is the only thing
kept for a whole input), so memory stays flat however long the input is::

    with open_source("clip.mp4", step=2, width=320) as source:
        print(source.info)                    # size, fps, frames it will yield
        for index, frame in source:           # index in the full input, frame (H, W, 3) uint8 BGR
            ...

The backends (PySceneDetect style):

* **video** -- any file OpenCV's FFmpeg backend decodes
  (``cv2.VideoCapture(path, cv2.CAP_FFMPEG)``);
* **folder** -- the images of a folder in natural order (``in2.jpg`` before ``in10.jpg``); a CDnet
  sequence folder (one holding ``input/``) reads its ``input/`` folder;
* **glob** -- the images matching a pattern such as ``"frames/*.png"``, in natural order;
* **stream** -- a camera index (``0``), a video device (``/dev/video0``) or a URL
  (``rtsp://...``, ``http://.../clip.mp4``), read once as it comes (:mod:`bgsub.io.streams`).

Problems a user can fix (missing or unreadable input, mixed image sizes, frames smaller than a
patch, an empty frame range, bad options) raise :class:`bgsub.errors.InputError` with one line.
"""

from __future__ import annotations

import contextlib
import glob
import math
import numbers
import os
import re
import sys
import threading
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

# FFmpeg prints its own complaints ("moov atom not found", ...) straight to stderr; bgsub reports
# unreadable input itself in one line. OpenCV reads this variable when its FFmpeg backend starts,
# so it has to be set before cv2 decodes anything; a value the user set is kept.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

import cv2  # noqa: E402 (after the environment variable above)

from bgsub.errors import InputError, given_path  # noqa: E402

#: Smallest width and height of the frames bgsub processes (the side of the motion model's
#: patches; the same floor for every engine, so inputs that one accepts all others do).
MIN_FRAME_SIZE = 13

#: Frame rate reported for image folders and videos that do not state one.
DEFAULT_FPS = 25.0

#: File name extensions read as images (what ``cv2.imread`` decodes); other files are ignored.
IMAGE_EXTENSIONS = frozenset(
    {".bmp", ".dib", ".jpg", ".jpeg", ".jpe", ".jp2", ".png", ".webp", ".pbm", ".pgm", ".ppm",
     ".pnm", ".tif", ".tiff", ".sr", ".ras", ".exr", ".hdr", ".pic"}
)

#: File name extensions of video containers, in the order a mask video is looked for
#: (``NAME.mkv`` before ``NAME.avi`` ...: `bgsub eval` on a dataset, `bgsub compare` reports):
#: the lossless mask videos `bgsub run` writes first, then its lossy ones, then other containers
#: FFmpeg reads. Also what names a file as a video where an image was expected.
VIDEO_SUFFIXES = (".mkv", ".avi", ".mp4", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv",
                  ".flv", ".ts", ".3gp")

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class VideoInfo:
    """What a :class:`FrameSource` will yield.

    Attributes
    ----------
    path : str
        The input as given.
    width, height : int
        Size of the yielded frames, after resizing.
    fps : float
        Frame rate of the yielded stream: the input's rate divided by ``step``, so a video written
        from it plays at the input's speed. :data:`DEFAULT_FPS` (divided by ``step``) for image
        folders.
    fps_is_default : bool
        True when the input states no frame rate and :data:`DEFAULT_FPS` was assumed.
    frame_count : int or None
        Number of frames this source yields (after start/stop/step), ``None`` if the video does
        not say how long it is.
    kind : str
        ``"video"``, ``"folder"``, ``"glob"`` or ``"stream"`` (a camera, device or URL: one
        pass, ``frame_count`` None).
    """

    path: str
    width: int
    height: int
    fps: float
    fps_is_default: bool
    frame_count: Optional[int]
    kind: str


@contextlib.contextmanager
def quiet_opencv() -> Iterator[None]:
    """Silence OpenCV's own log lines (``[ WARN:0@0.01] ...``) inside the ``with`` block.

    OpenCV's log level is process-wide: blocks that overlap (sinks written from several
    threads) share one silence, and the level in force before the first is restored when the
    last ends (saved and restored per block, the first to end would keep OpenCV silent)."""
    global _quiet_depth, _loud_level
    logging = cv2.utils.logging
    with _quiet_lock:
        if _quiet_depth == 0:
            _loud_level = logging.getLogLevel()
            logging.setLogLevel(logging.LOG_LEVEL_SILENT)
        _quiet_depth += 1
    try:
        yield
    finally:
        with _quiet_lock:
            _quiet_depth -= 1
            if _quiet_depth == 0:
                logging.setLogLevel(_loud_level)


_quiet_lock = threading.Lock()
_quiet_depth = 0  # quiet_opencv blocks running now
_loud_level = 0  # OpenCV's log level before the first of them


@contextlib.contextmanager
def _native_stderr_muted(data: np.ndarray) -> Iterator[None]:
    """Point file descriptor 2 at the null device inside the ``with`` block when ``data`` is a
    PNG file's bytes: libpng prints its errors there itself ("libpng error: IDAT: ..."), outside
    OpenCV's log levels, and bgsub reports the failed decode in its own line. Other data, and
    calls while another block is open (threads), leave stderr alone."""
    if not _native_lock.acquire(blocking=False):
        yield
        return
    try:
        if data[:8].tobytes() != _PNG_SIGNATURE:
            yield
            return
        sys.stderr.flush()  # what Python holds for fd 2 goes out before it is muted
        saved, sink = os.dup(2), os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(sink, 2)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            os.close(sink)
    finally:
        _native_lock.release()


_native_lock = threading.Lock()
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_image_quietly(path: Any, flags: int = cv2.IMREAD_COLOR) -> Optional[np.ndarray]:
    """``cv2.imread(path, flags)`` without OpenCV's or libpng's own lines on stderr (the
    caller reports a failure in its own line): None when the file cannot be read or decoded."""
    try:
        data = np.fromfile(os.fspath(path), dtype=np.uint8)  # (+ imdecode: any path encoding)
    except (OSError, ValueError):
        return None
    if not data.size:
        return None
    with quiet_opencv(), _native_stderr_muted(data):
        return cv2.imdecode(data, flags)


def decode_image(data: np.ndarray, *, name: str) -> Optional[np.ndarray]:
    """An image file's bytes ``(N,) uint8`` decoded as ``(H, W, 3) uint8`` BGR (what
    ``cv2.IMREAD_COLOR`` gives: gray expanded, alpha dropped, 16 bits scaled to 8), without
    OpenCV's or libpng's own lines on stderr; None when it is no image OpenCV decodes.

    Floating-point images (32-bit TIFF, ...), which ``IMREAD_COLOR`` refuses, are read as gray
    levels in [0, 1]; values outside raise :class:`InputError` naming ``name`` (the file), as
    does a sample type with no 8-bit reading."""
    if not data.size:
        return None
    with quiet_opencv(), _native_stderr_muted(data):
        image = cv2.imdecode(data, cv2.IMREAD_COLOR)
        raw = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if image is None else None
    if image is not None or raw is None:
        return image
    if raw.dtype.kind != "f":
        raise InputError(f"{name}: images of {raw.dtype} samples are not supported (give 8- or "
                         "16-bit, or floating-point, images)")
    low, high = (float(raw.min()), float(raw.max())) if np.isfinite(raw).all() else (-1.0, -1.0)
    if not 0.0 <= low <= high <= 1.0:
        shown = f"from {low:g} to {high:g}" if high >= 0 else "that are not finite"
        raise InputError(f"{name}: a floating-point image with values {shown}; bgsub reads "
                         "floating-point images as gray levels from 0 to 1 (convert it to 8 bits)")
    image = np.rint(raw * np.float32(255.0)).astype(np.uint8)
    channels = image.shape[2] if image.ndim == 3 else 1
    if channels not in (1, 3, 4):
        raise InputError(f"{name}: images with {channels} channels are not supported")
    code = {1: cv2.COLOR_GRAY2BGR, 4: cv2.COLOR_BGRA2BGR}.get(channels)
    return image if code is None else cv2.cvtColor(image, code)


def natural_key(text: str) -> list:
    """Sort key that orders the digit runs of ``text`` as numbers: ``in2.jpg`` < ``in10.jpg``."""
    # re.split with a group alternates text, number, text, ..., so keys compare type-wise.
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", text)]


def _size_text(shape: Sequence[int]) -> str:
    return f"{shape[1]}x{shape[0]}"


def _as_bgr(frame: np.ndarray) -> np.ndarray:
    """``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` or ``(H, W, 4)`` uint8 -> ``(H, W, 3)`` BGR."""
    if frame.ndim == 3 and frame.shape[2] == 3:
        return frame
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return cv2.cvtColor(frame.reshape(frame.shape[:2]), cv2.COLOR_GRAY2BGR)


# --------------------------------------------------------------------------------------------
# Backends: each yields (index, raw frame) for a frame range; FrameSource does the rest.
# --------------------------------------------------------------------------------------------


class _VideoBackend:
    """A video file read with OpenCV's FFmpeg backend."""

    kind = "video"

    def __init__(self, path: Path) -> None:
        self.path = path
        capture = self._open()
        try:
            ok, frame = capture.read()
            if not ok or frame is None:
                raise InputError(f"{path}: the video has no frames that can be decoded")
            self.first_shape: Tuple[int, ...] = frame.shape
            fps = capture.get(cv2.CAP_PROP_FPS)
            count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            capture.release()
        self.fps_is_default = not (math.isfinite(fps) and 0 < fps <= 1000)
        self.fps = DEFAULT_FPS if self.fps_is_default else float(fps)
        # The container's count; some containers only estimate it, so iteration never relies on it.
        self.total: Optional[int] = count if count > 0 else None
        # Frames decoded (from the first) when the last pass's decoder gave up before its stop;
        # None when it reached its stop or was not run to the end.
        self.decoding_ended_at: Optional[int] = None

    def _open(self) -> "cv2.VideoCapture":
        with quiet_opencv():
            capture = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        if not capture.isOpened():
            raise InputError(
                f"{self.path}: cannot read it as a video (not a video file, or a format "
                "OpenCV's FFmpeg cannot decode)"
            )
        return capture

    def describe(self, index: int) -> str:
        return f"frame {index} of {self.path}"

    def frames(self, start: int, stop: Optional[int], step: int
               ) -> Iterator[Tuple[int, np.ndarray]]:
        self.decoding_ended_at = None
        capture = self._open()
        try:
            # Skip by decoding rather than seeking with CAP_PROP_POS_FRAMES: seeking lands on a
            # nearby key frame in some containers, and masks must match frame numbers exactly.
            for index in range(start):
                if not capture.grab():
                    raise self._past_the_end(start, index)
            index = start
            while stop is None or index < stop:
                ok, frame = capture.read()
                if not ok or frame is None:
                    if index == start:  # not one frame from the start on: decoded to the end
                        raise self._past_the_end(start, index)
                    self.decoding_ended_at = index
                    return
                yield index, frame
                for skipped in range(step - 1):
                    if not capture.grab():
                        self.decoding_ended_at = index + 1 + skipped
                        return
                index += step
        finally:
            capture.release()


    def _past_the_end(self, start: int, decoded: int) -> InputError:
        declared = (f"; its header declares {self.total}, so the file may be truncated or "
                    "damaged" if self.total is not None and self.total > decoded else "")
        return InputError(f"{self.path}: start frame {start} is past the end of the video "
                          f"({decoded} frames decode{declared})")


class _ImageListBackend:
    """Images read one at a time from a list of files (a folder or a glob pattern)."""

    fps = DEFAULT_FPS
    fps_is_default = True

    def __init__(self, files: List[Path], kind: str) -> None:
        self.files = files
        self.kind = kind
        self.total: Optional[int] = len(files)
        self.first_shape: Tuple[int, ...] = ()
        # The folders the files are listed from, resolved (a glob may span several).
        self.folders: Tuple[Path, ...] = tuple(sorted({parent.resolve() for parent in
                                                       {path.parent for path in files}}))

    def read(self, index: int) -> np.ndarray:
        path = self.files[index]
        try:
            data = np.fromfile(path, np.uint8)
        except OSError as err:
            raise InputError(f"{path}: cannot read this image ({err.strerror or err})") from None
        if path.suffix.lower() in _JPEG_EXTENSIONS and not _ends_as_jpeg(data):
            # libjpeg would decode what is there, fill the rest with gray and only print
            # "Premature end of JPEG file" without a name: a half-gray frame is no input.
            raise InputError(f"{path}: truncated JPEG (it stops before its end marker)")
        image = decode_image(data, name=str(path))
        if image is None:
            raise InputError(f"{path}: cannot read this image (corrupt or not an image)")
        return image

    def describe(self, index: int) -> str:
        return str(self.files[index])

    def frames(self, start: int, stop: Optional[int], step: int
               ) -> Iterator[Tuple[int, np.ndarray]]:
        end = len(self.files) if stop is None else min(stop, len(self.files))
        for index in range(start, end, step):
            yield index, self.read(index)


_JPEG_EXTENSIONS = frozenset({".jpg", ".jpeg", ".jpe"})


def _ends_as_jpeg(data: np.ndarray) -> bool:
    """``(N,) uint8`` file bytes hold a JPEG end-of-image marker (``FF D9``) near their end.

    Inside a JPEG's compressed data a 0xFF byte is always followed by 0x00 or a restart marker,
    so ``FF D9`` is the end marker; some writers pad a few bytes after it."""
    tail = data[-1024:].tobytes()
    return b"\xff\xd9" in tail


def _is_image_file(path: Path) -> bool:
    # Names starting with "." are hidden files such as macOS "._in000001.jpg" resource forks.
    return path.suffix.lower() in IMAGE_EXTENSIONS and not path.name.startswith(".") \
        and path.is_file()


def _folder_backend(folder: Path) -> _ImageListBackend:
    if (folder / "input").is_dir():  # a CDnet sequence: NAME/input/in000001.jpg ...
        folder = folder / "input"
    try:
        entries = list(folder.iterdir())
    except OSError as err:
        raise InputError(f"{folder}: cannot list the folder ({err.strerror})") from None
    files = sorted((p for p in entries if _is_image_file(p)), key=lambda p: natural_key(p.name))
    if not files:
        raise InputError(f"{folder}: the folder holds no images")
    return _ImageListBackend(files, "folder")


def _glob_backend(pattern: str) -> _ImageListBackend:
    matches = [Path(p) for p in glob.glob(pattern)]
    files = sorted((p for p in matches if _is_image_file(p)), key=lambda p: natural_key(str(p)))
    if not files:
        what = "no images" if matches else "nothing"
        raise InputError(f"{pattern}: {what} matches this pattern")
    return _ImageListBackend(files, "glob")


# --------------------------------------------------------------------------------------------
# The source users see.
# --------------------------------------------------------------------------------------------


class FrameSource:
    """Frames of one input, streamed: a context manager and an iterable.

    Iterating yields ``(index, frame)``: ``index`` is the frame's 0-based position in the full
    input (so ``start=10, step=5`` yields 10, 15, 20, ...), ``frame`` an ``(H, W, 3) uint8`` BGR
    array of :attr:`info`'s size. A source can be iterated more than once; each pass reads the
    input again. Build one with :func:`open_source`.
    """

    def __init__(self, backend, info: VideoInfo, *, start: int, stop: Optional[int], step: int,
                 ) -> None:
        self.info = info
        self._backend = backend
        self._range = (start, stop, step)
        self._iterators: "weakref.WeakSet" = weakref.WeakSet()
        self._closed = False

    def __enter__(self) -> "FrameSource":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def close(self) -> None:
        """Stop any iteration in progress and release the decoder."""
        self._closed = True
        for iterator in list(self._iterators):
            iterator.close()
        if callable(getattr(self._backend, "close", None)):
            self._backend.close()  # (a stream opened but never iterated)

    def first_frame(self) -> Optional[np.ndarray]:
        """The first frame in range as read, ``(H, W, 3) uint8`` BGR before resizing, or None:
        a stream's is the frame read when it was opened (it is not opened again), other
        inputs' is read in a pass of its own."""
        if self.info.kind == "stream":
            held = getattr(self._backend, "held_frame", None)
            return None if held is None else _as_bgr(held)
        frames = iter(self)
        try:
            first = next(frames, None)
        finally:
            frames.close()
        return None if first is None else first[1]

    def __iter__(self) -> Iterator[Tuple[int, np.ndarray]]:
        if self._closed:
            raise ValueError("iterating a closed FrameSource")
        iterator = self._frames()
        self._iterators.add(iterator)
        return iterator

    def __repr__(self) -> str:
        return f"FrameSource({self.info})"

    def file_name(self, index: int) -> Optional[str]:
        """The name of the image file of frame ``index`` (0-based, in the full input), or
        ``None`` for a video."""
        files = getattr(self._backend, "files", None)
        return None if files is None else Path(files[index]).name

    @property
    def folders(self) -> Tuple[Path, ...]:
        """The folders the frames are listed from, resolved: an image folder (a CDnet sequence's
        ``input/``) or every folder a glob's matches lie in; ``()`` for a video. Images written
        there would be read as frames the next time."""
        return getattr(self._backend, "folders", ())

    def truncation(self) -> Optional[str]:
        """A one-line note when the last complete pass over a video ended because decoding
        stopped well short of the frame count its container declares (a truncated or damaged
        file), else ``None``. A pass that reached its ``stop`` is not short; a few frames of
        difference are allowed, since some containers only estimate their length."""
        ended = getattr(self._backend, "ended", None)  # a stream: stalled, dropped or ended
        if ended is not None:
            return ended
        decoded = getattr(self._backend, "decoding_ended_at", None)
        declared = self._backend.total
        if decoded is None or declared is None:
            return None
        stop = self._range[1]
        expected = declared if stop is None else min(stop, declared)
        if expected - decoded <= max(2, declared // 50):
            return None
        return (f"{self.info.path} ended after {decoded} of the {declared} frames its header "
                "declares (truncated or damaged?)")

    def _frames(self) -> Iterator[Tuple[int, np.ndarray]]:
        size = (self.info.width, self.info.height)
        reference: Optional[Tuple[Tuple[int, ...], int]] = None  # (shape, index) of 1st frame
        for index, raw in self._backend.frames(*self._range):
            if reference is None:
                reference = (raw.shape[:2], index)
            elif raw.shape[:2] != reference[0]:
                raise InputError(
                    f"{self._backend.describe(index)} is {_size_text(raw.shape)} but "
                    f"{self._backend.describe(reference[1])} is {_size_text(reference[0])}: all "
                    "frames must have the same size"
                )
            frame = _as_bgr(raw)
            if (frame.shape[1], frame.shape[0]) != size:
                shrinking = size[0] < frame.shape[1]
                frame = cv2.resize(frame, size, interpolation=cv2.INTER_AREA if shrinking
                                   else cv2.INTER_LINEAR)
            yield index, frame


def _check_range(start: int, stop: Optional[int], step: int) -> None:
    # The step first: a caller that counts stop from it (start + frames * step) gets a stop
    # that is wrong only because the step is.
    if not isinstance(step, (int, np.integer)) or step < 1:
        raise InputError(f"invalid frame range: step must be at least 1, not {step!r}")
    if not isinstance(start, (int, np.integer)) or start < 0:
        raise InputError(f"invalid frame range: start must be a frame number >= 0, not {start!r}")
    if stop is not None and (not isinstance(stop, (int, np.integer)) or stop <= start):
        raise InputError(f"invalid frame range: stop ({stop!r}) must be after start ({start})")


def _stream_backend(text: str, *, start: int, stall_seconds: Optional[float]) -> Any:
    """The backend of a camera index, video device or URL, or None for other inputs."""
    from bgsub.io.streams import DEFAULT_STALL_SECONDS, StreamBackend, stream_kind

    kind = stream_kind(text)
    if stall_seconds is not None and not (isinstance(stall_seconds, numbers.Real)
                                          and math.isfinite(stall_seconds) and stall_seconds > 0):
        raise InputError(f"the stall timeout must be a number of seconds > 0, not "
                         f"{stall_seconds!r}")
    if kind is None:
        return None
    return StreamBackend(text, kind, start=start,
                         stall_seconds=stall_seconds or DEFAULT_STALL_SECONDS)


def _backend(path: Union[PathLike, int], *, start: int, stall_seconds: Optional[float]
             ) -> Tuple[str, Any]:
    """``(text, backend)`` of the input ``path``: a live source, a folder, a video or a glob."""
    if isinstance(path, (int, np.integer)) and not isinstance(path, bool):
        path = str(int(path))  # a camera index
    text = given_path(path, what="input", hint="a video file, an image folder or a glob pattern")
    location = Path(text)
    stream = _stream_backend(text, start=start, stall_seconds=stall_seconds)
    if stream is not None:  # a camera, device or URL
        return text, stream
    if location.is_dir():
        return text, _folder_backend(location)
    if location.is_file():
        if location.suffix.lower() in IMAGE_EXTENSIONS:  # (OpenCV would read one frame)
            folder = location.parent
            raise InputError(f"{text}: is one image, not a video; give the folder of the frames "
                             f"({folder}{os.sep}) or a quoted glob pattern "
                             f"('{folder / ('*' + location.suffix)}')")
        return text, _VideoBackend(location)
    if glob.has_magic(text):
        return text, _glob_backend(text)
    if location.exists():
        raise InputError(f"{text}: not a video file, image folder or glob pattern (a pipe, "
                         "socket or other special file)")
    raise InputError(f"{text}: no such file or folder")


#: Largest side of a resized frame (8K video is 7680 wide).
MAX_SIDE = 16384


def output_size(width: int, height: int, *, scale: Optional[float] = None,
                target_width: Optional[int] = None) -> Tuple[int, int]:
    """Size ``(width, height)`` of frames resized by ``scale`` or to ``target_width``.

    The aspect ratio is kept; with neither option the size is unchanged.
    """
    if scale is not None and target_width is not None:
        raise InputError("give either a scale or a width to resize to, not both")
    if scale is not None:
        if not (isinstance(scale, numbers.Real) and math.isfinite(scale) and scale > 0):
            raise InputError(f"invalid scale {scale!r}: it must be a number > 0, e.g. 0.5")
        size = max(1, round(width * scale)), max(1, round(height * scale))
    elif target_width is not None:
        if not isinstance(target_width, (int, np.integer)) or target_width < 1:
            raise InputError(f"invalid width {target_width!r}: it must be a whole number of "
                             "pixels >= 1")
        size = int(target_width), max(1, round(height * target_width / width))
    else:
        return width, height
    if max(size) > MAX_SIDE:
        # A typo (--scale 1000) would otherwise end in the system killing the process.
        raise InputError(f"resized frames would be {size[0]}x{size[1]}; the largest side "
                         f"allowed is {MAX_SIDE} pixels")
    return size


def open_source(path: Union[PathLike, int], *, start: int = 0, stop: Optional[int] = None,
                step: int = 1, scale: Optional[float] = None, width: Optional[int] = None,
                fps: Optional[float] = None, stall_seconds: Optional[float] = None
                ) -> FrameSource:
    """Open a video file, an image folder, a glob pattern or a live source as a stream of
    frames.

    Parameters
    ----------
    path : str, path or int
        A video file, a folder of images (a CDnet sequence folder reads its ``input/``), a
        glob pattern such as ``"frames/*.png"``, or a live source read once as OpenCV's
        ``cv2.VideoCapture`` opens it: a camera index (``0`` or ``"0"``), a video device
        (``"/dev/video0"``) or a URL (``"rtsp://..."``, ``"http://.../clip.mp4"``).
    start, stop, step : int
        Read frames ``start, start + step, ...`` before ``stop`` (0-based; ``stop=None`` is the
        end), like ``range(start, stop, step)``.
    scale : float, optional
        Resize every frame by this factor (``cv2.INTER_AREA`` when shrinking).
    width : int, optional
        Resize every frame to this width, keeping the aspect ratio. Exclusive with ``scale``.
    fps : float, optional
        The input's frame rate (any real number from 0.01 to 1000: int, float, a numpy scalar),
        in place of what it states (image folders state none: videos written from them play at
        :data:`DEFAULT_FPS` otherwise). ``info.fps`` is this divided by ``step``.
    stall_seconds : float, optional
        A live source that gives no frame for this long (seconds, > 0) is taken as stalled:
        the pass ends and :meth:`FrameSource.truncation` says so (default
        :data:`bgsub.io.streams.DEFAULT_STALL_SECONDS`).

    Returns
    -------
    FrameSource
        Yields ``(index, (H, W, 3) uint8 BGR frame)``; ``.info`` is a :class:`VideoInfo`.

    Raises
    ------
    InputError
        Missing or unreadable input, no frames, frames smaller than ``MIN_FRAME_SIZE``, a frame
        range past the end, or invalid options. Images of mixed sizes and unreadable images are
        reported when iteration reaches them.
    """
    _check_range(start, stop, step)
    if fps is not None and not (isinstance(fps, numbers.Real) and not isinstance(fps, bool)
                                and math.isfinite(fps) and 0.01 <= fps <= 1000):
        # (OpenCV's video writers refuse rates near 0: 0.001 fails, 0.002 works.)
        raise InputError(f"the frame rate must be a number of frames per second from 0.01 to "
                         f"1000, not {fps!r}")
    text, backend = _backend(path, start=start, stall_seconds=stall_seconds)

    total = backend.total
    if total is not None and start >= total:
        raise InputError(f"{text}: start frame {start} is past the end of the input "
                         f"({total} frames)")
    if isinstance(backend, _ImageListBackend):
        # The first frame in range fixes the size every other frame must have.
        backend.first_shape = backend.read(start).shape
    raw_h, raw_w = backend.first_shape[:2]
    out_w, out_h = output_size(raw_w, raw_h, scale=scale, target_width=width)
    if min(out_w, out_h) < MIN_FRAME_SIZE:
        resized = f" after resizing from {raw_w}x{raw_h}" if (out_w, out_h) != (raw_w, raw_h) \
            else ""
        raise InputError(
            f"{text}: frames are {out_w}x{out_h}{resized}, smaller than "
            f"{MIN_FRAME_SIZE}x{MIN_FRAME_SIZE}, the smallest frames bgsub processes"
        )

    count = None
    if total is not None:
        count = len(range(start, total if stop is None else min(stop, total), step))
    rate = backend.fps if fps is None else float(fps)
    info = VideoInfo(path=text, width=out_w, height=out_h, fps=rate / step,
                     fps_is_default=backend.fps_is_default and fps is None, frame_count=count,
                     kind=backend.kind)
    return FrameSource(backend, info, start=start, stop=stop, step=step)
