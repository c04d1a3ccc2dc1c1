"""``python slow_engine.py ARGS`` is ``bgsub ARGS`` with the test engine ``_test_slow``
registered: mog2 that waits ``delay`` seconds per frame and, when built, leaves a file named
after its process id in the folder ``pids`` (the workers a fault test may kill).

Worker processes see the engine too: a local batch's workers are started with "spawn" and run
this file as their main module, and a Dask cluster's workers are given it as a preload."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from bgsub.engines import Engine, Param, register_engine


class _Slow(Engine):
    def __init__(self, delay: float, pids: str) -> None:
        self.engine = cv2.createBackgroundSubtractorMOG2()
        self.delay = delay
        if pids:
            (Path(pids) / str(os.getpid())).touch()

    def apply(self, image, fgmask=None, learning_rate=-1.0):
        time.sleep(self.delay)
        return np.where(self.engine.apply(image) > 127, 255, 0).astype(np.uint8)


register_engine("_test_slow", "test: mog2 that waits between frames",
                params={"delay": Param(0.05, "seconds per frame"),
                        "pids": Param("", "folder of the workers' process ids")})(_Slow)

if __name__ == "__main__":
    from bgsub.cli import main

    sys.exit(main(sys.argv[1:]))
