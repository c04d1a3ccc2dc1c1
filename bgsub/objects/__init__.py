"""Objects in the masks: connected foreground regions, tracked across frames.

The next layer after a foreground mask (the Object Semantic Hierarchy's 2D objects in 2D
space): :mod:`bgsub.objects.tracker` finds each frame's regions and keeps their ids from frame
to frame; :mod:`bgsub.objects.writer` writes them (JSON lines or a MOTChallenge CSV) as a
consumer of :class:`bgsub.io.loop.FrameLoop`, and draws them into ``--vis``.
"""

from bgsub.objects.tracker import ObjectTracker, TrackedObject, TrackerConfig, find_regions
from bgsub.objects.writer import ObjectSink, ObjectVisWriter, ObjectWriter, check_objects_output

__all__ = ["ObjectSink", "ObjectTracker", "ObjectVisWriter", "ObjectWriter", "TrackedObject",
           "TrackerConfig", "check_objects_output", "find_regions"]
