"""Live and network sources: a camera index (``0``), a video device (``/dev/video0``) or a URL
(``rtsp://...``, ``http://.../clip.mp4``), opened as OpenCV opens them (``cv2.VideoCapture``
with the index, the device or the URL).

A stream is opened once: the first frame is read when it is opened (it fixes the frame size)
and handed out first, and the one pass over it reads on until the stream ends, the frame range's
``stop``, or the caller stops (Ctrl-C). Its length is unknown (``VideoInfo.frame_count`` is
None). A read that gives no frame for ``stall_seconds`` ends the pass as a stall; a stream that
ends before the length it declares (a file over HTTP) or that ends at all (a camera, RTSP) is
reported by :attr:`StreamBackend.ended`, one line. Frames are read in a thread of the source's
own, so a stall is timed by bgsub (not by the backend) and Ctrl-C during a stall finishes the
outputs at once (the process ends when OpenCV's read gives up, a second after the stall
timeout).
"""

from __future__ import annotations

import atexit
import math
import os
import queue
import re
import stat
import threading
import time
import urllib.parse
import weakref
from pathlib import Path
from typing import Iterator, Optional, Tuple

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.io.sources import DEFAULT_FPS, quiet_opencv

__all__ = ["DEFAULT_STALL_SECONDS", "StreamBackend", "is_live", "stream_kind", "stream_name"]

#: Seconds a live source may give no frame before it is taken as stalled.
DEFAULT_STALL_SECONDS = 10.0

_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


def stream_kind(text: str) -> Optional[str]:
    """``"camera"`` (a whole number such as ``"0"``, when no file has that name), ``"url"``
    (``scheme://...``), ``"device"`` (a character device such as ``/dev/video0``) or None
    (a file, folder or pattern)."""
    if _URL.match(text):
        return "url"
    if text.isdigit() and not os.path.exists(text):
        return "camera"
    try:
        mode = os.stat(text).st_mode
    except (OSError, ValueError):
        return None
    return "device" if stat.S_ISCHR(mode) else None


def is_live(text: str) -> bool:
    """Whether ``text`` names a live source, whose frames differ each time it is read: a
    camera, a device, or a URL other than ``http(s)``/``ftp``/``file`` (``rtsp://``, ``udp://``
    ...); a file over HTTP is the same file each time."""
    kind = stream_kind(text)
    if kind != "url":
        return kind is not None
    return urllib.parse.urlsplit(text).scheme.lower() not in {"http", "https", "ftp", "file"}


def stream_name(text: str) -> str:
    """A name for the outputs of a stream: ``camera0``, ``video0`` (``/dev/video0``), the stem
    of a URL's last path part (``clip`` for ``http://host/v/clip.mp4?key=1``) or its host."""
    kind = stream_kind(text)
    if kind == "camera":
        return f"camera{int(text)}"
    if kind == "url":
        parts = urllib.parse.urlsplit(text)
        stem = Path(parts.path).stem
        return stem or parts.hostname or "stream"
    return Path(text).name


def _plausible_fps(fps: float) -> bool:
    return math.isfinite(fps) and 0 < fps <= 1000


class _Reader(threading.Thread):
    """Reads a capture in a thread of its own and hands the frames over in a small queue (None
    at the end), so that waiting for a frame can time out and Ctrl-C is seen at once, however
    long OpenCV blocks in ``read()``. The thread releases the capture when it stops."""

    def __init__(self, capture: "cv2.VideoCapture") -> None:
        super().__init__(name="bgsub-stream", daemon=True)
        self.capture = capture
        self.queue: "queue.Queue[Optional[np.ndarray]]" = queue.Queue(maxsize=4)
        self.stop = threading.Event()
        _running.add(self)

    def finish(self, timeout: float) -> None:
        """Stop, and wait up to ``timeout`` seconds for the thread to end."""
        self.stop.set()
        if self.is_alive():
            self.join(timeout)

    def run(self) -> None:
        try:
            while not self.stop.is_set():
                with quiet_opencv():
                    ok, frame = self.capture.read()
                self._put(frame if ok and frame is not None else None)
                if not ok or frame is None:
                    return
        finally:
            self.capture.release()

    def _put(self, item: Optional[np.ndarray]) -> None:
        while not self.stop.is_set():
            try:
                self.queue.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def get(self, timeout: float) -> Tuple[bool, Optional[np.ndarray]]:
        """``(True, frame or None at the end)``, or ``(False, None)`` when no frame came within
        ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                return True, self.queue.get(timeout=min(0.1, max(deadline - time.monotonic(),
                                                                 0.001)))
            except queue.Empty:
                if time.monotonic() >= deadline:
                    return False, None


# Readers not yet finished: a thread still inside OpenCV when the interpreter exits aborts the
# process ("FATAL: exception not rethrown"), so they are waited for at exit (a source used
# without being closed).
_running: "weakref.WeakSet[_Reader]" = weakref.WeakSet()


@atexit.register
def _finish_readers() -> None:
    for reader in list(_running):
        reader.finish(timeout=30.0)


def _no_frame_hint(url: str) -> str:
    """Why a file over HTTP opens but gives no frame, and what to do: ``""`` for other
    sources."""
    if not url.lower().startswith(("http://", "https://")):
        return ""
    return ("; the likely cause: the server ignores byte ranges (as `python3 -m http.server` "
            "does) and the file keeps its index at its end (an .mp4 or .mov not written for "
            "streaming), so it cannot be read as it arrives. Serve it from a server with range "
            "support, or give an .mkv, or a faststart .mp4: ffmpeg -i in.mp4 -c copy -movflags "
            "+faststart out.mp4")


class StreamBackend:
    """One live source, open from construction to the end of its one pass (or :meth:`close`).

    ``label`` names it in messages (``camera 0``, the device path, the URL). ``first_shape``
    and ``held_frame`` are the first frame's (read at ``start``, after skipping the frames
    before it)."""

    kind = "stream"
    total: Optional[int] = None  # (a live source's length is unknown)

    def __init__(self, text: str, kind: str, *, start: int, stall_seconds: float) -> None:
        self.text, self.stream = text, kind
        self.label = f"camera {int(text)}" if kind == "camera" else text
        self.stall_seconds = float(stall_seconds)
        self.ended: Optional[str] = None
        self.stalled = False
        capture = self._open()
        fps = capture.get(cv2.CAP_PROP_FPS)
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        self._declared = count if kind == "url" and count > 0 else None
        self._read_count = 0
        self._reader: Optional[_Reader] = _Reader(capture)
        self._reader.start()
        try:
            frame = self._next()
            for index in range(start):
                if frame is None:
                    raise InputError(f"{self.label}: the stream ended after {index} frames, "
                                     f"before start frame {start}")
                frame = self._next()
            if frame is None:
                within = f" within {self.stall_seconds:g} s" if self.stalled else ""
                raise InputError(f"{self.label}: opened, but it gave no frame{within}"
                                 + ("" if self.stalled else _no_frame_hint(text)))
        except BaseException:
            self.close()
            raise
        self.ended = None
        self.held_frame: Optional[np.ndarray] = frame
        self.first_shape: Tuple[int, ...] = frame.shape
        self.fps_is_default = not _plausible_fps(fps)
        self.fps = DEFAULT_FPS if self.fps_is_default else float(fps)

    def _open(self) -> "cv2.VideoCapture":
        # FFmpeg gives up a second after the stall timeout: a stall is reported as one, and
        # the reader thread ends soon after (close() waits for it).
        timeout = int(round(self.stall_seconds * 1000 + 1000))
        with quiet_opencv():
            if self.stream == "camera":
                capture = cv2.VideoCapture(int(self.text))
            elif self.stream == "device":
                capture = cv2.VideoCapture(self.text)
            else:
                capture = cv2.VideoCapture(self.text, cv2.CAP_FFMPEG,
                                           [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, timeout,
                                            cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout])
        if not capture.isOpened():
            why = {"camera": "no camera with this index, or it is in use",
                   "device": "not a video device OpenCV can open, or it is in use",
                   "url": "unreachable, not found, or a format OpenCV's FFmpeg cannot read"}
            raise InputError(f"{self.label}: cannot open it ({why[self.stream]})")
        return capture

    def _next(self) -> Optional[np.ndarray]:
        """The next frame, or None at the end; sets :attr:`ended` when the stream stalled or
        ended early."""
        came, frame = (False, None) if self._reader is None else self._reader.get(
            self.stall_seconds)
        if frame is not None:
            self._read_count += 1
            return frame
        frames = f"{self._read_count} frame{'s' * (self._read_count != 1)}"
        self.stalled = not came
        if self.stalled:
            self.ended = (f"{self.label} stalled (no frame for {self.stall_seconds:g} s) after "
                          f"{frames}")
        elif self._declared is None:
            self.ended = f"{self.label} ended after {frames}"
        elif self._read_count < self._declared - max(2, self._declared // 50):
            self.ended = (f"{self.label} dropped after {frames} of the {self._declared} it "
                          "declares")
        self._stop()
        return None

    def describe(self, index: int) -> str:
        return f"frame {index} of {self.label}"

    def _stop(self) -> None:
        """Stop reading (the reader releases the capture once OpenCV's read returns)."""
        if self._reader is not None:
            self._reader.stop.set()

    def close(self) -> None:
        """Stop reading and wait for the reader thread to release the capture: at most a
        little longer than the stall timeout (a stalled URL's case). Called when the source is
        closed, after the outputs are finished."""
        reader, self._reader = self._reader, None
        if reader is not None:
            reader.finish(self.stall_seconds + 2.0)

    def frames(self, start: int, stop: Optional[int], step: int
               ) -> Iterator[Tuple[int, np.ndarray]]:
        if self._reader is None or self.held_frame is None:
            raise InputError(f"{self.label}: a live source is read once; open it again for "
                             "another pass")
        frame, self.held_frame = self.held_frame, None
        index = start
        try:
            while frame is not None and (stop is None or index < stop):
                yield index, frame
                for _ in range(step - 1):
                    if self._next() is None:
                        return
                frame = self._next()
                index += step
        finally:
            self._stop()  # (close() waits for the reader, once the outputs are finished)
