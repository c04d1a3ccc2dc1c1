"""A hash of every mask the engines make on the development data: proof that a change of code
left every mask as it was.

For each method (``grbm`` with ``overlap`` 0 and 1 and with ``--preset fast``, ``compensated``
with ``overlap`` 0 and 1, and ``mog2``) it runs every sequence of ``../shared/data/real``,
``../shared/data/generated`` and the in-memory ``bgsub samples`` scenes (every category, seeds
0-2) from its first frame and hashes each mask (SHA-256 over the masks' bytes in order). It
writes one JSON object ``{method: {sequence: hash}}``; two runs are compared with ``--compare``.
It uses only the public API (``bgsub.create_engine``, ``bgsub.samples``), so the same script
runs on both sides of a refactoring.

Usage (about 20 minutes on 2 cores)::

    python benchmarks/mask_hashes.py -o before.json            # on the old head
    python benchmarks/mask_hashes.py -o after.json             # on the new head
    python benchmarks/mask_hashes.py --compare before.json after.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
METHODS = {
    "grbm/overlap=0": ("grbm", {"overlap": 0}),
    "grbm/overlap=1": ("grbm", {"overlap": 1}),
    "grbm/fast": ("grbm", {"preset": "fast"}),
    "compensated/overlap=0": ("compensated", {"overlap": 0}),
    "compensated/overlap=1": ("compensated", {"overlap": 1}),
    "mog2": ("mog2", {}),
}


def sequences() -> list:
    """``(name, source)`` of every sequence: a folder of frames, or ``("sample", category, seed)``."""
    out = []
    for family in ("real", "generated"):
        root = DATA / family
        if root.is_dir():
            out += [(f"{family}/{p.parent.relative_to(root)}", str(p.parent))
                    for p in sorted(root.glob("**/input"))]
    from bgsub.samples import CATEGORIES

    out += [(f"samples/{c}_s{s}", ("sample", c, s)) for c in CATEGORIES for s in (0, 1, 2)]
    return out


def frames(source):
    if isinstance(source, tuple):
        from bgsub.samples import SceneSpec, render_frames

        for frame in render_frames(SceneSpec(source[1], seed=source[2])):
            yield frame.image
        return
    files = sorted(Path(source, "input").glob("in*.jpg")) + sorted(
        Path(source, "input").glob("in*.png"))
    for path in files:
        yield cv2.imread(str(path), cv2.IMREAD_COLOR)


def hash_masks(job: tuple) -> tuple:
    label, name, source = job
    from bgsub import create_engine

    method, params = METHODS[label]
    engine = create_engine(method, **params)
    digest = hashlib.sha256()
    for image in frames(source):
        digest.update(engine.apply(image).tobytes())
    engine.close()
    return label, name, digest.hexdigest()


def run(out: Path, methods: list, jobs: int, match: str = "") -> None:
    work = [(m, name, src) for m in methods for name, src in sequences() if match in name]
    result: dict = {m: {} for m in methods}
    with ProcessPoolExecutor(jobs) as pool:
        for i, (label, name, digest) in enumerate(pool.map(hash_masks, work), 1):
            result[label][name] = digest
            print(f"[{i}/{len(work)}] {label} {name} {digest[:12]}", file=sys.stderr)
    out.write_text(json.dumps(result, indent=1, sort_keys=True) + "\n")


def compare(a: Path, b: Path) -> int:
    old, new = json.loads(a.read_text()), json.loads(b.read_text())
    # Only what both runs hashed (a run may cover a subset: --match, --methods).
    pairs = [(m, s) for m in new for s in new[m] if s in old.get(m, {})]
    differ = [(m, s) for m, s in pairs if new[m][s] != old[m][s]]
    n = len(pairs)
    for m, s in differ:
        print(f"differs: {m} {s}")
    print(f"{n - len(differ)} of {n} mask sequences identical")
    return 1 if differ else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", type=Path, help="JSON file to write the hashes to")
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--jobs", type=int, default=2, help="sequences hashed at once (processes)")
    ap.add_argument("--match", default="", help="only sequences whose name contains this")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("OLD", "NEW"))
    args = ap.parse_args()
    if args.compare:
        return compare(*args.compare)
    if not args.out:
        ap.error("give -o FILE (or --compare OLD NEW)")
    run(args.out, args.methods, args.jobs, args.match)
    return 0


if __name__ == "__main__":
    sys.exit(main())
