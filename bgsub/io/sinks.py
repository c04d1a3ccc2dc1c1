"""Sinks: where masks, pictures and camera motion go (one import for all of them).

* :func:`open_mask_sink` -- foreground masks, ``(H, W) uint8`` 0/255, as a lossless video
  (``.mkv`` / ``.avi``: FFV1, so 0 and 255 come back exactly) or a CDnet-style folder of
  ``binNNNNNN.png`` (:mod:`bgsub.io.mask_sinks`); ``.mp4`` works too but is lossy (a warning
  says so).
* :class:`VideoSink`, :class:`VisSink` -- colour pictures, and the input with its mask overlaid
  beside the mask (:mod:`bgsub.io.picture_sinks`).
* :class:`MotionSink` -- the camera motion of every frame (:mod:`bgsub.io.motion_sink`).
* ``check_*_output`` -- the checks run before anything is written (:mod:`bgsub.io.outputs`).
* :func:`process` -- stream frames through an engine into these sinks (:mod:`bgsub.io.pipeline`,
  over the frame loop of :mod:`bgsub.io.loop`).

Every sink is a context manager that writes under a temporary name in the output's folder and
renames it to the final name when finished. Finishing also happens when the ``with`` block ends
by an exception or Ctrl-C, so a partial video is still a valid, playable file; the sink then says
on stderr that the output is partial and how many frames it holds. An existing output is refused
(:class:`bgsub.errors.OutputError`) unless ``overwrite=True``, and so is an output another run is
writing at the same moment. A full disk stops the run with a
:class:`bgsub.errors.ProcessingError` naming the output; a video it left unplayable is removed,
never given its final name.
"""

from bgsub.io.loop import RunStats, hold_interrupts
from bgsub.io.mask_sinks import MaskFolderSink, MaskSink, MaskVideoSink, open_mask_sink
from bgsub.io.motion_sink import MotionSink
from bgsub.io.outputs import (
    MASK_NAME,
    MASK_VIDEO_CODECS,
    PARTIAL_MASK_NAME,
    PICTURE_VIDEO_CODECS,
    PathLike,
    check_file_output,
    check_mask_output,
    check_motion_output,
    check_video_output,
    is_video_path,
    names_a_folder,
    write_atomically,
)
from bgsub.io.picture_sinks import VideoSink, VisSink, render_overlay
from bgsub.io.sink_base import Sink
from bgsub.io.pipeline import process

# The names bgsub.evaluation.compare imports.
_MASK_NAME, _PARTIAL_MASK_NAME = MASK_NAME, PARTIAL_MASK_NAME

__all__ = [
    "MASK_VIDEO_CODECS", "PICTURE_VIDEO_CODECS", "MaskFolderSink", "MaskSink", "MaskVideoSink",
    "MotionSink", "PathLike", "RunStats", "Sink", "VideoSink", "VisSink", "check_file_output",
    "check_mask_output", "check_motion_output", "check_video_output", "hold_interrupts",
    "is_video_path", "names_a_folder", "open_mask_sink", "process", "render_overlay",
    "write_atomically",
]
