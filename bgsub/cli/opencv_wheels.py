"""A warning when OpenCV's GUI and headless wheels are both installed.

bgsub depends on ``opencv-python-headless``. Installed beside ``opencv-python`` or
``opencv-contrib-python``, the two write the same ``cv2`` module: the last one installed wins,
``cv2.imshow`` may stop working, and uninstalling either leaves ``cv2`` broken. Only package
metadata is read (no import), so the check costs a command's start next to nothing.
"""

from __future__ import annotations

import importlib.metadata
import sys
from typing import Callable, List, Optional

#: OpenCV's wheels with a GUI (highgui), and without.
GUI_WHEELS = ("opencv-python", "opencv-contrib-python")
HEADLESS_WHEELS = ("opencv-python-headless", "opencv-contrib-python-headless")

_warned = False


def _installed(names: tuple, version: Callable[[str], str]) -> List[str]:
    found = []
    for name in names:
        try:
            version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        found.append(name)
    return found


def clash_message(version: Optional[Callable[[str], str]] = None) -> Optional[str]:
    """The warning when a GUI and a headless OpenCV wheel are both installed, else None;
    ``version`` looks a distribution up (default :func:`importlib.metadata.version`)."""
    version = version or importlib.metadata.version
    gui, headless = _installed(GUI_WHEELS, version), _installed(HEADLESS_WHEELS, version)
    if not (gui and headless):
        return None
    both = " ".join(gui + headless)
    return (f"{' and '.join(gui + headless)} are installed together and overwrite each "
            f"other's cv2 (cv2.imshow may fail); keep one: pip uninstall -y {both}; pip install "
            f"{gui[0]} (bgsub runs with it: README.md, 'Next to opencv-python')")


def warn_once() -> None:
    """Print :func:`clash_message` once per process, as a ``bgsub: warning:`` line."""
    global _warned
    if _warned:
        return
    _warned = True
    message = clash_message()
    if message:
        print(f"bgsub: warning: {message}", file=sys.stderr)
