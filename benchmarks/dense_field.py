"""The dense field `bgsub flow` writes, against Middlebury RubberWhale's ground truth.

Usage: python benchmarks/dense_field.py [DATA_DIR]   (default ../shared/data/flow)

For each pyramid setting, patch stride and texture threshold (the other settings are
FlowConfig's defaults, those of bgsub flow; the last row is bgsub flow's own): the share of
pixels with a value (the rest are NaN: no valid patch covers them), and over the pixels with a
value and a ground truth the mean end-point error and the share within 1 px.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from bgsub.motion import FlowConfig, estimate_flow
from bgsub.io.flowio import read_flo
from bgsub.model.rbm import load_model

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "flow"


def main(argv: list) -> int:
    data = Path(argv[0]) if argv else DATA
    frame10 = next(data.glob("**/frame10.png"), None)
    if frame10 is None:
        print(f"no frame10.png under {data}", file=sys.stderr)
        return 2
    first, second = cv2.imread(str(frame10)), cv2.imread(str(frame10.with_name("frame11.png")))
    truth = read_flo(next(data.glob("**/flow10.flo")))
    has_truth = np.isfinite(truth).all(axis=2)
    model = load_model("natural")
    print("| levels | stride | min_texture | pixels with a value | EPE (px) | within 1 px |")
    print("|---|---|---|---|---|---|")
    default = FlowConfig()
    for levels, stride, min_texture in ((1, 6, 0.0), (1, 3, 0.0), (None, 6, 0.0), (None, 3, 0.0),
                                        (None, default.stride, default.min_texture)):
        # The rest as bgsub flow reads (RubberWhale's motions are within 4 px: FlowConfig's
        # search reaches them, no wider one is needed).
        config = FlowConfig(dense=True, min_texture=min_texture, levels=levels or 0,
                            stride=stride, warn_range=False)
        dense = estimate_flow(first, second, config, model=model).dense
        known = np.isfinite(dense).all(axis=2)
        both = known & has_truth
        error = np.hypot(*(dense[both] - truth[both]).T)
        print(f"| {levels or '(auto)'} | {stride} | {min_texture:g} | {known.mean():.1%} | "
              f"{error.mean():.3f} | {(error < 1).mean():.1%} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
