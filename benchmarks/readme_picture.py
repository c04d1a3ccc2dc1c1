"""The README's picture, ``docs/overlay.png``: one frame of the bundled sample
``samples/pan.mp4`` with grbm's mask overlaid, beside the mask.

Usage (a few seconds)::

    python benchmarks/readme_picture.py                    # frame 80 -> docs/overlay.png
    python benchmarks/readme_picture.py --frame 100 -o /tmp/overlay.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2

import bgsub
from bgsub.io.picture_sinks import render_overlay
from bgsub.io.sources import open_source
from bgsub.samples import bundled_sample

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frame", type=int, default=80, help="0-based frame to show")
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "overlay.png")
    args = parser.parse_args()
    engine = bgsub.create_engine("grbm")
    with open_source(str(bundled_sample()), stop=args.frame + 1) as source:
        for _, frame in source:
            mask = engine.apply(frame)
    engine.close()
    # PNG's strongest compression: the picture stays a few tens of KB.
    cv2.imwrite(str(args.output), render_overlay(frame, mask), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {args.output} ({args.output.stat().st_size // 1024} KB)")


if __name__ == "__main__":
    main()
