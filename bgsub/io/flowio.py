"""Optical-flow files and pictures: Middlebury ``.flo`` I/O, the colour wheel (and its legend),
arrows, errors.

Flow fields follow the project convention (docs/ARCHITECTURE.md): ``(H, W, 2) float32`` with
``flow[y, x] = (dx, dy)`` = Middlebury's ``(u, v)``, NaN where unknown.

The ``.flo`` format (Baker et al., IJCV 2011) is a float32 tag ``202021.25``, int32 width, int32
height, then ``height * width`` interleaved ``(u, v)`` float32 pairs, row-major, little-endian.
Unknown flow is stored as a value above ``1e9``; this module writes NaN as ``1e10`` and reads any
component above ``1e9`` (in magnitude) as unknown.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Optional, Sequence, Tuple, Union

import cv2
import numpy as np

from bgsub.errors import InputError, OutputError
from bgsub.io.sinks import write_atomically
from bgsub.io.sources import VIDEO_SUFFIXES, decode_image

PathLike = Union[str, "os.PathLike[str]"]

FLO_TAG = np.float32(202021.25)
#: Components above this magnitude mean "unknown" in a .flo file.
UNKNOWN_THRESHOLD = 1e9
#: What :func:`write_flo` stores for an unknown (NaN) vector.
UNKNOWN_VALUE = np.float32(1e10)
# Sanity bound on the header: a corrupt header must not make us allocate terabytes.
_MAX_SIDE = 1 << 16


def read_flo(path: PathLike) -> np.ndarray:
    """Read a Middlebury ``.flo`` file.

    Parameters
    ----------
    path : str or path-like
        The ``.flo`` file.

    Returns
    -------
    (H, W, 2) float32 array
        ``(u, v) = (dx, dy)`` per pixel; both components NaN where the file marks the vector
        unknown (either component above 1e9 in magnitude).

    Raises
    ------
    InputError
        The file is missing or unreadable, has a wrong tag, an impossible size, or is truncated.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise InputError(f"flow file not found: {p}") from None
    except OSError as err:
        raise InputError(f"cannot read flow file {p}: {err.strerror or err}") from None
    if len(raw) < 12:
        raise InputError(f"not a .flo file (only {len(raw)} bytes, header needs 12): {p}")
    tag = np.frombuffer(raw, dtype="<f4", count=1)[0]
    if tag != FLO_TAG:
        raise InputError(f"not a .flo file (tag {float(tag):g}, expected 202021.25): {p}")
    width, height = (int(v) for v in np.frombuffer(raw, dtype="<i4", count=2, offset=4))
    if not (0 < width <= _MAX_SIDE and 0 < height <= _MAX_SIDE):
        raise InputError(f"corrupt .flo header (size {width}x{height}): {p}")
    expected = 12 + 8 * width * height
    if len(raw) < expected:
        raise InputError(
            f"truncated .flo file ({len(raw)} bytes, {width}x{height} needs {expected}): {p}"
        )
    flow = np.frombuffer(raw, dtype="<f4", count=2 * width * height, offset=12)
    flow = flow.reshape(height, width, 2).astype(np.float32)  # copy: writable, native order
    unknown = ~(np.abs(flow) <= UNKNOWN_THRESHOLD).all(axis=2)  # also catches NaN/inf in file
    flow[unknown] = np.nan
    return flow


def write_flo(path: PathLike, flow: np.ndarray, *, overwrite: bool = False) -> Path:
    """Write a flow field as a Middlebury ``.flo`` file (NaN vectors stored as unknown).

    The file is written under a temporary name and renamed, so a failed write never leaves a
    partial ``.flo`` behind.

    Parameters
    ----------
    path : str or path-like
        Output file.
    flow : (H, W, 2) float array
        ``(u, v)`` per pixel; a vector with any NaN component is written as unknown (1e10).
    overwrite : bool
        Replace an existing file (refused otherwise).

    Returns
    -------
    Path of the written file.

    Raises
    ------
    OutputError
        The file exists (without ``overwrite``) or cannot be written.
    ValueError
        ``flow`` is not an ``(H, W, 2)`` array, or is empty (a programming error, not user
        input).
    """
    flow = np.asarray(flow)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise ValueError(f"flow must be (H, W, 2), got shape {flow.shape}")
    if flow.shape[0] < 1 or flow.shape[1] < 1:
        raise ValueError(f"flow is empty (shape {flow.shape}): a .flo file holds at least "
                         "one pixel")
    p = Path(path)
    if p.exists() and not overwrite:
        raise OutputError(f"{p}: already exists (overwrite=True, or --overwrite on the command "
                          "line, replaces it)")
    data = flow.astype("<f4", copy=True)
    data[~np.isfinite(data).all(axis=2)] = UNKNOWN_VALUE
    height, width = data.shape[:2]
    header = FLO_TAG.astype("<f4").tobytes() + np.array([width, height], "<i4").tobytes()
    write_atomically(p, header + data.tobytes(), what="flow file")
    return p


def _make_color_wheel() -> np.ndarray:
    """The Middlebury colour wheel: (55, 3) float64 RGB in [0, 255].

    Segment lengths chosen by Baker et al. for perceptual uniformity: red-yellow 15,
    yellow-green 6, green-cyan 4, cyan-blue 11, blue-magenta 13, magenta-red 6.
    """
    ry, yg, gc, cb, bm, mr = 15, 6, 4, 11, 13, 6
    wheel = np.zeros((ry + yg + gc + cb + bm + mr, 3))
    col = 0
    wheel[col:col + ry, 0] = 255
    wheel[col:col + ry, 1] = np.floor(255 * np.arange(ry) / ry)
    col += ry
    wheel[col:col + yg, 0] = 255 - np.floor(255 * np.arange(yg) / yg)
    wheel[col:col + yg, 1] = 255
    col += yg
    wheel[col:col + gc, 1] = 255
    wheel[col:col + gc, 2] = np.floor(255 * np.arange(gc) / gc)
    col += gc
    wheel[col:col + cb, 1] = 255 - np.floor(255 * np.arange(cb) / cb)
    wheel[col:col + cb, 2] = 255
    col += cb
    wheel[col:col + bm, 2] = 255
    wheel[col:col + bm, 0] = np.floor(255 * np.arange(bm) / bm)
    col += bm
    wheel[col:col + mr, 2] = 255 - np.floor(255 * np.arange(mr) / mr)
    wheel[col:col + mr, 0] = 255
    return wheel


_COLOR_WHEEL = _make_color_wheel()


def _check_max_magnitude(max_magnitude: Optional[float]) -> None:
    # Written so that NaN fails too (every comparison with NaN is false).
    if max_magnitude is not None and not 0 < float(max_magnitude) < math.inf:
        raise InputError(f"max_magnitude must be a number of pixels above 0 (None: the largest "
                         f"in the field), not {max_magnitude!r}")


def colour_scale(flow: np.ndarray, *, max_magnitude: Optional[float] = None) -> float:
    """The magnitude (pixels) :func:`flow_to_color` shows at full saturation: ``max_magnitude``
    when given, else the largest known magnitude in ``flow`` ((H, W, 2); 0 when none is
    known)."""
    if max_magnitude is not None:
        return float(max_magnitude)
    flow = np.asarray(flow, dtype=np.float64)
    known = np.isfinite(flow).all(axis=2)
    return float(np.hypot(flow[known, 0], flow[known, 1]).max()) if known.any() else 0.0


def flow_to_color(flow: np.ndarray, *, max_magnitude: Optional[float] = None) -> np.ndarray:
    """Colour-code a flow field with the Middlebury colour wheel (Baker et al.).

    Hue gives the direction (right = red, down = yellow, left = cyan, up = blue/violet), saturation
    the magnitude relative to ``max_magnitude`` (zero motion is white; vectors longer than
    ``max_magnitude`` are drawn darker). Unknown (NaN) vectors are black.

    Parameters
    ----------
    flow : (H, W, 2) float array
        ``(u, v)`` per pixel, NaN where unknown.
    max_magnitude : float, optional
        Magnitude shown at full saturation, a finite number above 0; None (the default): the
        largest known magnitude in ``flow``.

    Returns
    -------
    (H, W, 3) uint8 BGR image (OpenCV's channel order, ready for ``cv2.imwrite``).

    Raises
    ------
    InputError
        ``max_magnitude`` is 0, negative, NaN or infinite (``bgsub flow --max-magnitude``
        refuses the same values).
    """
    _check_max_magnitude(max_magnitude)
    flow = np.asarray(flow, dtype=np.float64)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise ValueError(f"flow must be (H, W, 2), got shape {flow.shape}")
    known = np.isfinite(flow).all(axis=2)
    u = np.where(known, flow[..., 0], 0.0)
    v = np.where(known, flow[..., 1], 0.0)
    rad = np.hypot(u, v)
    scale = max(colour_scale(flow, max_magnitude=max_magnitude), np.finfo(np.float64).eps)
    u, v, rad = u / scale, v / scale, rad / scale

    n_cols = len(_COLOR_WHEEL)
    angle = np.arctan2(-v, -u) / np.pi  # in [-1, 1]
    fk = (angle + 1) / 2 * (n_cols - 1)
    k0 = np.floor(fk).astype(np.int64)
    k1 = (k0 + 1) % n_cols
    frac = (fk - k0)[..., None]
    color = (1 - frac) * _COLOR_WHEEL[k0] / 255 + frac * _COLOR_WHEEL[k1] / 255
    inside = (rad <= 1)[..., None]
    # Inside the unit circle: blend towards white as the magnitude shrinks; outside: darken.
    color = np.where(inside, 1 - rad[..., None] * (1 - color), color * 0.75)
    rgb = np.floor(255 * color).astype(np.uint8)
    rgb[~known] = 0
    return np.ascontiguousarray(rgb[..., ::-1])


def colour_wheel(max_magnitude: float, *, size: int = 64) -> Tuple[np.ndarray, np.ndarray]:
    """The legend of :func:`flow_to_color`: a disc whose pixel at angle ``theta`` and radius
    ``r`` (of the disc's radius ``R``) has the colour of the vector ``max_magnitude * r / R *
    (cos theta, sin theta)`` (image axes: x right, y down), so the centre is still (white) and
    the rim moves ``max_magnitude`` pixels.

    Returns
    -------
    wheel : (size, size, 3) uint8 BGR
    disc : (size, size) bool, True inside the disc
    """
    _check_max_magnitude(max_magnitude)
    centre = (size - 1) / 2
    radius = size / 2 - 1
    ys, xs = np.mgrid[0:size, 0:size].astype(np.float64)
    offsets = np.stack([xs - centre, ys - centre], axis=2)
    wheel = flow_to_color(offsets / radius * max_magnitude, max_magnitude=max_magnitude)
    disc = np.hypot(offsets[..., 0], offsets[..., 1]) <= radius
    return wheel, disc


def add_colour_wheel(picture: np.ndarray, max_magnitude: float) -> np.ndarray:
    """A copy of ``picture`` ((H, W, 3) uint8, a :func:`flow_to_color` picture) with its legend
    in the bottom-right corner: :func:`colour_wheel` (a fifth of the shorter side, 24 to 96
    pixels) on a dark square, and the speed of its rim (``"4 px"``) beside it. ``max_magnitude``
    is the picture's full-saturation magnitude (:func:`colour_scale`); 0 (a still field) draws
    the wheel of 1 px and writes ``"0 px"``. Pictures under 48 pixels a side are returned
    unchanged (no room)."""
    canvas = np.array(picture, dtype=np.uint8, copy=True)
    h, w = canvas.shape[:2]
    if min(h, w) < 48:
        return canvas
    size = int(np.clip(min(h, w) // 5, 24, 96))
    wheel, disc = colour_wheel(max_magnitude if max_magnitude > 0 else 1.0, size=size)
    text = f"{max_magnitude:.3g} px"
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.4
    (tw, th), _ = cv2.getTextSize(text, font, scale, 1)
    x0, y0 = w - size - 4, h - size - 4
    box_left = max(0, x0 - tw - 8)
    cv2.rectangle(canvas, (box_left, y0 - 2), (w - 1, h - 1), (32, 32, 32), -1)
    region = canvas[y0:y0 + size, x0:x0 + size]
    region[disc] = wheel[disc]
    cv2.putText(canvas, text, (box_left + 3, y0 + size // 2 + th // 2), font, scale,
                (255, 255, 255), 1, cv2.LINE_AA)
    return canvas


def draw_flow_arrows(
    image: np.ndarray,
    points: np.ndarray,
    vectors: np.ndarray,
    *,
    scale: float = 1.0,
    color: Tuple[int, int, int] = (0, 255, 0),
    thickness: int = 1,
    tip_fraction: float = 0.3,
    dot_color: Optional[Tuple[int, int, int]] = (0, 0, 255),
) -> np.ndarray:
    """Draw one arrow per point, as in the paper's max-flow pictures.

    Parameters
    ----------
    image : (H, W) or (H, W, 3) uint8 array
        Background picture (gray is expanded to BGR); not modified.
    points : (N, 2) float array
        Arrow tails ``(x, y)`` in pixels.
    vectors : (N, 2) float array
        ``(dx, dy)`` per point; rows with NaN are skipped.
    scale : float
        Arrows are drawn ``scale`` times longer than the motion (small motions need > 1).
    color : BGR tuple
        Arrow colour.
    thickness : int
        Line thickness in pixels.
    tip_fraction : float
        Length of the arrow head relative to the arrow.
    dot_color : BGR tuple or None
        Colour of a dot drawn at tails whose vector is (near) zero; None for no dots.

    Returns
    -------
    (H, W, 3) uint8 BGR copy of ``image`` with the arrows.
    """
    canvas = np.asarray(image)
    if canvas.dtype != np.uint8 or canvas.ndim not in (2, 3):
        raise ValueError("image must be (H, W) or (H, W, 3) uint8")
    canvas = cv2.cvtColor(canvas, cv2.COLOR_GRAY2BGR) if canvas.ndim == 2 else canvas.copy()
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 2)
    if len(points) != len(vectors):
        raise ValueError("points and vectors must have the same length")
    ok = np.isfinite(points).all(axis=1) & np.isfinite(vectors).all(axis=1)
    tails, d = points[ok], vectors[ok] * scale
    length = np.hypot(d[:, 0], d[:, 1])
    moving = length >= 0.5
    if dot_color is not None and (~moving).any():
        # One call draws all the dots: zero-length two-point polylines are drawn as round dots.
        dots = np.round(tails[~moving]).astype(np.int32)[:, None, None, :].repeat(2, axis=1)
        cv2.polylines(canvas, list(dots), False, dot_color, max(thickness, 1) + 1, cv2.LINE_AA)
    tails, d, length = tails[moving], d[moving], length[moving]
    if len(tails):
        tips = tails + d
        # Head: two barbs at +-30 degrees from the reversed direction.
        back = -d / length[:, None] * (tip_fraction * np.maximum(length, 4.0))[:, None]
        c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
        barb1 = tips + np.stack([c * back[:, 0] - s * back[:, 1], s * back[:, 0] + c * back[:, 1]], 1)
        barb2 = tips + np.stack([c * back[:, 0] + s * back[:, 1], -s * back[:, 0] + c * back[:, 1]], 1)
        # Each arrow is one open polyline tail -> tip -> barb1, plus the segment tip -> barb2.
        shafts = np.stack([tails, tips, barb1], axis=1)
        heads = np.stack([tips, barb2], axis=1)
        polys = np.round(np.concatenate([shafts, heads[:, [0, 1, 1]]])).astype(np.int32)
        # OpenCV wants a list of (k, 1, 2) int32 point arrays.
        cv2.polylines(canvas, list(polys[:, :, None, :]), False, color, thickness, cv2.LINE_AA)
    return canvas


def arrow_grid(flow: np.ndarray, *, step: int = 16) -> Tuple[np.ndarray, np.ndarray]:
    """Sample a dense field on a regular grid for :func:`draw_flow_arrows`.

    Parameters
    ----------
    flow : (H, W, 2) float array
    step : int
        Grid spacing in pixels (the first point is at ``step // 2``).

    Returns
    -------
    points : (N, 2) float32 ``(x, y)``; vectors : (N, 2) float32 (NaN where unknown).
    """
    h, w = flow.shape[:2]
    ys, xs = np.mgrid[step // 2:h:step, step // 2:w:step]
    points = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.float32)
    vectors = np.asarray(flow, dtype=np.float32)[ys.ravel(), xs.ravel()]
    return points, vectors


def flow_picture(
    flow: np.ndarray,
    *,
    image: Optional[np.ndarray] = None,
    arrows: bool = False,
    step: int = 16,
    arrow_scale: Optional[float] = None,
    max_magnitude: Optional[float] = None,
    legend: bool = False,
) -> np.ndarray:
    """A picture of a dense flow field: the colour code, or arrows over the image.

    Parameters
    ----------
    flow : (H, W, 2) float array, NaN where unknown
    image : (H, W) or (H, W, 3) uint8, optional
        The first frame; needed for ``arrows`` (drawn over a dimmed gray copy of it).
    arrows : bool
        Arrows on a grid of ``step`` pixels instead of the colour code.
    step : int
        Arrow grid spacing.
    arrow_scale : float, optional
        Arrow length per pixel of motion; default: the 95th-percentile motion is drawn
        ``0.9 * step`` long (at least 1x).
    max_magnitude : float, optional
        Colour-code saturation (see :func:`flow_to_color`); above 0 when given.
    legend : bool
        The colour code with its colour wheel and scale in a corner (:func:`add_colour_wheel`);
        arrows need none.

    Returns
    -------
    (H, W, 3) uint8 BGR
    """
    _check_max_magnitude(max_magnitude)  # refused with arrows too, which do not use it
    if not arrows:
        picture = flow_to_color(flow, max_magnitude=max_magnitude)
        if legend:
            picture = add_colour_wheel(picture, colour_scale(flow, max_magnitude=max_magnitude))
        return picture
    if image is None:
        raise ValueError("arrows are drawn over the image: give image")
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    background = (gray.astype(np.float32) * 0.6 + 40).astype(np.uint8)
    points, vectors = arrow_grid(flow, step=step)
    if arrow_scale is None:
        mag = np.hypot(vectors[:, 0], vectors[:, 1])
        mag = mag[np.isfinite(mag)]
        typical = float(np.percentile(mag, 95)) if len(mag) else 0.0
        arrow_scale = max(1.0, 0.9 * step / typical) if typical > 0 else 1.0
    return draw_flow_arrows(background, points, vectors, scale=arrow_scale)


def read_image(path: PathLike) -> np.ndarray:
    """Read an image file as ``(H, W, 3) uint8`` BGR (gray expanded, alpha dropped).

    Raises
    ------
    InputError
        The file is missing or not an image OpenCV can decode.
    """
    p = check_image_file(path)
    data = np.fromfile(str(p), dtype=np.uint8)  # np.fromfile + imdecode: any path encoding
    image = decode_image(data, name=str(p))
    if image is None:
        if p.suffix.lower() in VIDEO_SUFFIXES:  # a name that says "video"
            raise InputError(f"{p} is a video, not an image: give a video alone (bgsub flow "
                             f"{p.name} -o flow.mp4) or two images")
        raise InputError(f"cannot read image (not a format OpenCV decodes, or corrupt): {p}")
    return image


def check_image_file(path: PathLike) -> Path:
    """``path`` as a :class:`Path` if it is an existing file, else an :class:`InputError` that
    says what it is instead (missing, a folder, a device...)."""
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{p}: is a folder, not an image file")
    if not p.exists():
        raise InputError(f"image not found: {p}")
    if not p.is_file():
        raise InputError(f"not an image file: {p}")
    return p


def write_image(path: PathLike, picture: np.ndarray) -> Path:
    """Write a picture (gray or BGR uint8) in the format its extension names, atomically.

    Encoded in memory and written by Python, so a failure gives the system's reason (e.g. "No
    space left on device") instead of a codec library's message on stderr.

    Raises
    ------
    OutputError
        OpenCV cannot encode this extension, or the file cannot be written.
    """
    p = Path(path)
    try:
        ok, data = cv2.imencode(p.suffix.lower(), picture)
    except cv2.error:
        ok = False
    if not ok:
        raise OutputError(f"cannot encode a picture as {p.suffix or '(no extension)'}: {p}")
    write_atomically(p, data.tobytes(), what="image")
    return p


def endpoint_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Per-vector endpoint error ``|estimate - truth|`` (Euclidean).

    Parameters
    ----------
    estimate, truth : (..., 2) float arrays of the same shape
        Flow vectors ``(u, v)``, NaN where unknown.

    Returns
    -------
    (...) float32 array, NaN where either vector is unknown. Use ``np.nanmean`` for the average
    endpoint error (AEE) over the known vectors.
    """
    estimate = np.asarray(estimate, dtype=np.float32)
    truth = np.asarray(truth, dtype=np.float32)
    if estimate.shape != truth.shape or estimate.shape[-1] != 2:
        raise ValueError(f"shapes differ or are not (..., 2): {estimate.shape} vs {truth.shape}")
    diff = estimate - truth
    return np.hypot(diff[..., 0], diff[..., 1]).astype(np.float32)


def within(estimate: np.ndarray, truth: np.ndarray, *, tolerance: float = 1.0) -> np.ndarray:
    """Whether each estimated vector is within ``tolerance`` px (endpoint error) of the truth.

    Returns
    -------
    (...) bool array; False where either vector is unknown.
    """
    err = endpoint_error(estimate, truth)
    with np.errstate(invalid="ignore"):
        return err <= tolerance


__all__: Sequence[str] = (
    "read_flo",
    "write_flo",
    "flow_to_color",
    "colour_scale",
    "colour_wheel",
    "add_colour_wheel",
    "draw_flow_arrows",
    "arrow_grid",
    "flow_picture",
    "read_image",
    "check_image_file",
    "write_image",
    "endpoint_error",
    "within",
)
