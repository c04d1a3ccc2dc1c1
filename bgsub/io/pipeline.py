"""One output pipeline: the files a run writes for one input, checked, opened and closed
together. ``bgsub run`` (one input), every input of a batch and :func:`process` (the Python API)
all go through here, so they accept the same outputs and write the same files.

An :class:`OutputRequest` names the outputs by kind (:data:`KINDS`); :meth:`OutputRequest.check`
refuses bad ones before any frame is read, :meth:`OutputRequest.open` opens their sinks and
:func:`writers` turns sinks into the frame loop's consumers, in the order the outputs need
(objects are tracked before ``vis`` draws them).
"""

from __future__ import annotations

import contextlib
from dataclasses import asdict, dataclass
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Tuple

import numpy as np

from bgsub.io.frame_stats import StatsSink, StatsWriter, check_stats_output
from bgsub.io.loop import Consumer, FrameLoop, RunStats
from bgsub.io.mask_sinks import open_mask_sink
from bgsub.io.motion_sink import MotionSink
from bgsub.io.outputs import check_mask_output, check_motion_output, check_video_output
from bgsub.io.picture_sinks import VideoSink, VisSink
from bgsub.io.writers import (DebugImageWriter, FrameCallback, MaskWriter, MotionWriter,
                              VisWriter)

#: The kinds of output, in the order of their writers in the frame loop.
KINDS = ("masks", "objects", "vis", "flow_vis", "motion", "stats")


_WRITERS: Dict[str, Callable[..., Consumer]] = {
    "masks": MaskWriter, "vis": VisWriter, "flow_vis": DebugImageWriter, "motion": MotionWriter,
    "stats": StatsWriter}


@dataclass(frozen=True)
class OutputRequest:
    """The outputs of one input: a path per kind (None: not written), and how to write them.

    Attributes
    ----------
    masks : str
        Mask video or folder (:func:`bgsub.io.mask_sinks.open_mask_sink`).
    vis, flow_vis : str, optional
        Picture videos: the input with its mask, and the engine's ``debug_image()``.
    motion : str, optional
        The camera motion, ``.npy``.
    objects : str, optional
        The tracked objects, ``.jsonl`` or MOTChallenge ``.csv``.
    stats : str, optional
        Per-frame statistics, ``.csv`` (:mod:`bgsub.io.frame_stats`).
    codec : str
        Codec of the ``.mp4`` picture videos: ``auto``, ``h264`` or ``mp4v``.
    min_object_area : int, optional
        The tracker's smallest object (pixels); its default when None.
    overwrite : bool
        Replace existing outputs.
    """

    masks: str
    vis: Optional[str] = None
    flow_vis: Optional[str] = None
    motion: Optional[str] = None
    objects: Optional[str] = None
    stats: Optional[str] = None
    codec: str = "auto"
    min_object_area: Optional[int] = None
    overwrite: bool = False

    def paths(self) -> Dict[str, str]:
        """``{kind: path}`` of the outputs asked for, masks first."""
        given = asdict(self)
        return {kind: str(given[kind]) for kind in ("masks", "vis", "flow_vis", "motion",
                                                    "objects", "stats") if given[kind]}

    def check(self) -> None:
        """Refuse, before any frame is read, an output that cannot be written (see the
        ``check_*_output`` functions); nothing is written."""
        from bgsub.objects import check_objects_output

        checks = {"masks": check_mask_output, "motion": check_motion_output,
                  "objects": check_objects_output, "stats": check_stats_output,
                  "vis": check_video_output, "flow_vis": check_video_output}
        for kind, path in self.paths().items():
            checks[kind](path, overwrite=self.overwrite)

    def open(self, stack: contextlib.ExitStack, *, width: int, height: int,
             fps: float) -> Dict[str, Any]:
        """Open the sinks in ``stack`` (a failure to open one closes the others) and return
        them by kind."""
        from bgsub.objects import ObjectSink

        paths, overwrite = self.paths(), self.overwrite
        size = dict(width=width, height=height, fps=fps, overwrite=overwrite)
        openers: Dict[str, Callable[[str], Any]] = {
            "masks": lambda path: open_mask_sink(path, **size),
            "vis": lambda path: VisSink(path, **size, codec=self.codec),
            "flow_vis": lambda path: VideoSink(path, fps=fps, overwrite=overwrite,
                                               codec=self.codec),
            "motion": lambda path: MotionSink(path, overwrite=overwrite),
            "objects": lambda path: ObjectSink(path, overwrite=overwrite),
            "stats": lambda path: StatsSink(path, overwrite=overwrite),
        }
        return {kind: stack.enter_context(openers[kind](path)) for kind, path in paths.items()}

    def tracker(self) -> Any:
        """The tracker's settings (:class:`bgsub.objects.TrackerConfig`)."""
        from bgsub.objects import TrackerConfig

        if self.min_object_area is None:
            return TrackerConfig()
        return TrackerConfig(min_area=self.min_object_area)


def writers(sinks: Mapping[str, Any], *, tracker: Any = None,
            engine: Optional[str] = None) -> List[Consumer]:
    """The frame loop's consumers of ``sinks`` (by kind, :data:`KINDS`): with objects, the
    ``vis`` video draws their boxes and ids. ``tracker``: a
    :class:`bgsub.objects.TrackerConfig`; ``engine``: the engine whose results they write
    (None: the loop's only engine)."""
    from bgsub.objects import ObjectVisWriter, ObjectWriter, TrackerConfig

    made: Dict[str, Consumer] = {}
    for kind in (kind for kind in KINDS if kind in sinks):  # (objects before vis draws them)
        if kind == "objects":
            made[kind] = ObjectWriter(sinks[kind], engine=engine,
                                      config=tracker or TrackerConfig())
        elif kind == "vis" and "objects" in made:
            made[kind] = ObjectVisWriter(sinks[kind], objects=made["objects"], engine=engine)
        else:
            made[kind] = _WRITERS[kind](sinks[kind], engine=engine)
    return list(made.values())


def open_outputs(stack: contextlib.ExitStack, request: OutputRequest, *, width: int,
                 height: int, fps: float) -> Tuple[List[Consumer], Dict[str, str]]:
    """Open ``request``'s outputs in ``stack``; ``(consumers, codecs)``: the frame loop's
    writers, and the codec each picture video is written in (``{"vis": "h264"}``)."""
    sinks = request.open(stack, width=width, height=height, fps=fps)
    codecs = {kind: sinks[kind].codec for kind in ("vis", "flow_vis") if kind in sinks}
    return writers(sinks, tracker=request.tracker()), codecs


def process(frames: Iterable[Tuple[int, np.ndarray]], engine: Any, masks: Any, *,
            vis: Any = None, flow_vis: Any = None, motion: Any = None, objects: Any = None,
            stats: Any = None, on_frame: Optional[Callable[[int, np.ndarray], None]] = None
            ) -> RunStats:
    """Run ``engine`` over ``frames`` and write its masks (and the other outputs) to the
    sinks, then finish the sinks.

    Parameters
    ----------
    frames : iterable of (int, (H, W, 3) uint8)
        ``(index, frame)`` pairs, e.g. a :class:`bgsub.io.sources.FrameSource`.
    engine : Engine
        Anything with OpenCV's ``apply(image) -> (H, W) uint8 mask``.
    masks : MaskSink
        Gets every mask, with its frame index.
    vis : VisSink, optional
        Gets every frame with its mask (and the objects' boxes, with ``objects``).
    flow_vis : VideoSink, optional
        Gets ``engine.debug_image()`` after every frame (see :class:`DebugImageWriter`).
    motion : MotionSink, optional
        Gets ``engine.last_motion`` after every frame.
    objects : ObjectSink, optional
        Gets the tracked objects of every frame (:mod:`bgsub.objects`).
    stats : StatsSink, optional
        Gets a row of per-frame statistics (:mod:`bgsub.io.frame_stats`).
    on_frame : callable(index, mask), optional
        Called after every frame is written.

    Returns
    -------
    RunStats

    The sinks are finished when the run ends, also by an error or Ctrl-C (partial but valid
    outputs); open them in ``with`` blocks all the same, so that a failure to open a later one
    closes the earlier ones (:meth:`OutputRequest.open` does).
    """
    given = dict(masks=masks, vis=vis, flow_vis=flow_vis, motion=motion, objects=objects,
                 stats=stats)
    consumers = writers({kind: sink for kind, sink in given.items() if sink is not None})
    consumers += [FrameCallback(on_frame)] if on_frame is not None else []
    return FrameLoop(engine, consumers).run(frames)
