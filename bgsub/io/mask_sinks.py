"""Mask sinks: foreground masks, ``(H, W) uint8`` 0/255, as a lossless video or a CDnet-style
folder of ``binNNNNNN.png`` (numbered from the input frame, so ``bin000123.png`` is the mask of
``in000123.jpg``); :func:`open_mask_sink` picks one from the output's name."""

from __future__ import annotations

import contextlib
import os
from abc import abstractmethod
from pathlib import Path
from typing import Optional

import numpy as np

from bgsub.errors import OutputError
from bgsub.io.outputs import (LOSSY_CODECS, MASK_NAME, MASK_VIDEO_CODECS, PARTIAL_MASK_NAME,
                              OutputClaim, PathLike, check_mask_output, say, write_error)
from bgsub.io.sink_base import Sink, binary_mask, check_size
from bgsub.io.videofile import VideoFile

import cv2  # noqa: E402,I100 (bgsub.io.sources sets FFmpeg's log level before cv2 starts FFmpeg)


class MaskSink(Sink):
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
        check_size(path, width, height, "masks")
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
        mask = binary_mask(mask)
        if mask.shape != (self.height, self.width):
            raise ValueError(f"a mask must be {self.width}x{self.height} for {self.path}, got "
                             f"{mask.shape[1]}x{mask.shape[0]}")
        self._write(mask, index)

    @abstractmethod
    def _write(self, mask: np.ndarray, index: Optional[int]) -> None:
        """Write one validated mask."""


class MaskVideoSink(MaskSink):
    """Masks as a gray video: lossless FFV1 in ``.mkv``/``.avi``, lossy mp4v in ``.mp4``."""

    def __init__(self, path: Path, *, width: int, height: int, fps: float,
                 overwrite: bool = False) -> None:
        super().__init__(path, width=width, height=height)
        if width % 2 or height % 2:
            # A padded or cropped mask would no longer match its frame or its ground truth.
            raise OutputError(
                f"{path}: {width}x{height} masks cannot be written to a video (OpenCV's video "
                f"writer drops the last column or row of an odd size); write them as a folder "
                f"of PNGs or resize the input to an even size (--width {width - width % 2})")
        codec = MASK_VIDEO_CODECS[path.suffix.lower()]
        self._video = VideoFile(path, codec=codec, fps=fps, is_color=False, overwrite=overwrite)
        self._video.open(width, height)
        if codec in LOSSY_CODECS:
            say(f"warning: {path}: {codec} is lossy, mask values will not stay exactly 0/255; "
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
    holds other results) without moving or deleting anything but its old masks. The folder is
    claimed (:class:`OutputClaim`) until the sink is closed: a second run writing masks to it at
    the same time is refused.
    """

    def __init__(self, path: Path, *, width: int, height: int, overwrite: bool = False) -> None:
        super().__init__(path, width=width, height=height)
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise OutputError(f"{path}: cannot prepare the mask folder ({err.strerror})") from None
        self._claim = OutputClaim(path, output=path, folder=True)
        try:
            self._clear(overwrite=overwrite)
        except BaseException:
            self._claim.release()
            raise
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
            raise write_error(self.path / name, "the mask", err) from None
        self._count += 1
        self._last = name

    def _clear(self, *, overwrite: bool) -> None:
        """Remove the folder's old masks (``overwrite``; otherwise there must be none)."""
        try:
            old = [p for p in self.path.iterdir()
                   if MASK_NAME.fullmatch(p.name) or PARTIAL_MASK_NAME.fullmatch(p.name)]
            if not overwrite and any(MASK_NAME.fullmatch(p.name) for p in old):
                raise OutputError(f"{self.path}: already holds masks: another run wrote them "
                                  "meanwhile (--overwrite replaces them)")
            for path in old:
                path.unlink()
        except OSError as err:
            raise OutputError(f"{self.path}: cannot prepare the mask folder "
                              f"({err.strerror})") from None

    def close(self) -> None:
        self._claim.release()  # every PNG is already complete

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
        return MaskVideoSink(output, width=width, height=height, fps=fps, overwrite=overwrite)
    return MaskFolderSink(output, width=width, height=height, overwrite=overwrite)
