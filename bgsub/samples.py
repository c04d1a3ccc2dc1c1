"""Synthetic moving-camera scenes with exact ground truth, in the CDnet 2014 layout.

A scene is a large textured background ("the world") seen through a camera whose pose changes
every frame, plus 2-4 textured foreground objects that move along their own straight paths in
world coordinates, so they move relative to the background and enter and leave the view.

Everything is analytic, so the ground truth is exact:

* the camera pose of frame ``k`` is a similarity ``C_k`` mapping view pixel coordinates to world
  coordinates; the view is ``cv2.warpPerspective(world, C_k, (W, H), WARP_INVERSE_MAP,
  INTER_LINEAR)``; the camera motion from frame ``k-1`` to frame ``k`` is therefore
  ``H_k = inv(C_k) @ C_{k-1}`` (``frame_k[H_k p] == frame_{k-1}[p]`` on the background, the
  displacement convention of :mod:`bgsub`);
* each object is a star-shaped blob ``rho < r(theta)`` in its own coordinates; a ground-truth
  pixel is 255 iff the object covers the pixel centre. Object edges are antialiased (coverage
  ``alpha = clip(d + 0.5, 0, 1)`` with ``d`` the signed distance to the outline in view pixels),
  so pixels within half a pixel of an outline are a mix of object and background: they are
  marked 170 ("unknown", ignored by the CDnet evaluation) unless ``SceneSpec.boundary_unknown``
  is False. Hence GT 0 pixels are pure background and GT 255 pixels pure object.

Timeline (fair to static-camera methods, like a CDnet sequence): the first ``warmup`` frames
(default ``min(24, n_frames // 5)``, so 24 of the default 120) show the background alone, with the
camera already moving as it will for the whole clip; ``temporalROI.txt`` is ``"<warmup+1>
<n_frames>"`` (the CDnet convention: frames before the ROI are an unscored warm-up). Every object
enters the view through a side after the warm-up (none is in view in the first frame, so no model
can learn one into its background), crosses it at 2.5-5 view px/frame and may leave through
another side. An object of radius 11-22 px (at 320x240) therefore covers a pixel for about 4-15
frames, which a static-camera model with a sensible learning rate does not absorb. The warm-up and
the object rules are the same for every category: only the camera differs.

On disk (:func:`generate_scene`) a scene ``DIR/<category>_s<seed>/`` holds
``input/in000001.jpg ...`` (JPEG quality 95), ``groundtruth/gt000001.png ...`` (uint8 0/170/255),
``temporalROI.txt``, ``<category>_s<seed>.mp4`` (the input as an mp4v video) and
``camera_motion.npy`` (``(n_frames, 3, 3) float64``, entry ``k`` maps pixel coordinates of frame
``k-1`` to frame ``k``; entry 0 is the identity).

Example
-------
>>> from bgsub.samples import SceneSpec, render_frames
>>> for image, gt, motion in render_frames(SceneSpec("pan", seed=0, n_frames=5)):
...     pass  # image (240, 320, 3) uint8 BGR, gt (240, 320) uint8, motion (3, 3) float64
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, Iterator, List, NamedTuple, Optional, Tuple, Union

import cv2
import numpy as np

from bgsub.errors import InputError, OutputError

#: The file name of the bundled sample: the ``pan`` scene of seed 0 as a video.
BUNDLED_SAMPLE = "pan.mp4"

#: The scene categories and what their camera does.
CATEGORIES: Dict[str, str] = {
    "static": "camera still (the case classical background subtraction is built for)",
    "pan": "steady pan of 2-5 px/frame, mostly horizontal",
    "jitter": "camera shaking by a few px (and a fraction of a degree) around a fixed point, "
              "like CDnet cameraJitter",
    "pan-zoom-rotate": "pan of 2-4 px/frame with a slow zoom (0.15-0.3 %/frame) and a small "
                       "rotation (0.1-0.25 deg/frame)",
    "fast-pan": "steady pan of 8-15 px/frame",
    "parallax": "camera translating 1.5-3 px/frame past a near ground band (the bottom "
                "quarter to third of the view) that moves 1.8-2.6 times as fast: rigid, not "
                "planar, background",
}

#: Ground-truth labels (CDnet 2014).
GT_BACKGROUND = 0
GT_UNKNOWN = 170
GT_FOREGROUND = 255

#: Longest scene: its camera path is computed up front (a few hundred bytes per frame).
MAX_FRAMES = 100_000

_JPEG_QUALITY = 95
_DEFAULT_WARMUP = 24
#: Object speed relative to the view, px/frame, and radius as a fraction of min(width, height).
_OBJECT_SPEED = (2.5, 5.0)
_OBJECT_RADIUS = (0.045, 0.09)


@dataclass(frozen=True)
class SceneSpec:
    """What to render: everything about a scene follows from these fields.

    Parameters
    ----------
    category : str
        One of :data:`CATEGORIES`.
    seed : int
        Seeds every random choice (background, camera path, objects, sensor noise).
    width, height : int
        Frame size in pixels (at least 64 x 48). :func:`render_frames` takes any; to be written
        by :func:`generate_scene` (with its .mp4 video) both must be even.
    n_frames : int
        Number of frames (at least 2).
    fps : float
        Frame rate written into the mp4.
    n_objects : int or None
        Number of foreground objects; None draws 2-4 from ``seed``.
    noise_sigma : float
        Standard deviation of the Gaussian sensor noise, in gray levels.
    boundary_unknown : bool
        Mark the antialiased 1-pixel rim of each object 170 (unknown) in the ground truth.
    warmup : int or None
        Number of leading frames with no object in view (background and camera motion only).
        None means ``min(24, n_frames // 5)``; see :attr:`warmup_frames`.
    roi_first : int or None
        First frame number (1-based) of ``temporalROI.txt``: frames before it are warm-up
        that evaluation ignores, like CDnet's. None means ``warmup_frames + 1``; see
        :attr:`roi_start`.
    """

    category: str
    seed: int = 0
    width: int = 320
    height: int = 240
    n_frames: int = 120
    fps: float = 25.0
    n_objects: Optional[int] = None
    noise_sigma: float = 2.0
    boundary_unknown: bool = True
    warmup: Optional[int] = None
    roi_first: Optional[int] = None

    def __post_init__(self) -> None:
        if self.category not in CATEGORIES:
            known = ", ".join(CATEGORIES)
            raise InputError(f"unknown scene category {self.category!r} (available: {known})")
        if self.width < 64 or self.height < 48:
            raise InputError(f"scene size {self.width}x{self.height} is too small (minimum 64x48)")
        if self.width > 4096 or self.height > 4096:
            raise InputError(f"scene size {self.width}x{self.height} is too large (max 4096)")
        if self.n_frames < 2:
            raise InputError(f"a scene needs at least 2 frames, not {self.n_frames}")
        if self.n_frames > MAX_FRAMES:
            raise InputError(f"a scene has at most {MAX_FRAMES} frames, not {self.n_frames}")
        if self.n_objects is not None and not 0 <= self.n_objects <= 16:
            raise InputError(f"n_objects must be in 0..16, not {self.n_objects}")
        if self.warmup is not None and not 0 <= self.warmup <= self.n_frames - 1:
            raise InputError(f"warmup must be in 0..{self.n_frames - 1} frames, not "
                             f"{self.warmup}")
        if self.roi_first is not None and not 1 <= self.roi_first <= self.n_frames:
            raise InputError(f"roi_first must be in 1..{self.n_frames}, not {self.roi_first}")
        if self.seed < 0:
            raise InputError(f"seed must be >= 0, not {self.seed}")

    @property
    def warmup_frames(self) -> int:
        """Leading frames without objects: ``warmup``, or ``min(24, n_frames // 5)``."""
        if self.warmup is not None:
            return self.warmup
        return min(_DEFAULT_WARMUP, self.n_frames // 5)

    @property
    def roi_start(self) -> int:
        """First scored frame number (1-based) written to ``temporalROI.txt``."""
        return self.roi_first if self.roi_first is not None else self.warmup_frames + 1

    @property
    def name(self) -> str:
        """Folder (and video) name of the scene: ``<category>_s<seed>``."""
        return f"{self.category}_s{self.seed}"


class SceneFrame(NamedTuple):
    """One rendered frame; unpacks as ``(image, groundtruth, motion)``."""

    image: np.ndarray        # (H, W, 3) uint8 BGR, with sensor noise
    groundtruth: np.ndarray  # (H, W) uint8, 0 / 170 / 255
    motion: np.ndarray       # (3, 3) float64, pixel coords of the previous frame -> this frame


@dataclass
class _Object:
    """A foreground blob: outline ``rho < radius * (1 + sum a_i cos(i theta + phase_i))``."""

    radius: float
    harmonics: np.ndarray        # (m,) float64 amplitudes a_i, i = 2..m+1
    phases: np.ndarray           # (m,) float64
    sprite: np.ndarray           # (S, S, 3) float32 texture in object coordinates, centre S//2
    start: np.ndarray            # (2,) float64 world position at frame 0
    velocity: np.ndarray         # (2,) float64 world px/frame
    angle0: float                # radians at frame 0
    spin: float                  # radians/frame
    extent: float = field(init=False)

    def __post_init__(self) -> None:
        self.extent = self.radius * (1.0 + float(np.abs(self.harmonics).sum()))

    def pose(self, k: int) -> np.ndarray:
        """(3, 3) float64: object coordinates -> world coordinates at frame ``k``."""
        x, y = self.start + k * self.velocity
        return _similarity(x, y, self.angle0 + k * self.spin, 1.0)


# ----------------------------------------------------------------------------- geometry


def _similarity(tx: float, ty: float, angle: float, scale: float) -> np.ndarray:
    """(3, 3) float64: rotate by ``angle`` and scale about the origin, then translate."""
    c, s = scale * math.cos(angle), scale * math.sin(angle)
    return np.array([[c, -s, tx], [s, c, ty], [0.0, 0.0, 1.0]])


def _rng(spec: SceneSpec, stream: str) -> np.random.Generator:
    """An independent generator per (seed, category, purpose): changing one purpose's draws
    (say, the object count) leaves the others (the background) unchanged."""
    key = [spec.seed, zlib.crc32(spec.category.encode()), zlib.crc32(stream.encode())]
    return np.random.default_rng(key)


def _camera_path(spec: SceneSpec) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera centre ``(n, 2)``, angle ``(n,)`` radians and scale ``(n,)`` (world px per view px)
    for each frame, before shifting into the world image."""
    rng = _rng(spec, "camera")
    n = spec.n_frames
    k = np.arange(n, dtype=np.float64)
    centre = np.zeros((n, 2))
    angle = np.zeros(n)
    scale = np.ones(n)
    category = spec.category

    def pan_velocity(low: float, high: float) -> np.ndarray:
        speed = rng.uniform(low, high)
        heading = rng.choice([0.0, math.pi]) + rng.uniform(-0.35, 0.35)  # mostly horizontal
        return speed * np.array([math.cos(heading), math.sin(heading)])

    if category == "pan":
        centre = k[:, None] * pan_velocity(2.0, 5.0)
    elif category == "parallax":  # a camera on a track: horizontal (the band stays in view)
        centre = k[:, None] * np.array([rng.uniform(1.5, 3.0) * rng.choice([-1.0, 1.0]), 0.0])
    elif category == "fast-pan":
        centre = k[:, None] * pan_velocity(8.0, 15.0)
    elif category == "jitter":
        centre = np.clip(rng.normal(0.0, 2.0, size=(n, 2)), -5.0, 5.0)
        angle = np.clip(rng.normal(0.0, math.radians(0.2), size=n), -0.01, 0.01)
        centre[0], angle[0] = 0.0, 0.0
    elif category == "pan-zoom-rotate":
        centre = k[:, None] * pan_velocity(2.0, 4.0)
        zoom = rng.uniform(0.0015, 0.003) * rng.choice([-1.0, 1.0])
        scale = np.exp(zoom * k)
        angle = k * math.radians(rng.uniform(0.1, 0.25)) * rng.choice([-1.0, 1.0])
    return centre, angle, scale


def _camera_poses(spec: SceneSpec, margin: int = 24) -> Tuple[np.ndarray, Tuple[int, int]]:
    """Camera poses ``(n, 3, 3) float64`` (view pixel -> world pixel) and the world size
    ``(width, height)`` that contains every view with ``margin`` pixels to spare."""
    centre, angle, scale = _camera_path(spec)
    w, h = spec.width, spec.height
    to_centre = _similarity(-(w - 1) / 2.0, -(h - 1) / 2.0, 0.0, 1.0)
    poses = np.stack([
        _similarity(cx, cy, a, s) @ to_centre for (cx, cy), a, s in zip(centre, angle, scale)
    ])
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float).T
    world_corners = np.concatenate([(p @ corners)[:2] for p in poses], axis=1)
    low = np.floor(world_corners.min(axis=1)) - margin
    high = np.ceil(world_corners.max(axis=1)) + margin
    shift = _similarity(-low[0], -low[1], 0.0, 1.0)
    poses = shift @ poses
    size = (int(high[0] - low[0]) + 1, int(high[1] - low[1]) + 1)
    return poses, size


def camera_motion(poses: np.ndarray) -> np.ndarray:
    """Frame-to-frame motion ``(n, 3, 3) float64`` from camera poses (view -> world).

    Entry ``k`` is ``inv(C_k) @ C_{k-1}``: it maps pixel coordinates of frame ``k-1`` to frame
    ``k``; entry 0 is the identity.
    """
    motion = np.empty_like(poses)
    motion[0] = np.eye(3)
    for k in range(1, len(poses)):
        m = np.linalg.solve(poses[k], poses[k - 1])
        motion[k] = m / m[2, 2]
    return motion


# ----------------------------------------------------------------------------- textures


def _noise_field(rng: np.random.Generator, shape: Tuple[int, int],
                 octaves: List[Tuple[int, float]]) -> np.ndarray:
    """Sum of smooth noise octaves: ``(H, W) float32``; ``octaves`` are (cell px, amplitude).

    Each octave is white noise on a grid of ``cell``-pixel cells upsampled with bicubic
    interpolation, so the result has structure at every listed scale but no periodicity.
    """
    h, w = shape
    out = np.zeros((h, w), np.float32)
    for cell, amplitude in octaves:
        gh, gw = h // cell + 3, w // cell + 3
        grid = rng.standard_normal((gh, gw)).astype(np.float32)
        up = cv2.resize(grid, (gw * cell, gh * cell), interpolation=cv2.INTER_CUBIC)
        oy, ox = int(rng.integers(0, cell)), int(rng.integers(0, cell))
        out += amplitude * up[oy:oy + h, ox:ox + w]
    return out


# Muted natural colours (BGR): foliage, soil, stone, bark, sky-gray.
_PALETTE = np.array([
    [70, 120, 90], [60, 100, 130], [120, 130, 135], [50, 80, 110], [150, 150, 140],
    [90, 140, 120], [40, 70, 90], [130, 120, 100], [100, 110, 80], [170, 165, 160],
], np.float32)


def _background(rng: np.random.Generator, size: Tuple[int, int]) -> np.ndarray:
    """The world image ``(Hw, Ww, 3) float32`` BGR in [0, 255].

    Layers: a smooth colour field, opaque random shapes (discs, rotated boxes, strokes) of
    3-40 px that give sharp edges at several scales, then multi-octave luminance texture over
    everything so no area is flat, and a slight blur so the image is band-limited like a
    camera's (bilinear resampling of it then stays close to the truth).
    """
    w, h = size
    base = _PALETTE[rng.integers(len(_PALETTE))]
    world = np.empty((h, w, 3), np.float32)
    world[:] = base
    for c in range(3):
        world[..., c] += _noise_field(rng, (h, w), [(128, 25.0), (48, 15.0)])
    n_shapes = max(20, (w * h) // 900)
    for _ in range(n_shapes):
        colour = _PALETTE[rng.integers(len(_PALETTE))] + rng.normal(0, 25, 3)
        colour = tuple(float(v) for v in np.clip(colour, 20, 235))
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        r = float(np.exp(rng.uniform(np.log(3), np.log(40))))
        kind = rng.integers(3)
        if kind == 0:
            cv2.circle(world, (x, y), int(r), colour, -1, cv2.LINE_AA)
        elif kind == 1:
            box = ((x, y), (2 * r, r * rng.uniform(0.3, 1.5)), rng.uniform(0, 180))
            cv2.fillPoly(world, [cv2.boxPoints(box).round().astype(np.int32)], colour,
                         cv2.LINE_AA)
        else:
            t = rng.uniform(0, np.pi)
            p2 = (int(x + 2 * r * np.cos(t)), int(y + 2 * r * np.sin(t)))
            cv2.line(world, (x, y), p2, colour, int(rng.integers(1, 5)), cv2.LINE_AA)
    texture = _noise_field(rng, (h, w), [(24, 14.0), (12, 10.0), (6, 8.0), (3, 6.0), (2, 4.0)])
    world += texture[..., None] * np.float32(1.0) + rng.normal(0, 2, 3).astype(np.float32)
    world = cv2.GaussianBlur(world, (0, 0), 0.6)
    return np.clip(world, 0, 255)


def _sprite(rng: np.random.Generator, extent: float) -> np.ndarray:
    """Object texture ``(S, S, 3) float32``: a vivid colour that is clearly darker or brighter
    than the background, with stripes or spots and fine noise so that motion shows inside it."""
    size = 2 * int(math.ceil(extent)) + 8
    hue = int(rng.integers(0, 180))
    bright = bool(rng.integers(2))
    value = rng.uniform(215, 245) if bright else rng.uniform(40, 70)
    hsv = np.uint8([[[hue, int(rng.uniform(150, 230)), int(value)]]])
    colour = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0].astype(np.float32)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    if rng.integers(2):  # stripes at a random angle and period
        t = rng.uniform(0, np.pi)
        period = rng.uniform(6, 12)
        pattern = np.sin(2 * np.pi * (xx * np.cos(t) + yy * np.sin(t)) / period)
    else:  # spots
        pattern = np.zeros((size, size), np.float32)
        for _ in range(max(3, size * size // 150)):
            cx, cy = rng.uniform(0, size, 2)
            pattern += np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * rng.uniform(1.5, 3) ** 2))
        pattern = 2 * np.clip(pattern, 0, 1) - 1
    # Dark objects get lighter patterns and bright ones darker, keeping their mean apart from
    # the background's.
    shade = (-1.0 if bright else 1.0) * (14 * (pattern + 1) + _noise_field(rng, (size, size),
                                                                           [(6, 6.0), (3, 4.0)]))
    return np.clip(colour[None, None, :] + shade[..., None], 0, 255).astype(np.float32)


# ----------------------------------------------------------------------------- objects


def _objects(spec: SceneSpec, poses: np.ndarray) -> List[_Object]:
    """Draw the foreground objects: each enters the view through one side at a random frame
    after the warm-up (in its first half of the remaining frames) and heads for another side,
    moving in the world at >= 1 px/frame."""
    rng = _rng(spec, "objects")
    w, h, n = spec.width, spec.height, spec.n_frames
    warmup = spec.warmup_frames
    count = spec.n_objects if spec.n_objects is not None else int(rng.integers(2, 5))
    short = min(w, h)
    objects = []
    for _ in range(count):
        radius = rng.uniform(*_OBJECT_RADIUS) * short
        harmonics = rng.uniform(0.0, 0.12, size=3) * rng.choice([-1, 1], size=3)
        phases = rng.uniform(0, 2 * np.pi, size=3)
        extent = radius * (1 + np.abs(harmonics).sum())
        sprite = _sprite(rng, extent)
        angle0 = rng.uniform(0, 2 * np.pi)
        spin = math.radians(rng.uniform(-1.0, 1.0))
        # A path is accepted when the object moves in the world (so it is not part of the
        # background for a moving camera) and stays out of view during the warm-up (the entry
        # geometry is exact for translations; zoom and rotation need the check).
        for _attempt in range(100):
            start, velocity = _crossing(rng, poses, w=w, h=h, n=n, extent=extent, warmup=warmup)
            obj = _Object(radius=radius, harmonics=harmonics, phases=phases, sprite=sprite,
                          start=start, velocity=velocity, angle0=angle0, spin=spin)
            if np.hypot(*velocity) >= 1.0 and not _in_view(obj, poses[:warmup], w=w, h=h):
                break
        objects.append(obj)
    return objects


def _in_view(obj: _Object, poses: np.ndarray, *, w: int, h: int) -> bool:
    """Whether ``obj`` (its bounding circle plus one pixel) touches the view in any of the
    frames ``0 .. len(poses) - 1`` whose camera poses are given."""
    for k, pose in enumerate(poses):
        inv = np.linalg.inv(pose)
        cx, cy, cw = inv @ obj.pose(k)[:, 2]
        per_px = math.sqrt(abs(np.linalg.det(pose[:2, :2])))  # world px per view px
        reach = obj.extent / per_px + 1.0
        dx = max(-(cx / cw), 0.0, cx / cw - (w - 1))
        dy = max(-(cy / cw), 0.0, cy / cw - (h - 1))
        if math.hypot(dx, dy) < reach:
            return True
    return False


def _crossing(rng: np.random.Generator, poses: np.ndarray, *, w: int, h: int, n: int,
              extent: float, warmup: int) -> Tuple[np.ndarray, np.ndarray]:
    """A straight world path ``(start (2,), velocity (2,))`` that enters the view through one
    side at frame ``t0`` (``warmup <= t0 <= warmup + (n - warmup) / 2``) and reaches another
    side at ``t1`` (possibly after the clip, so some objects are still in view at the end)."""
    sides = rng.choice(4, size=2, replace=False)
    pad = extent + 2

    def border_point(side: int) -> np.ndarray:
        u = rng.uniform(0.15, 0.85)
        return [np.array([-pad, u * h]), np.array([w - 1 + pad, u * h]),
                np.array([u * w, -pad]), np.array([u * w, h - 1 + pad])][side]

    entry, leave = border_point(sides[0]), border_point(sides[1])
    view_speed = rng.uniform(*_OBJECT_SPEED)
    duration = max(8.0, float(np.hypot(*(leave - entry))) / view_speed)
    # Enter after the warm-up and early enough to be seen for at least half the rest of the
    # clip. Short clips (a few frames) still work: t0 is then just after the warm-up.
    t0 = warmup + rng.uniform(0.0, 0.5) * max(n - 1 - warmup, 0)
    t1 = t0 + duration

    def to_world(point: np.ndarray, t: float) -> np.ndarray:
        k = int(np.clip(round(t), 0, n - 1))  # outside the clip the camera is extrapolated
        p = poses[k] @ np.array([point[0], point[1], 1.0])
        # Move the point with the camera's own drift for the frames beyond the clip.
        if t != k and n > 1:
            kk = 1 if k == 0 else k
            drift = (poses[kk] @ [w / 2, h / 2, 1.0] - poses[kk - 1] @ [w / 2, h / 2, 1.0])[:2]
            p[:2] += (t - k) * drift
        return p[:2]

    p0, p1 = to_world(entry, t0), to_world(leave, t1)
    velocity = (p1 - p0) / (t1 - t0)
    return p0 - t0 * velocity, velocity


def _draw_objects(view: np.ndarray, gt: np.ndarray, objects: List[_Object], pose: np.ndarray,
                  k: int, *, boundary_unknown: bool) -> None:
    """Composite the objects into ``view`` ``(H, W, 3) float32`` and label ``gt`` in place."""
    h, w = gt.shape
    inv_pose = np.linalg.inv(pose)
    for obj in objects:
        to_world = obj.pose(k)
        cx, cy, cw = inv_pose @ to_world[:, 2]
        cx, cy = cx / cw, cy / cw
        local = np.linalg.solve(to_world, pose)       # view px -> object coordinates
        per_px = math.sqrt(abs(np.linalg.det(local[:2, :2])))  # object units per view px
        reach = obj.extent / per_px + 2
        x0, x1 = max(int(cx - reach), 0), min(int(cx + reach) + 1, w)
        y0, y1 = max(int(cy - reach), 0), min(int(cy + reach) + 1, h)
        if x0 >= x1 or y0 >= y1:
            continue
        ys, xs = np.mgrid[y0:y1, x0:x1].astype(np.float64)
        den = local[2, 0] * xs + local[2, 1] * ys + local[2, 2]
        u = (local[0, 0] * xs + local[0, 1] * ys + local[0, 2]) / den
        v = (local[1, 0] * xs + local[1, 1] * ys + local[1, 2]) / den
        rho = np.hypot(u, v)
        theta = np.arctan2(v, u)
        outline = np.ones_like(rho)
        for i, (a, phase) in enumerate(zip(obj.harmonics, obj.phases), start=2):
            outline += a * np.cos(i * theta + phase)
        outline *= obj.radius
        inside = rho < outline                         # exact: covers the pixel centre
        depth = (outline - rho) / per_px               # signed distance in view px (approx.)
        # Coverage: > 0.5 exactly where the pixel centre is inside, 1 beyond half a pixel in.
        alpha = np.clip(depth + 0.5, 0.0, 1.0).astype(np.float32)
        centre = obj.sprite.shape[0] // 2
        tex = cv2.remap(obj.sprite, (u + centre).astype(np.float32),
                        (v + centre).astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REFLECT)
        patch = view[y0:y1, x0:x1]
        patch += alpha[..., None] * (tex - patch)
        labels = gt[y0:y1, x0:x1]
        if boundary_unknown:
            mixed = (alpha > 0) & (alpha < 1) & (labels != GT_FOREGROUND)
            labels[mixed] = GT_UNKNOWN
            labels[alpha >= 1] = GT_FOREGROUND
        else:
            labels[inside] = GT_FOREGROUND


# ----------------------------------------------------------------------------- rendering


def render_frames(spec: SceneSpec, *, include_objects: bool = True) -> Iterator[SceneFrame]:
    """Render the scene in memory, one frame at a time.

    Parameters
    ----------
    spec : SceneSpec
        The scene.
    include_objects : bool
        False renders the background alone (same camera, same noise): the frames then equal
        the full scene's wherever its ground truth is 0.

    Yields
    ------
    SceneFrame
        ``(image (H, W, 3) uint8 BGR, groundtruth (H, W) uint8 0/170/255, motion (3, 3)
        float64)``; ``motion`` maps pixel coordinates of the previous frame to this one
        (identity for the first frame).
    """
    poses, world_size = _camera_poses(spec)
    world = _background(_rng(spec, "background"), world_size)
    objects = _objects(spec, poses) if include_objects else []
    near = _NearBand(spec, poses) if spec.category == "parallax" else None
    motion = camera_motion(poses)
    noise_rng = _rng(spec, "noise")
    size = (spec.width, spec.height)
    for k in range(spec.n_frames):
        view = cv2.warpPerspective(world, poses[k], size,
                                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                   borderMode=cv2.BORDER_REFLECT)
        if near is not None:
            near.draw(view, k)
        gt = np.zeros((spec.height, spec.width), np.uint8)
        _draw_objects(view, gt, objects, poses[k], k, boundary_unknown=spec.boundary_unknown)
        noise = noise_rng.standard_normal(view.shape, dtype=np.float32)
        view += np.float32(spec.noise_sigma) * noise
        image = np.clip(np.rint(view), 0, 255).astype(np.uint8)
        yield SceneFrame(image, gt, motion[k].copy())


class _NearBand:
    """The ``parallax`` category's near layer: a textured ground band along the bottom of the
    view, static in the world but nearer than the rest, so it moves ``speed`` times as fast
    (a translating camera's parallax); its top edge is irregular, like rocks or bushes."""

    def __init__(self, spec: SceneSpec, poses: np.ndarray) -> None:
        rng = _rng(spec, "near band")
        self.speed = rng.uniform(1.8, 2.6)
        w, h = spec.width, spec.height
        shift = poses[:, :2, 2] - poses[0, :2, 2]  # the camera's path (far-layer px)
        self.offset = -self.speed * shift.min(axis=0) + 8
        span = np.ceil(self.speed * (shift.max(axis=0) - shift.min(axis=0))).astype(int)
        self.texture = _background(rng, (w + span[0] + 16, h + span[1] + 16)) * np.float32(0.7)
        self.shift = shift
        top = h * (1 - rng.uniform(0.25, 0.35))
        bumps = 6 * np.sin(np.arange(self.texture.shape[1]) / rng.uniform(9, 20))
        self.top = (top + bumps).astype(np.float32)  # per texture column

    def draw(self, view: np.ndarray, k: int) -> None:
        """Cover ``view`` ((H, W, 3) float32) with the band as frame ``k`` sees it, in place."""
        h, w = view.shape[:2]
        x0, y0 = self.speed * self.shift[k] + self.offset
        move = np.array([[1, 0, x0], [0, 1, y0]], np.float32)
        band = cv2.warpAffine(self.texture, move, (w, h),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
        cols = np.clip(np.arange(w) + x0, 0, len(self.top) - 1)
        top = np.interp(cols, np.arange(len(self.top)), self.top) - y0 + self.offset[1]
        rows = np.arange(h, dtype=np.float32)[:, None]
        alpha = np.clip(rows - top[None, :] + 0.5, 0, 1).astype(np.float32)[..., None]
        view *= 1 - alpha
        view += alpha * band


def bundled_sample() -> Path:
    """The path of the bundled sample video ``pan.mp4`` (320x240, 120 frames, 25 fps: the
    ``pan`` scene of seed 0), installed as the package data ``bgsub.data``."""
    from importlib import resources

    try:
        folder = resources.files("bgsub.data")
    except ModuleNotFoundError:
        # A source checkout that was never pip-installed: samples/ sits beside bgsub/.
        folder = Path(__file__).resolve().parents[1] / "samples"
    path = Path(str(folder.joinpath(BUNDLED_SAMPLE)))
    if not path.is_file():
        raise InputError(f"the bundled sample {BUNDLED_SAMPLE} is not installed (no {path}); "
                         "`bgsub samples DIR --category pan --seed 0` writes the same video")
    return path


def copy_bundled_sample(out_dir: Union[str, os.PathLike], *, overwrite: bool = False) -> Path:
    """Copy the bundled sample (:func:`bundled_sample`) to ``out_dir/pan.mp4`` and return that
    path; :class:`OutputError` when it exists (without ``overwrite``) or cannot be written."""
    source = bundled_sample()
    folder = Path(out_dir)
    target = folder / BUNDLED_SAMPLE
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder} exists and is not a folder")
    if target.exists() and not overwrite:
        raise OutputError(f"{target} already exists (use --overwrite to replace it)")
    if target.exists() and target.resolve() == source.resolve():
        return target  # the checkout's own samples/pan.mp4: nothing to copy
    partial = folder / f".{BUNDLED_SAMPLE}.partial"  # renamed when whole
    try:
        folder.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, partial)
        os.replace(partial, target)
    except OSError as err:
        raise OutputError(f"cannot write {target}: {err.strerror or err}") from None
    return target


def check_video_size(width: int, height: int) -> None:
    """:class:`InputError` unless ``width`` and ``height`` are even, as a scene written by
    :func:`generate_scene` needs: the codec would pad its .mp4 to even sizes, and the video
    would no longer match the scene's frames and ground truth. (Rendering in memory, as
    :func:`render_frames` and ``bgsub bench`` do, takes any size.)"""
    if width % 2 or height % 2:
        raise InputError(f"scene size {width}x{height} must be even in both dimensions to be "
                         "written: the codec would pad the scene's .mp4 video to even sizes and "
                         "it would no longer match the frames and ground truth (e.g. "
                         f"{width - width % 2}x{height - height % 2})")


def generate_scene(spec: SceneSpec, out_dir: Union[str, os.PathLike], *, overwrite: bool = False,
                   on_frame: Optional[Callable[[int], object]] = None) -> Path:
    """Render ``spec`` and write it to ``out_dir/<category>_s<seed>/`` in the CDnet layout.

    The scene is written to a temporary folder next to its final place and renamed at the end,
    so an interrupted run leaves no half scene.

    Parameters
    ----------
    spec : SceneSpec
        The scene.
    out_dir : path
        Parent folder (created if needed).
    overwrite : bool
        Replace an existing scene folder of the same name; refused otherwise.
    on_frame : callable, optional
        Called with 1 after each frame is written (e.g. ``tqdm.update``).

    Returns
    -------
    Path of the scene folder.

    Raises
    ------
    InputError
        The frame size is odd (see :func:`check_video_size`).
    OutputError
        The scene folder exists and ``overwrite`` is False, or it cannot be written.
    """
    check_video_size(spec.width, spec.height)
    out_dir = Path(out_dir)
    target = out_dir / spec.name
    if target.exists() and not overwrite:
        raise OutputError(f"{target}: already exists (overwrite=True, or --overwrite on the "
                          "command line, replaces it)")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{spec.name}.", dir=out_dir))
    except OSError as err:
        raise OutputError(f"cannot write to {out_dir}: {err.strerror or err}") from None
    try:
        _write_scene(spec, tmp, on_frame=on_frame)
        if target.exists():
            shutil.rmtree(target) if target.is_dir() else target.unlink()
        # mkdtemp makes the folder private (0700); give it the permissions of a normal folder.
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o777 & ~umask)
        tmp.rename(target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def _write_scene(spec: SceneSpec, folder: Path, *,
                 on_frame: Optional[Callable[[int], object]]) -> None:
    (folder / "input").mkdir()
    (folder / "groundtruth").mkdir()
    video_path = folder / f"{spec.name}.mp4"
    video = cv2.VideoWriter(str(video_path), cv2.VideoWriter_fourcc(*"mp4v"), spec.fps,
                            (spec.width, spec.height))
    if not video.isOpened():
        raise OutputError(f"cannot write {video_path}: OpenCV has no mp4v video writer")
    motions = np.empty((spec.n_frames, 3, 3), np.float64)
    try:
        for k, (image, gt, motion) in enumerate(render_frames(spec)):
            number = k + 1
            ok = cv2.imwrite(str(folder / "input" / f"in{number:06d}.jpg"), image,
                             [cv2.IMWRITE_JPEG_QUALITY, _JPEG_QUALITY])
            ok &= cv2.imwrite(str(folder / "groundtruth" / f"gt{number:06d}.png"), gt)
            if not ok:
                raise OutputError(f"cannot write frame {number} into {folder}")
            video.write(image)
            motions[k] = motion
            if on_frame is not None:
                on_frame(1)
    finally:
        video.release()
    np.save(folder / "camera_motion.npy", motions, allow_pickle=False)
    (folder / "temporalROI.txt").write_text(f"{spec.roi_start} {spec.n_frames}\n")
