"""Patch-motion accuracy of a gated RBM against NCC block matching, on real imagery.

Two test sets, same protocol:

* **Middlebury RubberWhale** (``../shared/data/flow/Middlebury_RubberWhale``: frame10 -> frame11,
  ground truth flow10.flo; skipped with a note when the folder is absent);
* **held-out photographs**: scikit-image photos never used for training
  (:data:`bgsub.model.imagedata.TEST_IMAGES`), each moved globally by a random sub-pixel shift of up
  to ``--max-shift`` px plus a small rotation/zoom (:func:`bgsub.model.imagedata.warped_frame_pair`).

Protocol: 13x13 patches on a grid (stride 4) of frame 1; the ground-truth displacement of a
patch is the ground-truth flow at its centre pixel. A patch counts when its ground truth is
known and the patch is *textured*: :func:`bgsub.model.tiling.texture_score` >= ``--texture`` (default
0.1, i.e. the smaller structure-tensor eigenvalue averaged over the patch is >= 2.2e-4 in
gray-per-pixel^2 units, the top ~30% of RubberWhale's patches; flat patches and single straight
edges fall below). Results are also
given for all non-flat patches (RMS contrast >= 0.02). Both methods see the same patches:

* the model: the patch pair at the same place in both frames, ``model.prepare`` and
  :func:`bgsub.model.readout.patch_displacements` (``max_disp = r``, sub-pixel peak);
* NCC: :func:`bgsub.motion.blockmatch.ncc_block_match` over the same ``[-r, r]^2`` integer range.

Reported: the fraction within 1 px (endpoint error <= 1) and the mean endpoint error.

Usage::

    python benchmarks/middlebury.py                       # the shipped `natural` model
    python benchmarks/middlebury.py --model path/to/model.npz --max-disp 4 --json out.json
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from bgsub.model import readout
from bgsub.motion.blockmatch import ncc_block_match
from bgsub.io.flowio import endpoint_error, read_flo
from bgsub.model.rbm import GatedRBM, load_model
from bgsub.model.tiling import extract_patch_pairs, texture_score, to_gray

MIDDLEBURY = Path(__file__).resolve().parents[2] / "shared" / "data" / "flow" / "Middlebury_RubberWhale"


def _summary(est: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> Dict[str, float]:
    err = endpoint_error(est[mask], gt[mask])
    err = np.where(np.isfinite(err), err, np.inf)  # a method's "no answer" counts as wrong
    finite = np.isfinite(err)
    return {
        "within_1px": float(np.mean(err <= 1.0)) if len(err) else float("nan"),
        "mean_epe": float(np.mean(err[finite])) if finite.any() else float("nan"),
    }


def evaluate_pairs(
    model: GatedRBM,
    pairs: List[tuple],
    *,
    max_disp: int,
    stride: int = 4,
    texture: float = 0.1,
) -> Dict[str, object]:
    """Model and NCC patch displacements on ``pairs`` of ``(frame1, frame2, gt_flow)``.

    Returns
    -------
    dict: ``textured`` and ``all`` sections, each with ``n`` and per-method ``within_1px`` and
    ``mean_epe``; plus ``out_of_range`` (fraction of textured patches whose ground truth lies
    outside ``[-r - 0.5, r + 0.5]^2``, which neither method can get right).
    """
    ests_m, ests_n, gts, tex, nonflat = [], [], [], [], []
    p = model.patch_size
    for frame1, frame2, gt in pairs:
        pp = extract_patch_pairs(frame1, frame2, patch_size=p, stride=stride)
        cx = np.rint(pp.centres[:, 0]).astype(np.int64)
        cy = np.rint(pp.centres[:, 1]).astype(np.int64)
        x, y, flat = model.prepare(pp.x, pp.y)
        disp, _ = readout.patch_displacements(model, x, y, max_disp=max_disp)
        ncc = ncc_block_match(frame1, frame2, max_disp=max_disp, patch_size=p).flow[cy, cx]
        ests_m.append(disp)
        ests_n.append(ncc)
        gts.append(gt[cy, cx])
        tex.append(texture_score(to_gray(frame1), pp.centres, patch_size=p))
        nonflat.append(~flat)
    est_m, est_n, gt = np.concatenate(ests_m), np.concatenate(ests_n), np.concatenate(gts)
    tex, nonflat = np.concatenate(tex), np.concatenate(nonflat)
    known = np.isfinite(gt).all(axis=1)
    textured = known & nonflat & (tex >= texture)
    every = known & nonflat
    out = {}
    for name, mask in (("textured", textured), ("all", every)):
        out[name] = {
            "n": int(mask.sum()),
            "model": _summary(est_m, gt, mask),
            "ncc": _summary(est_n, gt, mask),
        }
    with np.errstate(invalid="ignore"):
        far = (np.abs(gt[textured]) > max_disp + 0.5).any(axis=1)
    out["out_of_range"] = float(far.mean()) if textured.any() else float("nan")
    return out


def middlebury_pairs(folder: Path = MIDDLEBURY) -> Optional[List[tuple]]:
    """RubberWhale frame10 -> frame11 with flow10.flo, or None when the data is absent."""
    import cv2

    if not folder.is_dir():
        return None
    f1 = cv2.imread(str(folder / "frame10.png"))
    f2 = cv2.imread(str(folder / "frame11.png"))
    return [(f1, f2, read_flo(folder / "flow10.flo"))]


def photo_pairs(*, max_shift: float = 3.0, per_image: int = 4, seed: int = 2024) -> List[tuple]:
    """Held-out photos, each moved globally ``per_image`` times (sub-pixel shift, small
    rotation/zoom)."""
    from bgsub.model.imagedata import TEST_IMAGES, load_photos, warped_frame_pair

    rng = np.random.default_rng(seed)
    pairs = []
    for image in load_photos(TEST_IMAGES):
        for _ in range(per_image):
            pairs.append(warped_frame_pair(image, rng, max_shift=max_shift))
    return pairs


def _fmt(section: Dict[str, object]) -> str:
    m, n = section["model"], section["ncc"]
    return (f"n={section['n']:6d}  model {100 * m['within_1px']:5.1f}% within 1px, EPE {m['mean_epe']:.2f}"
            f"  |  NCC {100 * n['within_1px']:5.1f}%, EPE {n['mean_epe']:.2f}")


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--model", default="natural", help="shipped model name or .npz path")
    parser.add_argument("--max-disp", type=int, default=None,
                        help="search range r for both methods (default: the model's range)")
    parser.add_argument("--stride", type=int, default=4, help="patch grid step (default 4)")
    parser.add_argument("--texture", type=float, default=0.1,
                        help="texture_score threshold of a 'textured' patch (default 0.1)")
    parser.add_argument("--max-shift", type=float, default=3.0,
                        help="largest shift of the held-out photo pairs (default 3; rotation/zoom add up to ~2 px at the corners)")
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args(argv)

    from bgsub.motion.flowfield import model_range

    model = load_model(args.model)
    r = args.max_disp if args.max_disp is not None else model_range(model)
    results: Dict[str, object] = {
        "model": args.model, "max_disp": r, "stride": args.stride, "texture": args.texture,
        "machine": f"{platform.machine()} {platform.processor() or ''} ".strip(),
    }
    start = time.perf_counter()
    mb = middlebury_pairs()
    if mb is None:
        print(f"Middlebury data not found at {MIDDLEBURY}: skipped", file=sys.stderr)
    else:
        results["middlebury"] = evaluate_pairs(model, mb, max_disp=r, stride=args.stride, texture=args.texture)
    results["photos"] = evaluate_pairs(model, photo_pairs(max_shift=args.max_shift), max_disp=r,
                                       stride=args.stride, texture=args.texture)
    results["seconds"] = round(time.perf_counter() - start, 1)
    for name in ("middlebury", "photos"):
        if name in results:
            res = results[name]
            print(f"{name}  (r={r}, out of range: {100 * res['out_of_range']:.1f}% of textured)")
            print(f"  textured  {_fmt(res['textured'])}")
            print(f"  all       {_fmt(res['all'])}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
