"""bgsub: moving-camera background subtraction with a factored gated RBM.

The public Python API; the ``bgsub`` command is a thin layer over it. Every engine has the shape
of OpenCV's ``BackgroundSubtractor``::

    import cv2
    import bgsub

    engine = bgsub.create_engine("grbm")          # or "compensated", "mog2", "knn", "framediff"
    cap = cv2.VideoCapture("samples/pan.mp4")     # bgsub.samples.bundled_sample() is its path
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        mask = engine.apply(frame)                # (H, W) uint8: 0 background, 255 foreground
    camera = engine.last_motion                   # (3, 3) camera motion into the last frame

``bgsub.available_engines()`` lists the engines and their parameters (``bgsub methods``);
``bgsub.io.sources.open_source`` reads files, folders, globs, cameras and URLs;
``bgsub.io.loop.FrameLoop`` streams frames through engines into sinks; ``bgsub.evaluation``
scores masks by CDnet 2014 rules; ``bgsub.samples`` makes scenes with exact ground truth. Errors
a caller can act on are :class:`BgsubError` subclasses. More: docs/python-api.md.
"""

__version__ = "0.1.0"

from typing import Any

from bgsub.errors import BgsubError, InputError, ModelError, OutputError, ProcessingError

_ENGINE_API = ("Engine", "Param", "available_engines", "create_engine", "register_engine")


def __getattr__(name: str) -> Any:
    # The engine API (numpy, OpenCV) loads on first use: `bgsub --help` starts fast, and a
    # Ctrl-C while the command starts is the CLI's clean "interrupted", not a traceback.
    if name in _ENGINE_API:
        from bgsub import engines

        return getattr(engines, name)
    raise AttributeError(f"module 'bgsub' has no attribute {name!r}")


def __dir__() -> list:
    # dir() and help() list the lazy engine API too (without importing it).
    return sorted(set(globals()) | set(_ENGINE_API))


__all__ = [
    "__version__",
    "Engine",
    "Param",
    "available_engines",
    "create_engine",
    "register_engine",
    "BgsubError",
    "InputError",
    "ModelError",
    "OutputError",
    "ProcessingError",
]
