"""H.264 picture videos through PyAV (the optional ``h264`` extra: ``pip install 'bgsub[h264]'``).

The OpenCV wheels cannot encode H.264, and MPEG-4 part 2 (mp4v) does not play in web browsers.
PyAV's wheels bundle FFmpeg with libx264, so with PyAV installed ``.mp4`` and ``.mov`` picture
videos (overlays, flow pictures, side-by-side comparisons) are H.264: ``yuv420p`` (what every
browser decodes), constant quality (CRF 23, preset veryfast) and the index at the front of the file
(``+faststart``), so a browser starts playing before the whole file is read.

:func:`picture_codec` chooses the codec of a picture video: ``"auto"`` takes H.264 when PyAV
can encode it and MPEG-4 part 2 (``mp4v``) otherwise; ``"h264"`` and ``"mp4v"`` ask for one.
"""

from __future__ import annotations

import functools
from fractions import Fraction
from pathlib import Path
from typing import Any, Optional, Tuple

import numpy as np

from bgsub.errors import OutputError

#: The ``codec`` choices of picture videos (``--codec``).
CODEC_CHOICES = ("auto", "h264", "mp4v")
#: Suffixes whose codec ``codec`` chooses; ``.avi`` (MJPG) and ``.mkv`` (FFV1) keep theirs.
CHOOSABLE_SUFFIXES = (".mp4", ".mov")
#: What to install for H.264, as said in messages.
H264_EXTRA = "pip install 'bgsub[h264]' (PyAV)"

# libx264's default quality; the "veryfast" preset encodes much faster than the default
# "medium" at the same size (docs/BENCHMARKS.md).
_X264_OPTIONS = {"crf": "23", "preset": "veryfast"}


@functools.lru_cache(maxsize=None)
def h264_available() -> bool:
    """Whether PyAV is installed and its FFmpeg has the libx264 encoder."""
    try:
        import av
    except Exception:  # (ImportError, or a broken install: no H.264 either way)
        return False
    return "libx264" in getattr(av, "codecs_available", ())


def picture_codec(suffix: str, codec: str = "auto") -> Optional[str]:
    """The codec to write a picture video with ``suffix`` (``".mp4"``) in: ``"h264"`` or
    ``"mp4v"`` for ``.mp4`` / ``.mov``, None for other suffixes (their own codec).

    Raises
    ------
    OutputError
        ``codec`` is not one of :data:`CODEC_CHOICES`, or is ``"h264"`` while PyAV (with
        libx264) is not installed.
    """
    if codec not in CODEC_CHOICES:
        raise OutputError(f"video codec must be one of {', '.join(CODEC_CHOICES)}, "
                          f"not {codec!r}")
    if suffix.lower() not in CHOOSABLE_SUFFIXES:
        return None
    if codec == "h264" and not h264_available():
        raise OutputError(f"H.264 videos need PyAV with libx264: {H264_EXTRA}")
    if codec == "auto":
        return "h264" if h264_available() else "mp4v"
    return codec


class H264Writer:
    """Writes BGR pictures to an H.264 ``.mp4`` / ``.mov`` file, with the methods of
    ``cv2.VideoWriter`` that :class:`bgsub.io.videofile.VideoFile` uses (``isOpened``,
    ``write``, ``release``).

    Parameters
    ----------
    path : path
        The file (its suffix, ``.mp4`` or ``.mov``, gives the container).
    fps : float
    size : (width, height)
        Even numbers (yuv420p halves the colour planes).
    """

    def __init__(self, path: Path, *, fps: float, size: Tuple[int, int]) -> None:
        import av

        self._container: Any = None
        self._stream: Any = None
        suffix = Path(path).suffix.lower()
        try:
            self._container = av.open(str(path), mode="w",
                                      format="mov" if suffix == ".mov" else "mp4",
                                      options={"movflags": "+faststart"})
            stream = self._container.add_stream(
                "libx264", rate=Fraction(fps).limit_denominator(1001000),
                options=dict(_X264_OPTIONS))
            stream.width, stream.height = size
            stream.pix_fmt = "yuv420p"
            self._stream = stream
        except (OSError, ValueError, av.FFmpegError):
            self.release()

    def isOpened(self) -> bool:  # noqa: N802 (cv2.VideoWriter's name)
        return self._stream is not None

    def write(self, image: np.ndarray) -> bool:
        """Encode one ``(height, width, 3)`` BGR uint8 picture; False when the file cannot
        be written (a full disk)."""
        import av

        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")
        try:
            self._container.mux(self._stream.encode(frame))
        except (OSError, av.FFmpegError):
            return False
        return True

    def release(self) -> None:
        """Flush the encoder and finish the file (its index); safe to call twice."""
        import av

        container, self._container = self._container, None
        if container is None:
            return
        try:
            if self._stream is not None:
                container.mux(self._stream.encode(None))
        except (OSError, av.FFmpegError):
            pass  # (VideoFile counts the frames the file holds)
        finally:
            self._stream = None
            try:
                container.close()
            except (OSError, av.FFmpegError):
                pass
