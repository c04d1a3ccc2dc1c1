"""``bgsub analogy``: apply the motion from X to Y to a new image X2 (paper, Figure 7)."""

from __future__ import annotations

import argparse
from typing import Any

from bgsub.cli.common import check_distinct, model_files, note, warn_if_binary_model
from bgsub.errors import InputError, OutputError

# --zoom enlarges a patch-sized result for viewing (13 px x 64 = 832 px); far more only costs
# memory (--zoom 100000 asked for terabytes). The side limit also bounds zoomed large images.
MAX_ZOOM = 64
MAX_OUTPUT_SIDE = 16384  # bgsub.io.sources.MAX_SIDE (not imported: it would load cv2 for --help)

_DESCRIPTION = """\
Make an analogy with a gated RBM: infer the mapping units from the pair (X, Y) -- how X moved
into Y -- and apply them to X2, giving the image Y2 that X2 would become under the same motion.

Images are read as gray. When X, Y and X2 are exactly one patch (e.g. 13x13) the model is
applied once. Larger images (all three the same size) are processed patch by patch: every patch
of X2 moves the way the patch at the same place moved from X to Y, and overlapping outputs are
blended (so a spatially varying motion is transferred place by place). With --resize the three
images are first shrunk to one patch instead (the whole image is one motion), and Y2 is written
at patch size, enlarged by --zoom for viewing.
Output: 8-bit gray; binary models write probabilities (0-255), Gaussian models intensities.
"""

_EPILOG = """\
examples:
  bgsub analogy x.png y.png x2.png -o y2.png                    (dots-translation model)
  bgsub analogy x.png y.png x2.png -o y2.png --model dots-rotation --zoom 8
  bgsub analogy a.png b.png c.png -o d.png --model natural
"""


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "analogy",
        help="transfer the motion X -> Y onto X2",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("x", metavar="X", help="first image of the example pair")
    parser.add_argument("y", metavar="Y", help="second image of the example pair (X moved)")
    parser.add_argument("x2", metavar="X2", help="image to move the same way")
    parser.add_argument("-o", "--output", required=True, metavar="Y2.png", help="output image")
    parser.add_argument("--model", default="dots-translation",
                        help="shipped model name or .npz path (default dots-translation)")
    parser.add_argument("--resize", action="store_true",
                        help="shrink the images to one patch instead of working patch by patch")
    parser.add_argument("--stride", type=int, default=None, metavar="PX",
                        help="patch step for large images, from 1 to the patch size "
                             "(default patch size // 3)")
    parser.add_argument("--zoom", type=int, default=1, metavar="N",
                        help=f"enlarge the output N times (nearest neighbour), for viewing; 1 to "
                             f"{MAX_ZOOM}, and at most {MAX_OUTPUT_SIDE} px a side (default 1)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing output")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no note on stderr of what was written (warnings and errors are "
                             "still printed)")
    parser.set_defaults(handler=run)


def _read_gray(path: str):
    import cv2
    import numpy as np

    from bgsub.io.flowio import check_image_file
    from bgsub.io.sources import read_image_quietly

    check_image_file(path)
    image = read_image_quietly(path, cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise InputError(f"cannot read image {path}")
    return image.astype(np.float32) / 255.0


# The checks below raise InputError / OutputError rather than using argparse `type=` functions:
# argparse would print its usage block and exit itself, where the project wants one line.

def _check_options(args: argparse.Namespace) -> None:
    """Option values that need no model or image, checked before anything is read."""
    if args.stride is not None and args.stride < 1:
        raise InputError(f"--stride must be at least 1, not {args.stride} "
                         "(omit it for the default, patch size // 3)")
    if not 1 <= args.zoom <= MAX_ZOOM:
        raise InputError(f"--zoom must be from 1 to {MAX_ZOOM}, not {args.zoom}")


def _check_output(args: argparse.Namespace) -> None:
    """Refuse an output that would replace an input or cannot be written, before any work."""
    import cv2

    from bgsub.io.sinks import check_file_output

    check_distinct([args.x, args.y, args.x2] + model_files(args.model), [("-o", args.output)])
    check_file_output(args.output, overwrite=args.overwrite)
    if not cv2.haveImageWriter(args.output):  # decided by the extension alone
        raise OutputError(f"-o: cannot write an image with this extension: {args.output} "
                          "(use .png, .jpg, .bmp, .tif, ...)")


def _check_sizes(args: argparse.Namespace, patch_size: int, width: int, height: int) -> None:
    """Option values that depend on the model and the images."""
    if args.stride is not None and args.stride > patch_size:
        raise InputError(f"--stride {args.stride} is larger than the model's {patch_size}x"
                         f"{patch_size} patches: pixels between them would stay black "
                         f"(use 1 to {patch_size})")
    side = max(width, height)
    if args.zoom > 1 and side * args.zoom > MAX_OUTPUT_SIDE:
        raise InputError(f"--zoom {args.zoom} would make a {width * args.zoom}x{height * args.zoom} "
                         f"image, over the {MAX_OUTPUT_SIDE} px limit; use --zoom "
                         f"{max(1, MAX_OUTPUT_SIDE // side)} or less for {width}x{height}")


def run(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np

    from bgsub.io.flowio import write_image
    from bgsub.model.rbm import load_model
    from bgsub.model.readout import analogy_images

    _check_options(args)
    _check_output(args)
    model = load_model(args.model)
    p = model.patch_size
    images = [_read_gray(path) for path in (args.x, args.y, args.x2)]
    if args.resize:
        images = [cv2.resize(im, (p, p), interpolation=cv2.INTER_AREA) for im in images]
    shapes = {im.shape for im in images}
    if len(shapes) != 1:
        sizes = ", ".join(f"{im.shape[1]}x{im.shape[0]}" for im in images)
        raise InputError(f"X, Y and X2 must have the same size (got {sizes}); or use --resize")
    h, w = images[0].shape
    if h < p or w < p:
        raise InputError(f"images are {w}x{h}, smaller than the model's {p}x{p} patches; use --resize")
    _check_sizes(args, p, w, h)
    warn_if_binary_model(model, images[0], what=args.x)
    result = analogy_images(model, *images, stride=args.stride)
    picture = np.clip(np.rint(result * 255.0), 0, 255).astype(np.uint8)
    if args.zoom > 1:
        picture = np.kron(picture, np.ones((args.zoom, args.zoom), np.uint8))
    write_image(args.output, picture)
    zoomed = (f" ({picture.shape[1]}x{picture.shape[0]} with --zoom {args.zoom})"
              if args.zoom > 1 else "")
    note(f"analogy of {w}x{h} written to {args.output}{zoomed}", quiet=args.quiet)
    return 0
