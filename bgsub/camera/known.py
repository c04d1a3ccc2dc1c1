"""Camera motion given, not fitted (:class:`KnownMotion`: an IMU, a gimbal, a previous run), and
the scale between input and working-size pixels (:func:`work_scale`)."""

from __future__ import annotations

import os
from typing import Any, Optional

import numpy as np

from bgsub.errors import InputError
from bgsub.motion.global_motion import GlobalMotion, apply_homography

__all__ = ["KNOWN_MOTION_HELP", "KnownMotion", "NoKnownMotion", "work_scale"]


#: What the ``known_motion`` parameter of the moving-camera engines means (``bgsub methods``).
KNOWN_MOTION_HELP = ("camera motion to use instead of fitting it: an (N, 3, 3) .npy file as "
                     "--motion writes it (entry k maps input pixels of frame k-1 to frame k, "
                     "frames counted from 0 as the engine is given them) or, from Python, the "
                     "array; entries all NaN, and frames past its end, are fitted as usual "
                     "(empty = fit every frame)")


def _load_motion(path: str) -> np.ndarray:
    """The array in the ``.npy`` file ``path`` (``allow_pickle=False``)."""
    if not os.path.isfile(path):
        what = "is a folder" if os.path.isdir(path) else "no such file"
        raise InputError(f"{path}: {what} (the known camera motion, an .npy file)")
    expected = ("the known camera motion is an (N, 3, 3) float array saved by numpy.save as "
                "an .npy file, without pickled objects, as bgsub run --motion writes it")
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
        if magic != b"\x93NUMPY":
            what = "an .npz archive" if magic[:2] == b"PK" else "not an .npy file"
            raise InputError(f"{path}: {what}; {expected}")
        array = np.load(path, allow_pickle=False)
    except (OSError, EOFError) as err:
        raise InputError(f"{path}: cannot read the known camera motion "
                         f"({str(err).splitlines()[0] if str(err) else type(err).__name__})"
                         ) from None
    except ValueError:  # pickled objects, or a damaged header
        raise InputError(f"{path}: not a plain numeric .npy array; {expected}") from None
    return array


class KnownMotion:
    """Camera motion given, not fitted: ``matrices`` ``(N, 3, 3)``, entry ``k`` mapping pixel
    coordinates of the input's frame ``k - 1`` to frame ``k`` (frames counted as the engine is
    given them, from 0; the layout ``bgsub run --motion`` writes, so a run with the same
    ``--start``/``--step`` reads its own file back). Entries all NaN are fitted as usual, and
    so are frames past the last entry (:attr:`frames_past_end` counts them).

    The front end still measures local motion (the motion evidence needs it); the camera fit it
    is handed (:meth:`fit`) returns the given motion, with the vectors that agree with it
    within the RANSAC threshold as its inliers."""

    def __init__(self, matrices: Any, *, name: str = "the known camera motion") -> None:
        array = np.asarray(matrices)
        if array.ndim != 3 or array.shape[1:] != (3, 3) or not len(array) \
                or array.dtype.kind not in "iuf":
            raise InputError(f"{name} must be an (N, 3, 3) array of numbers, one matrix per "
                             f"frame, not {array.dtype} of shape {array.shape}")
        array = array.astype(np.float64)
        unknown = np.isnan(array).all(axis=(1, 2))
        bad = ~unknown & ~np.isfinite(array).all(axis=(1, 2))
        if bad.any():
            raise InputError(f"{name}: entry {int(np.flatnonzero(bad)[0])} is partly not "
                             "finite (only entries all NaN mean 'fit this frame')")
        scale = array[:, 2, 2]
        singular = ~unknown & ((np.abs(scale) < 1e-12) | (np.abs(np.linalg.det(
            np.where(unknown[:, None, None], np.eye(3), array))) < 1e-12))
        if singular.any():
            raise InputError(f"{name}: entry {int(np.flatnonzero(singular)[0])} is singular, "
                             "not a camera motion")
        self.matrices = np.where(unknown[:, None, None], np.nan,
                                 array / np.where(unknown, 1.0, scale)[:, None, None])
        self.name = name
        self.frame = -1  # the frame being processed (0-based), -1 before the first
        self.frames_past_end = 0

    @classmethod
    def from_value(cls, value: Any) -> "KnownMotion":
        """From an ``.npy`` file's path, an array, or a :class:`KnownMotion` (a fresh copy,
        its frame count at the start)."""
        if isinstance(value, KnownMotion):
            return cls(value.matrices, name=value.name)
        if isinstance(value, (str, os.PathLike)):
            path = os.fspath(value)
            return cls(_load_motion(path), name=path)
        return cls(value)

    def next_frame(self) -> None:
        """Count a frame given to the engine."""
        self.frame += 1
        if self.frame >= len(self.matrices):
            self.frames_past_end += 1

    def matrix(self, in_shape: tuple, work_shape: tuple) -> Optional[np.ndarray]:
        """The given motion of the current frame ``(3, 3) float64`` in working-size pixels
        (frames of ``in_shape`` ``(H, W, ...)`` processed at ``work_shape`` ``(h, w)``), or
        None where it is to be fitted."""
        if not 0 < self.frame < len(self.matrices) or np.isnan(self.matrices[self.frame, 0, 0]):
            return None
        scale = work_scale(in_shape, work_shape)
        return scale @ self.matrices[self.frame] @ np.linalg.inv(scale)

    @staticmethod
    def fit(matrix: np.ndarray, threshold: float) -> Any:
        """A camera fit (``fit(points, disp, weights, shape)``, as
        :class:`~bgsub.engines.frontend.CameraFit`) that returns ``matrix`` (3, 3), with the
        usable vectors within ``threshold`` px of it as inliers."""

        def given(points: np.ndarray, disp: np.ndarray, weights: np.ndarray,
                  shape: tuple) -> GlobalMotion:
            pts = np.asarray(points, np.float64).reshape(-1, 2)
            moved = pts + np.asarray(disp, np.float64).reshape(-1, 2)
            error = np.hypot(*(apply_homography(matrix, pts) - moved).T) if len(pts) else \
                np.zeros(0)
            return GlobalMotion(matrix.copy(), (np.asarray(weights) > 0) & (error < threshold),
                                True)

        return given


class NoKnownMotion:
    """No camera motion given: every frame's motion is fitted."""

    frames_past_end = 0

    def next_frame(self) -> None:
        """Nothing to count."""

    def matrix(self, in_shape: tuple, work_shape: tuple) -> None:
        """None: the motion is to be fitted."""
        return None


def work_scale(in_shape: tuple, work_shape: tuple) -> np.ndarray:
    """``(3, 3) float64``: input pixel coordinates of ``in_shape`` ``(H, W, ...)`` frames to
    those of their ``work_shape`` ``(h, w)`` resized copies (``cv2.resize``'s pixel centres)."""
    sx, sy = work_shape[1] / in_shape[1], work_shape[0] / in_shape[0]
    return np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)],
                     [0.0, 0.0, 1.0]])
