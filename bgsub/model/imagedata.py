"""Real-image training pairs for the gated RBM (the ``natural`` model).

Two sources of ``13 x 13`` patch pairs, both usable as the trainer's pair source
``pairs(rng, n, epoch) -> (X, Y)`` with ``X, Y`` ``(n, p*p) float32`` gray values in [0, 1]:

* :func:`shifted_image_pairs` -- photographs from scikit-image's bundled data (installed with the
  optional extra ``pip install bgsub[train]``), each pair cut from a photo and from a copy moved
  by a random sub-pixel shift of several pixels plus a small rotation and zoom. The true
  displacement of every pair is known (:meth:`ShiftedImagePairs.sample`), so held-out photos
  (:data:`TEST_IMAGES`) measure accuracy.
* :func:`video_frame_pairs` -- patches cut at the same place from consecutive frames of the
  user's own videos: the real motion, unlabelled (the model learns without labels anyway).

Sampling is vectorised: all images live in one flat buffer and every pair of every batch is
gathered with one bilinear interpolation, no loop per patch.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple, Union

import cv2
import numpy as np

from bgsub.errors import InputError
from bgsub.model.training import Curriculum

__all__ = [
    "TRAIN_IMAGES",
    "TEST_IMAGES",
    "load_photos",
    "ShiftedSample",
    "ShiftedImagePairs",
    "shifted_image_pairs",
    "warped_frame_pair",
    "VideoFramePairs",
    "video_frame_pairs",
]

#: Photographs of ``skimage.data`` used for training (all ship inside the scikit-image wheel,
#: so no download is needed).
TRAIN_IMAGES: Tuple[str, ...] = (
    "astronaut", "camera", "coffee", "rocket", "brick", "grass", "gravel", "moon",
    "immunohistochemistry", "clock", "cell", "page", "text", "hubble_deep_field", "retina",
)
#: Photographs held out for testing: never seen in training.
TEST_IMAGES: Tuple[str, ...] = ("chelsea", "coins", "motorcycle")

PathLike = Union[str, "os.PathLike[str]"]


def _skimage_data():
    try:
        import skimage.data as data  # optional dependency: only needed to (re)train
    except ImportError:
        raise InputError(
            "training on photographs needs scikit-image: pip install 'bgsub[train]' "
            "(or pip install scikit-image)"
        ) from None
    return data


def load_photos(names: Sequence[str], *, scale: float = 1.0) -> List[np.ndarray]:
    """Gray photographs from ``skimage.data``.

    Parameters
    ----------
    names : sequence of str
        ``skimage.data`` image names, e.g. :data:`TRAIN_IMAGES`; ``"motorcycle"`` is the left view
        of ``stereo_motorcycle``.
    scale : float
        Resize factor (``INTER_AREA``); 0.5 makes the texture finer per pixel, like video frames.

    Returns
    -------
    list of (H, W) float32 arrays, gray values in [0, 1].

    Raises
    ------
    InputError
        scikit-image is missing or a name is not one of its bundled images.
    """
    data = _skimage_data()
    photos = []
    for name in names:
        try:
            if name == "motorcycle":
                image = data.stereo_motorcycle()[0]
            else:
                image = getattr(data, name)()
        except AttributeError:
            raise InputError(f"scikit-image has no bundled image named {name!r}") from None
        except Exception as err:  # e.g. an image that needs a download in this install
            raise InputError(f"cannot load skimage.data.{name}: {err}") from None
        image = np.asarray(image)
        if image.ndim == 3:
            image = image[..., :3]
            image = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
        gray = image.astype(np.float32)
        if image.dtype == np.uint8:
            gray /= 255.0
        elif gray.max() > 1.0:
            gray /= gray.max()
        if scale != 1.0:
            gray = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        photos.append(np.ascontiguousarray(gray, dtype=np.float32))
    return photos


@dataclass
class ShiftedSample:
    """Patch pairs with their true motion.

    Attributes
    ----------
    x, y : (N, p*p) float32
        Patches of the photo and of its moved copy, gray values in [0, 1].
    disp : (N, 2) float32
        ``(dx, dy)`` of the patch centre: ``y`` shows at its centre what ``x`` shows at its
        centre, moved by ``disp`` (sub-pixel).
    rotation : (N,) float32
        Rotation of the moved copy in degrees (counter-clockwise in image coordinates).
    zoom : (N,) float32
        Scale factor of the moved copy.
    image : (N,) int64
        Index of the photo each pair came from.
    """

    x: np.ndarray
    y: np.ndarray
    disp: np.ndarray
    rotation: np.ndarray
    zoom: np.ndarray
    image: np.ndarray


@dataclass
class ShiftedImagePairs:
    """Pair source: patches of photographs and of moved copies of them.

    Use as the trainer's ``pairs(rng, n, epoch)``; :meth:`sample` also returns the true motion.

    The moved copy ``I2`` of a photo ``I`` satisfies ``I2(c + d + A (q - c)) = I(q)`` around the
    patch centre ``c``, with ``d`` the shift and ``A`` a rotation by ``theta`` times a zoom ``s``.
    Both patches are sampled with bilinear interpolation at a sub-pixel centre, so both see the
    same interpolation blur (otherwise "y is blurrier" would be a cue unrelated to motion).
    Every sample point lies inside the photo: no wrap-around, no padding.

    Attributes
    ----------
    images : list of (H, W) float32 in [0, 1]
    max_shift : float
        Shifts ``d`` are uniform in ``[-max_shift, max_shift]^2`` (pixels).
    integer_shifts : bool
        Round shifts and centres to whole pixels (exact copies when there is no rotation/zoom).
    max_rotation : float
        Rotations uniform in ``[-max_rotation, max_rotation]`` degrees.
    max_zoom : float
        Zoom ``s`` uniform in ``[1 - max_zoom, 1 + max_zoom]``.
    noise : float
        Standard deviation of independent Gaussian noise added to each patch (gray units).
    min_contrast : float
        Pairs whose first patch has an RMS contrast below this are redrawn (flat sky carries no
        motion signal; 0 keeps everything).
    curriculum : bgsub.model.training.Curriculum
        Narrower shift ranges in early epochs (``Curriculum.parse("100:1,200:2")``: at most 1 px
        before epoch 100, 2 px before 200, then ``max_shift``). Default: always ``max_shift``.
    patch_size : int
    """

    images: List[np.ndarray]
    max_shift: float = 3.0
    integer_shifts: bool = False
    max_rotation: float = 3.0
    max_zoom: float = 0.03
    noise: float = 0.005
    min_contrast: float = 0.02
    curriculum: Curriculum = field(default_factory=Curriculum)
    patch_size: int = 13
    _flat: np.ndarray = field(init=False, repr=False)
    _offsets: np.ndarray = field(init=False, repr=False)
    _shapes: np.ndarray = field(init=False, repr=False)
    _centres: np.ndarray = field(init=False, repr=False)
    _widest: float = field(init=False, repr=False)
    _centre_count: np.ndarray = field(init=False, repr=False)
    _centre_start: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not self.images:
            raise InputError("no images to sample training pairs from")
        self.images = [np.ascontiguousarray(im, dtype=np.float32) for im in self.images]
        shapes = np.array([im.shape for im in self.images], dtype=np.int64)
        widest = float(self.max_shift)
        margin = int(np.ceil(self._margin(widest)))
        self._widest = widest
        self._shapes = shapes
        sizes = shapes[:, 0] * shapes[:, 1]
        self._offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self._flat = np.concatenate([im.ravel() for im in self.images])
        # Candidate patch centres: far enough from the border for the widest shift, and with
        # some texture (local RMS contrast), so sampling needs (almost) no rejection.
        p = self.patch_size
        centres = []
        for k, im in enumerate(self.images):
            h, w = im.shape
            if min(h, w) <= 2 * margin + 2:
                raise InputError(f"image {k} ({w}x{h}) is too small for {p}x{p} patches moved by {widest} px")
            mean = cv2.boxFilter(im, -1, (p, p))
            var = cv2.boxFilter(im * im, -1, (p, p)) - mean * mean
            ok = np.zeros((h, w), bool)
            ok[margin:h - margin - 1, margin:w - margin - 1] = True
            ok &= var >= (0.9 * self.min_contrast) ** 2
            centres.append(self._offsets[k] + np.flatnonzero(ok))
        self._centre_count = np.array([len(c) for c in centres], np.int64)
        empty = np.flatnonzero(self._centre_count == 0)
        if len(empty):
            raise InputError(f"image {empty[0]} holds no patch with contrast >= {self.min_contrast}")
        self._centre_start = np.concatenate([[0], np.cumsum(self._centre_count)[:-1]])
        self._centres = np.concatenate(centres)

    def _margin(self, max_shift: float) -> float:
        """Distance from a candidate centre pixel to the farthest sample point of a pair, plus
        the sub-pixel jitter (0.5) and the bilinear support (1), with some slack."""
        half = (self.patch_size - 1) / 2.0
        return np.sqrt(2.0) * (half + max_shift) / (1.0 - self.max_zoom) + 2.5

    def shift_range(self, epoch: int) -> float:
        """The ``max_shift`` in force at ``epoch`` (see ``curriculum``)."""
        return float(self.curriculum.limit(epoch, self.max_shift))

    def _bilinear(self, image: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """Bilinear samples of photo ``image[n]`` at ``(px[n, i], py[n, i])`` (all inside)."""
        fx0, fy0 = np.floor(px), np.floor(py)
        fx = (px - fx0).astype(np.float32)
        fy = (py - fy0).astype(np.float32)
        x0, y0 = fx0.astype(np.int64), fy0.astype(np.int64)
        width = self._shapes[image, 1][:, None]
        base = self._offsets[image][:, None] + y0 * width + x0
        f = self._flat
        top = f[base] * (1 - fx) + f[base + 1] * fx
        bottom = f[base + width] * (1 - fx) + f[base + width + 1] * fx
        return (top * (1 - fy) + bottom * fy).astype(np.float32)

    def sample(self, rng: np.random.Generator, n: int, *, max_shift: Optional[float] = None) -> ShiftedSample:
        """``n`` patch pairs with their true motion.

        Parameters
        ----------
        rng : numpy.random.Generator
        n : int
        max_shift : float, optional
            Overrides :attr:`max_shift` (e.g. from the curriculum).

        Returns
        -------
        ShiftedSample
        """
        s = self.max_shift if max_shift is None else float(max_shift)
        if s > self._widest:
            raise ValueError(f"max_shift {s} exceeds the {self._widest} px the centres were chosen for")
        p = self.patch_size
        half = (p - 1) / 2.0
        gy, gx = np.mgrid[0:p, 0:p].astype(np.float64) - half
        gx, gy = gx.ravel()[None, :], gy.ravel()[None, :]  # row-major patch grid offsets

        out_x = np.empty((n, p * p), np.float32)
        out_y = np.empty((n, p * p), np.float32)
        disp = np.empty((n, 2), np.float32)
        rot = np.empty(n, np.float32)
        zoom = np.empty(n, np.float32)
        image = np.empty(n, np.int64)
        filled = 0
        accept = 0.9  # running guess of the fraction of pairs that pass the contrast check
        for _ in range(50):  # redraw the few flat pairs; one or two rounds normally suffice
            m = n - filled
            if m <= 0:
                break
            m_draw = int(1.1 * m / accept) + 8
            # Every photo equally often (a big, mostly dark one must not dominate), then a
            # random textured centre inside it.
            img = rng.integers(0, len(self.images), m_draw)
            pick = self._centre_start[img] + (rng.random(m_draw) * self._centre_count[img]).astype(np.int64)
            flat_idx = self._centres[pick]
            local = flat_idx - self._offsets[img]
            w = self._shapes[img, 1]
            # Centre = a candidate pixel plus sub-pixel jitter (whole pixels for integer shifts).
            cx = (local % w).astype(np.float64)
            cy = (local // w).astype(np.float64)
            if not self.integer_shifts:
                cx += rng.random(m_draw) - 0.5
                cy += rng.random(m_draw) - 0.5
            d = rng.uniform(-s, s, size=(m_draw, 2))
            if self.integer_shifts:
                d = np.round(d)
            theta = np.deg2rad(rng.uniform(-self.max_rotation, self.max_rotation, m_draw))
            sc = rng.uniform(1 - self.max_zoom, 1 + self.max_zoom, m_draw)
            # y(q) = I(c + A^-1 (g - d)) for the grid offset g = q - c.
            cos, sin = np.cos(theta)[:, None] / sc[:, None], np.sin(theta)[:, None] / sc[:, None]
            ux, uy = gx - d[:, :1], gy - d[:, 1:]
            sx = cx[:, None] + cos * ux + sin * uy
            sy = cy[:, None] - sin * ux + cos * uy
            xs = self._bilinear(img, cx[:, None] + gx, cy[:, None] + gy)
            ys = self._bilinear(img, sx, sy)
            if self.noise > 0:
                xs += rng.normal(0.0, self.noise, xs.shape).astype(np.float32)
                ys += rng.normal(0.0, self.noise, ys.shape).astype(np.float32)
            keep = xs.std(axis=1) >= self.min_contrast
            accept = max(float(keep.mean()), 0.02)
            idx = np.flatnonzero(keep)[:m]
            k = len(idx)
            sl = slice(filled, filled + k)
            out_x[sl], out_y[sl], disp[sl] = xs[idx], ys[idx], d[idx]
            rot[sl], zoom[sl], image[sl] = np.rad2deg(theta[idx]), sc[idx], img[idx]
            filled += k
        if filled < n:
            raise InputError(
                f"the photos hold too few patches with contrast >= {self.min_contrast}; lower min_contrast"
            )
        return ShiftedSample(x=out_x, y=out_y, disp=disp, rotation=rot, zoom=zoom, image=image)

    def __call__(self, rng: np.random.Generator, n: int, epoch: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        """The trainer's pair source: ``(X, Y)``, each ``(n, p*p) float32`` in [0, 1]."""
        sample = self.sample(rng, n, max_shift=self.shift_range(epoch))
        return sample.x, sample.y


def shifted_image_pairs(
    *,
    names: Optional[Sequence[str]] = None,
    split: str = "train",
    scale: float = 1.0,
    max_shift: float = 3.0,
    integer_shifts: bool = False,
    max_rotation: float = 3.0,
    max_zoom: float = 0.03,
    noise: float = 0.005,
    min_contrast: float = 0.02,
    curriculum: Optional[Curriculum] = None,
    patch_size: int = 13,
    blur: Sequence[float] = (),
    motion_blur: int = 0,
) -> ShiftedImagePairs:
    """Pair source of shifted (and slightly rotated / zoomed) photographs.

    Parameters
    ----------
    names : sequence of str, optional
        ``skimage.data`` images; default :data:`TRAIN_IMAGES` (``split="train"``) or
        :data:`TEST_IMAGES` (``split="test"``, the held-out photos).
    split : {"train", "test"}
    scale : float
        Resize factor applied to the photos (see :func:`load_photos`).
    max_shift, integer_shifts, max_rotation, max_zoom, noise, min_contrast, curriculum, patch_size
        See :class:`ShiftedImagePairs`.
    blur : sequence of float
        Also use every photo blurred by a Gaussian of each of these sigmas (px), like soft or
        compressed video frames (both patches of a pair come from the same blurred photo).
    motion_blur : int
        Also use every photo box-blurred over this many pixels horizontally and, separately,
        vertically, like the frames of a panning or shaking camera (0 = no).

    Returns
    -------
    ShiftedImagePairs, callable as ``pairs(rng, n, epoch) -> (X, Y)``.
    """
    if names is None:
        if split not in ("train", "test"):
            raise InputError(f"split must be 'train' or 'test', not {split!r}")
        names = TRAIN_IMAGES if split == "train" else TEST_IMAGES
    return ShiftedImagePairs(
        images=degraded_copies(load_photos(names, scale=scale), blur=blur,
                               motion_blur=motion_blur),
        max_shift=max_shift,
        integer_shifts=integer_shifts,
        max_rotation=max_rotation,
        max_zoom=max_zoom,
        noise=noise,
        min_contrast=min_contrast,
        curriculum=curriculum if curriculum is not None else Curriculum(),
        patch_size=patch_size,
    )


def degraded_copies(photos: Sequence[np.ndarray], *, blur: Sequence[float] = (),
                    motion_blur: int = 0) -> List[np.ndarray]:
    """``photos`` followed by their blurred copies (see :func:`shifted_image_pairs`).

    Parameters
    ----------
    photos : sequence of (H, W) float32
    blur : sequence of float
        Gaussian sigmas (px); each adds one copy of every photo.
    motion_blur : int
        Box length (px); when > 1 adds a horizontally and a vertically blurred copy of every
        photo.

    Returns
    -------
    list of (H, W) float32
    """
    out = list(photos)
    for sigma in blur:
        if sigma <= 0:
            raise InputError(f"blur sigmas must be positive, not {sigma}")
        out += [cv2.GaussianBlur(im, (0, 0), float(sigma)) for im in photos]
    if motion_blur > 1:
        n = int(motion_blur)
        out += [cv2.blur(im, (n, 1)) for im in photos]
        out += [cv2.blur(im, (1, n)) for im in photos]
    return out


def warped_frame_pair(
    image: np.ndarray,
    rng: np.random.Generator,
    *,
    max_shift: float = 3.0,
    max_rotation: float = 0.5,
    max_zoom: float = 0.005,
) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A whole frame pair: a photo and a globally moved copy, with the exact flow.

    For benchmarks that need whole frames (block matching searches around each patch).

    Parameters
    ----------
    image : (H, W) float32 in [0, 1]
    rng : numpy.random.Generator
    max_shift, max_rotation, max_zoom : float
        As in :class:`ShiftedImagePairs`, but the rotation/zoom is about the image centre, so
        it moves far pixels more: the defaults add at most ~2.5 px at the corners of a 512 px
        photo.

    Returns
    -------
    frame1, frame2 : (H, W) uint8
    flow : (H, W, 2) float32
        ``(dx, dy)`` of every pixel of ``frame1``; NaN where it leaves the frame.
    """
    h, w = image.shape
    d = rng.uniform(-max_shift, max_shift, 2)
    theta = np.deg2rad(rng.uniform(-max_rotation, max_rotation))
    s = rng.uniform(1 - max_zoom, 1 + max_zoom)
    c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    a = s * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    # p' = c + d + A (p - c): the same map as ShiftedImagePairs, about the image centre.
    affine = np.hstack([a, (c + d - a @ c)[:, None]])
    frame1 = np.clip(np.rint(image * 255), 0, 255).astype(np.uint8)
    frame2 = cv2.warpAffine(frame1, affine, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    tx = affine[0, 0] * xs + affine[0, 1] * ys + affine[0, 2]
    ty = affine[1, 0] * xs + affine[1, 1] * ys + affine[1, 2]
    flow = np.stack([tx - xs, ty - ys], axis=2).astype(np.float32)
    outside = (tx < 0) | (tx > w - 1) | (ty < 0) | (ty > h - 1)
    flow[outside] = np.nan
    return frame1, frame2, flow


@dataclass
class VideoFramePairs:
    """Pair source: a pool of patch pairs cut from consecutive frames of videos.

    Built once by :func:`video_frame_pairs` (streaming the videos, constant memory apart from
    the pool); each call then draws ``n`` pairs from the pool.

    Attributes
    ----------
    x, y : (M, p*p) uint8
        The pool (gray values 0-255; converted to [0, 1] float32 when drawn).
    patch_size : int
    """

    x: np.ndarray
    y: np.ndarray
    patch_size: int = 13

    def __len__(self) -> int:
        return len(self.x)

    def __call__(self, rng: np.random.Generator, n: int, epoch: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        """The trainer's pair source: ``(X, Y)``, each ``(n, p*p) float32`` in [0, 1]."""
        idx = rng.integers(0, len(self.x), n)
        scale = np.float32(1.0 / 255.0)
        return self.x[idx].astype(np.float32) * scale, self.y[idx].astype(np.float32) * scale


def video_frame_pairs(
    paths: Sequence[PathLike],
    *,
    pool_size: int = 50_000,
    patches_per_pair: int = 64,
    min_contrast: float = 0.03,
    patch_size: int = 13,
    step: int = 1,
    stop: Optional[int] = None,
    scale: Optional[float] = None,
    seed: int = 0,
) -> VideoFramePairs:
    """Patch pairs from consecutive frames of the user's videos (unsupervised training data).

    Each consecutive frame pair contributes ``patches_per_pair`` random patch positions (same
    place in both frames: the camera's and objects' real motion is what the pair shows). Flat
    patches are skipped; a reservoir keeps a uniform sample of at most ``pool_size`` pairs over
    all videos, so memory stays bounded however long the videos are.

    Parameters
    ----------
    paths : sequence of str
        Videos, image folders or globs (anything :func:`bgsub.io.sources.open_source` reads).
    pool_size : int
        Maximum number of pairs kept (``pool_size * 2 * p * p`` bytes).
    patches_per_pair : int
        Positions sampled per consecutive frame pair.
    min_contrast : float
        Minimum RMS contrast (gray in [0, 1]) of the first patch.
    patch_size : int
    step : int
        Use every ``step``-th frame (larger motion per pair).
    stop : int, optional
        Read at most up to this frame of each video.
    scale : float, optional
        Resize frames (e.g. 0.5 halves the motion, keeping it within the model's range).
    seed : int
        Seed of the patch positions and the reservoir.

    Returns
    -------
    VideoFramePairs, callable as ``pairs(rng, n, epoch) -> (X, Y)``.

    Raises
    ------
    InputError
        A path cannot be read (from :func:`open_source`) or no usable pair was found.
    """
    from bgsub.io.sources import open_source  # imported late: only needed for video training

    rng = np.random.default_rng(seed)
    p = patch_size
    n_pix = p * p
    pool_x = np.empty((pool_size, n_pix), np.uint8)
    pool_y = np.empty((pool_size, n_pix), np.uint8)
    seen = 0
    iy, ix = np.mgrid[0:p, 0:p]
    iy, ix = iy.ravel()[None, :], ix.ravel()[None, :]
    for path in paths:
        previous = None
        with open_source(str(path), stop=stop, step=step, scale=scale) as source:
            for _, frame in source:
                gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
                if previous is not None and min(gray.shape) >= p:
                    h, w = gray.shape
                    top = rng.integers(0, h - p + 1, patches_per_pair)[:, None]
                    left = rng.integers(0, w - p + 1, patches_per_pair)[:, None]
                    xs = previous[top + iy, left + ix]
                    ys = gray[top + iy, left + ix]
                    keep = xs.astype(np.float32).std(axis=1) >= min_contrast * 255
                    xs, ys = xs[keep], ys[keep]
                    k = len(xs)
                    # Reservoir sampling (Vitter's algorithm R), vectorised over the batch.
                    counts = seen + 1 + np.arange(k)
                    direct = counts <= pool_size
                    slots = np.where(direct, counts - 1, rng.integers(0, counts))
                    take = slots < pool_size
                    pool_x[slots[take]] = xs[take]
                    pool_y[slots[take]] = ys[take]
                    seen += k
                previous = gray
    size = min(seen, pool_size)
    if size == 0:
        raise InputError(
            f"no textured patch pairs found in {', '.join(map(str, paths)) or 'no videos'} "
            "(need at least two frames of at least 13x13 pixels)"
        )
    return VideoFramePairs(x=pool_x[:size].copy(), y=pool_y[:size].copy(), patch_size=p)
