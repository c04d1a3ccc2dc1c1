"""Picture sinks: colour videos common players open (:class:`VideoSink`: flow pictures,
side-by-side comparisons) and the input with its mask overlaid (:class:`VisSink`).

``.mp4`` / ``.mov`` in H.264 when PyAV is installed (the ``h264`` extra; web browsers play it),
else in MPEG-4 part 2 (mp4v, which OpenCV writes and desktop players play); ``.avi`` (MJPG) or
``.mkv`` (FFV1). See :mod:`bgsub.io.h264`.
"""

from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from bgsub.io.h264 import picture_codec
from bgsub.io.outputs import (PICTURE_VIDEO_CODECS, PathLike, check_video_output, output_path,
                              say)
from bgsub.io.sink_base import Sink, binary_mask, check_image, check_size
from bgsub.io.videofile import VideoFile

import cv2  # noqa: E402,I100 (bgsub.io.sources sets FFmpeg's log level before cv2 starts FFmpeg)


class VideoSink(Sink):
    """A colour video of pictures: ``.mp4`` / ``.mov`` (H.264 or mp4v), ``.avi`` (MJPG) or
    ``.mkv`` (FFV1).

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
    codec : {"auto", "h264", "mp4v"}
        For ``.mp4`` / ``.mov``: H.264 when PyAV can write it (``"auto"``) or always
        (``"h264"``; :class:`OutputError` without PyAV), or MPEG-4 part 2 (``"mp4v"``).
        Other suffixes keep their codec.

    Attributes
    ----------
    codec : str
        The codec written: ``"h264"``, ``"mp4v"``, ``"MJPG"`` or ``"FFV1"``.
    """

    def __init__(self, path: PathLike, *, fps: float, width: Optional[int] = None,
                 height: Optional[int] = None, overwrite: bool = False,
                 codec: str = "auto") -> None:
        suffix = output_path(path).suffix.lower()
        chosen = picture_codec(suffix, codec)  # (a bad choice refused before any check)
        self.path = check_video_output(path, overwrite=overwrite)
        if width is not None or height is not None:
            check_size(self.path, width, height, "pictures")
        self.codec = chosen or PICTURE_VIDEO_CODECS[suffix]
        self._video = VideoFile(self.path, codec=self.codec, fps=fps, is_color=True,
                                overwrite=overwrite)
        self._blanks = 0  # pictures skipped before the size was known
        if width is not None and height is not None:
            self._video.open(width, height)

    @property
    def frames_written(self) -> int:
        return self._video.frames_written

    def write(self, image: np.ndarray) -> None:
        """Write the next picture, ``(H, W, 3)`` BGR or ``(H, W)`` gray uint8, all the same size."""
        check_image(image, ndims=(2, 3), what="a picture")
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
            say(f"{self.path}: not written, there was no picture to write")
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
    cv2.copyTo(tinted, foreground, overlay)  # tint only under the mask (cheaper than np.where)
    contours, _ = cv2.findContours(foreground, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(overlay, contours, -1, color, 1, cv2.LINE_AA)
    return np.hstack([overlay, cv2.cvtColor(mask, cv2.COLOR_GRAY2BGR)])


class VisSink(Sink):
    """A video of each input frame with its mask overlaid, beside the mask (``2W x H``).

    Parameters
    ----------
    path : str or path
        ``.mp4`` / ``.mov`` (H.264 or mp4v), ``.avi`` (MJPG) or ``.mkv`` (FFV1).
    width, height : int
        Size of the input frames (the video is ``2 * width`` wide).
    fps : float
        Frame rate.
    overwrite : bool
        Replace an existing file.
    codec : {"auto", "h264", "mp4v"}
        As :class:`VideoSink`'s; the codec written is :attr:`codec`.
    """

    def __init__(self, path: PathLike, *, width: int, height: int, fps: float,
                 overwrite: bool = False, codec: str = "auto") -> None:
        check_size(output_path(path), width, height, "frames")
        self._video = VideoSink(path, fps=fps, width=2 * int(width), height=int(height),
                                overwrite=overwrite, codec=codec)
        self.path = self._video.path
        self.codec = self._video.codec
        self.width, self.height = int(width), int(height)

    @property
    def frames_written(self) -> int:
        return self._video.frames_written

    def write(self, frame: np.ndarray, mask: np.ndarray) -> None:
        """Write ``frame`` ((H, W, 3) BGR or (H, W) gray uint8) with its ``mask`` ((H, W)
        uint8 0/255, or bool), both of this sink's ``height, width``; ``ValueError`` otherwise."""
        check_image(frame, ndims=(2, 3), what="a frame")
        mask = binary_mask(mask)
        if frame.shape[:2] != (self.height, self.width) or mask.shape != frame.shape[:2]:
            raise ValueError(f"a frame and its mask must both be {self.width}x{self.height} for "
                             f"{self.path}, got {frame.shape[1]}x{frame.shape[0]} and "
                             f"{mask.shape[1]}x{mask.shape[0]}")
        self._video.write(render_overlay(frame, mask))

    def close(self) -> None:
        self._video.close()

    def _told(self) -> bool:
        return self._video._told()
