"""The engines' threads reuse freed memory: a frame-sized array freed in one frame is reused by
the next instead of being returned to the kernel and faulted in again."""

from __future__ import annotations

import platform
import subprocess
import sys
import textwrap

import pytest
from helpers import write_pan_clip

from bgsub.engines.threads import reuse_freed_memory

GLIBC = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"

# Decodes the clip given as argv[1] frame by frame (as `bgsub run` reads a video) into a `grbm`
# engine with its second thread, and prints the mean minor page faults of frames 10 to 29.
_COUNT_FAULTS = textwrap.dedent("""
    import os, resource, sys
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import cv2
    from bgsub import create_engine

    engine = create_engine("grbm", overlap=1)
    cap = cv2.VideoCapture(sys.argv[1])
    counts = []
    for k in range(30):
        ok, frame = cap.read()
        assert ok, k
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        engine.apply(frame)
        if k >= 10:
            counts.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
    print(sum(counts) / len(counts))
""")


def test_reuse_freed_memory_reports_whether_malloc_took_the_settings():
    assert reuse_freed_memory() is GLIBC
    assert reuse_freed_memory() is GLIBC  # once per process; later calls say the same


@pytest.mark.skipif(not GLIBC, reason="the malloc settings are glibc's")
def test_a_decoded_clip_does_not_fault_its_pages_in_every_frame(tmp_path):
    # Without the settings glibc returns the engine's freed 320x240 arrays to the kernel: 700
    # to 2,400 page faults per frame in this run (5 ms of system time per frame); with them a
    # handful.
    clip = write_pan_clip(tmp_path / "pan.avi", n=30)
    done = subprocess.run([sys.executable, "-c", _COUNT_FAULTS, str(clip)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout) < 100.0
