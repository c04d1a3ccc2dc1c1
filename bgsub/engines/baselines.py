"""Classical background subtractors for a static camera: ``mog2``, ``knn`` and ``framediff``.

They are the yardstick the moving-camera engines are measured against: excellent on a tripod,
poor as soon as the camera moves (every edge of the scene then looks like motion).

* ``mog2`` wraps ``cv2.createBackgroundSubtractorMOG2`` (Zivkovic 2004/2006: a per-pixel mixture
  of Gaussians with an adaptive number of components);
* ``knn`` wraps ``cv2.createBackgroundSubtractorKNN`` (Zivkovic & van der Heijden 2006: per-pixel
  sample sets, foreground when fewer than k samples are near);
* ``framediff`` thresholds the absolute gray-level difference to the previous frame.

All parameter defaults are OpenCV's, except ``detect_shadows``, which is off: bgsub masks are
strictly 0/255, and a shadow is background in CDnet's ground truth. With shadows on, OpenCV marks
them 127; these engines map them to 0 (background), so the mask contract holds either way.
"""

from __future__ import annotations

import functools
from typing import Any, Callable, Optional, Tuple

import cv2
import numpy as np

from bgsub.engines import (LEARNING_RATE, Engine, Param, check_fgmask, check_frame,
                           check_learning_rate, opencv_keywords, register_engine)
from bgsub.errors import InputError

# OpenCV's non-shadow foreground value; everything at or below SHADOW_CUT (shadows are 127) is
# background in a bgsub mask.
_SHADOW_CUT = 127

#: Largest per-pixel model (bytes) an OpenCV subtractor may allocate. OpenCV sizes KNN's model
#: with a C int: above 2 GiB the size wraps round, and it asks for exabytes or, wrapped back
#: into range, allocates too little and crashes (SIGSEGV). No sensible model needs more.
MODEL_BUDGET = 2**31 - 1

#: OpenCV's MOG2 asserts ``nmixtures <= 255`` on its first frame.
_MAX_MIXTURES = 255


def _largest_fitting(bytes_of: Callable[[int], int], guess: int) -> int:
    """The largest value (0 if none) whose ``bytes_of`` (increasing) is within
    :data:`MODEL_BUDGET`, searched from ``guess``, which is close."""
    value = max(0, guess)
    while value > 0 and bytes_of(value) > MODEL_BUDGET:
        value -= 1
    while bytes_of(value + 1) <= MODEL_BUDGET:
        value += 1
    return value


def _mog2_model_bytes(pixels: int, channels: int, n_mixtures: int) -> int:
    """Bytes of OpenCV MOG2's model: per pixel and component, a weight, a variance and a mean
    per channel (float32), plus a mode count per pixel."""
    return pixels * (4 * n_mixtures * (2 + channels) + 1)


def _knn_model_bytes(pixels: int, channels: int, n_samples: int) -> int:
    """Bytes of OpenCV KNN's model: per pixel, three sample sets (short, mid, long term) of
    ``n_samples`` samples of the channels plus a flag byte; the C int OpenCV sizes it with."""
    return pixels * n_samples * 3 * (channels + 1)


def _binarize_into(raw: np.ndarray, fgmask: Optional[np.ndarray]) -> np.ndarray:
    """Map an OpenCV mask (0 / 127 shadow / 255) to 0/255, in ``fgmask`` when given.

    Parameters
    ----------
    raw : (H, W) uint8
        Mask as OpenCV returns it.
    fgmask : (H, W) uint8, optional
        Output buffer (already checked by :func:`check_fgmask`), written in place.

    Returns
    -------
    (H, W) uint8 with values 0 and 255 only (``fgmask`` itself when given).
    """
    _, out = cv2.threshold(raw, _SHADOW_CUT, 255, cv2.THRESH_BINARY)
    if fgmask is None:
        return out
    fgmask[...] = out  # (not dst=fgmask: OpenCV cannot write into a strided view)
    return fgmask


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise InputError(message)


class OpenCVSubtractor(Engine):
    """An OpenCV ``BackgroundSubtractor`` whose masks are made strictly 0/255.

    Parameters
    ----------
    make : callable
        ``make() -> cv2.BackgroundSubtractor``: a configured MOG2 or KNN subtractor; called
        again for ``learning_rate=1`` ("restart from this frame").
    learning_rate : float
        The rate of a call to :meth:`apply` that gives none (negative: OpenCV's automatic).
    min_rate : float
        Rates in [0, ``min_rate``) are passed as ``min_rate``: OpenCV's KNN divides by
        ``log(1 - rate)`` and at 0 stops detecting anything instead of freezing its model.
    first_frame_repeats : int
        With such a rate on the very first frame, the subtractor first learns that frame this
        many times at its automatic rate (KNN: its sample count, so the frozen model is that
        frame rather than empty sample sets).
    name : str
        The engine's name, for messages.
    seed : int, optional
        The seed the caller gave OpenCV's generator (``cv2.setRNGSeed``) when it made the
        engine; given again when a pickled engine is loaded (in another process, say).
    model_size : (str, int, callable), optional
        ``(parameter, value, bytes_of)``: the parameter that sizes the per-pixel model, its
        value, and ``bytes_of(pixels, channels, value)``; the first frame is refused (with the
        largest value that fits) when the model would exceed :data:`MODEL_BUDGET`.

    An engine pickles (and deep-copies) before its first frame only: OpenCV's model cannot.
    """

    def __init__(self, make: Callable[[], Any], *, learning_rate: float = -1.0,
                 min_rate: float = 0.0, first_frame_repeats: int = 0, name: str = "opencv",
                 seed: Optional[int] = None,
                 model_size: Optional[Tuple[str, int, Callable[[int, int, int], int]]] = None
                 ) -> None:
        self._make = make
        self.name = name
        self.seed = seed
        self.model_size = model_size
        self.subtractor = make()
        self.learning_rate = float(learning_rate)
        self.min_rate = float(min_rate)
        self.first_frame_repeats = int(first_frame_repeats)
        # (H, W) of the stream, None before the first frame (OpenCV's KNN crashes on
        # getBackgroundImage() then).
        self._shape: Optional[tuple] = None

    @opencv_keywords
    def apply(
        self,
        image: np.ndarray,
        fgmask: Optional[np.ndarray] = None,
        learning_rate: float = -1.0,
    ) -> np.ndarray:
        """Next frame -> ``(H, W) uint8`` 0/255 mask; see :meth:`bgsub.engines.Engine.apply`."""
        image = check_frame(image, shape=self._shape)
        rate = check_learning_rate(learning_rate, default=self.learning_rate)
        check_fgmask(fgmask, image.shape[:2])
        if self._shape is None:
            self._check_model_size(image.shape)
        if rate >= 1.0:
            # A fresh model of this frame, the same way for both subtractors (KNN at rate 1
            # calls every later pixel foreground).
            self.subtractor, rate = self._make(), -1.0
        elif 0.0 <= rate < self.min_rate:
            rate = self.min_rate
            if self._shape is None:
                # Frozen from the first frame: that frame is the model. At min_rate KNN would
                # keep its sample sets empty and call every pixel foreground for good.
                for _ in range(self.first_frame_repeats):
                    self.subtractor.apply(image, learningRate=-1.0)
        raw = self.subtractor.apply(image, learningRate=rate)
        self._shape = image.shape
        return _binarize_into(raw, fgmask)

    def _check_model_size(self, shape: tuple) -> None:
        """Refuse frames of ``shape`` ((H, W) or (H, W, 3)) whose model would exceed
        :data:`MODEL_BUDGET`, before OpenCV allocates it."""
        if self.model_size is None:
            return
        param, value, bytes_of = self.model_size
        pixels, channels = shape[0] * shape[1], (shape[2] if len(shape) == 3 else 1)
        needed = bytes_of(pixels, channels, value)
        if needed <= MODEL_BUDGET:
            return
        fits = _largest_fitting(lambda v: bytes_of(pixels, channels, v),
                                value * MODEL_BUDGET // needed)
        kind = "colour" if channels == 3 else "gray"
        advice = (f"give {param} at most {fits} for frames of this size, or smaller frames"
                  if fits else "give smaller frames")
        raise InputError(f"{self.name}: {param}={value} needs a {needed / 2**30:.1f} GiB model "
                         f"for {shape[1]}x{shape[0]} {kind} frames, above the "
                         f"{(MODEL_BUDGET + 1) // 2**30} GiB a background model may take: {advice}")

    def get_background_image(self) -> Optional[np.ndarray]:
        """OpenCV's background estimate (like the input: gray or BGR uint8), ``None`` at first."""
        if self._shape is None:
            return None
        return self.subtractor.getBackgroundImage()

    def __getstate__(self) -> dict:
        # OpenCV keeps the model in C++, out of pickle's (and deepcopy's) reach: only an engine
        # that has seen no frame, whose model is what make() builds, travels (to the worker
        # processes of a pool, say). One mid-video would come back with an empty model.
        if self._shape is not None:
            raise TypeError(f"a {self.name} engine that has processed frames cannot be pickled "
                            "or copied (OpenCV keeps its model out of Python's reach): pickle "
                            "or copy it before its first frame, or create one where it runs")
        state = dict(self.__dict__)
        del state["subtractor"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.subtractor = self._make()
        if self.seed is not None:
            cv2.setRNGSeed(self.seed)  # as when the engine was made: the same masks there


_MOG2_PARAMS = {
    "history": Param(500, "number of recent frames that shape the background model", low=1),
    "var_threshold": Param(
        16.0, "squared Mahalanobis distance above which a pixel is foreground (higher: fewer "
        "detections)", above=0
    ),
    "detect_shadows": Param(
        False, "detect shadows (OpenCV marks them 127; bgsub maps them to background); slower"
    ),
    "background_ratio": Param(
        0.9, "fraction of the model weight that counts as background: a foreground value "
        "that stays for about background_ratio*history frames becomes background",
        above=0, high=1
    ),
    "n_mixtures": Param(
        5, "maximum number of Gaussian components per pixel (at most 255, OpenCV's limit; the "
        "model, 4 (2 + channels) n_mixtures bytes per pixel, may not exceed 2 GiB)",
        low=1, high=_MAX_MIXTURES
    ),
    "var_threshold_gen": Param(
        9.0, "squared Mahalanobis distance under which a value updates an existing component "
        "instead of creating a new one", above=0
    ),
    "var_init": Param(15.0, "initial variance of a new component", above=0),
    "var_min": Param(4.0, "lower bound on a component's variance", above=0),
    "var_max": Param(75.0, "upper bound on a component's variance (at least var_min)", above=0),
    "complexity_reduction_threshold": Param(
        0.05, "evidence (in samples) a component needs to survive; 0 gives the standard "
        "Stauffer-Grimson mixture", low=0
    ),
    "shadow_threshold": Param(
        0.5, "a pixel is shadow if it is a darker version of the background by at most this "
        "factor (0.5: twice as dark is not a shadow; below 1)", above=0, high=1
    ),
    "learning_rate": LEARNING_RATE,
}


@register_engine(
    "mog2",
    "OpenCV MOG2 mixture of Gaussians (Zivkovic); static camera only",
    params=_MOG2_PARAMS,
    common=("history", "var_threshold", "detect_shadows", "learning_rate", "roi"),
)
def make_mog2(
    *,
    history: int,
    var_threshold: float,
    detect_shadows: bool,
    background_ratio: float,
    n_mixtures: int,
    var_threshold_gen: float,
    var_init: float,
    var_min: float,
    var_max: float,
    complexity_reduction_threshold: float,
    shadow_threshold: float,
    learning_rate: float,
) -> OpenCVSubtractor:
    """Build the ``mog2`` engine (parameters as in :data:`_MOG2_PARAMS`, OpenCV defaults)."""
    # Single-value bounds are checked from _MOG2_PARAMS when the engine is made; these involve
    # two parameters or an open end that Param cannot state.
    _require(var_min <= var_max,
             f"mog2: parameter 'var_max' must be at least var_min={var_min:g}, not {var_max!r}")
    _require(shadow_threshold < 1,
             f"mog2: parameter 'shadow_threshold' must be below 1, not {shadow_threshold!r}")

    make = functools.partial(  # (a module-level function: the engine pickles before use)
        _new_mog2, history=history, var_threshold=var_threshold, detect_shadows=detect_shadows,
        background_ratio=background_ratio, n_mixtures=n_mixtures,
        var_threshold_gen=var_threshold_gen, var_init=var_init, var_min=var_min, var_max=var_max,
        complexity_reduction_threshold=complexity_reduction_threshold,
        shadow_threshold=shadow_threshold)
    return OpenCVSubtractor(make, learning_rate=learning_rate, name="mog2",
                            model_size=("n_mixtures", int(n_mixtures), _mog2_model_bytes))


def _new_mog2(*, history: int, var_threshold: float, detect_shadows: bool,
              background_ratio: float, n_mixtures: int, var_threshold_gen: float,
              var_init: float, var_min: float, var_max: float,
              complexity_reduction_threshold: float, shadow_threshold: float) -> Any:
    """A configured ``cv2.BackgroundSubtractorMOG2`` (the ``make`` of the ``mog2`` engine)."""
    sub = cv2.createBackgroundSubtractorMOG2(
        history=int(history), varThreshold=float(var_threshold),
        detectShadows=bool(detect_shadows))
    sub.setBackgroundRatio(float(background_ratio))
    sub.setNMixtures(int(n_mixtures))
    sub.setVarThresholdGen(float(var_threshold_gen))
    sub.setVarInit(float(var_init))
    sub.setVarMin(float(var_min))
    sub.setVarMax(float(var_max))
    sub.setComplexityReductionThreshold(float(complexity_reduction_threshold))
    sub.setShadowThreshold(float(shadow_threshold))
    return sub


_KNN_PARAMS = {
    "history": Param(500, "number of recent frames that shape the background model", low=1),
    "dist2_threshold": Param(
        400.0, "squared colour distance (summed over channels) under which a stored sample "
        "matches the pixel (higher: fewer detections)", above=0
    ),
    "detect_shadows": Param(
        False, "detect shadows (OpenCV marks them 127; bgsub maps them to background); slower"
    ),
    "n_samples": Param(
        7, "number of samples stored per pixel (the model, 3 (channels + 1) n_samples bytes per "
        "pixel, may not exceed 2 GiB: e.g. at most 2330 on 320x240 colour frames)", low=1
    ),
    "knn_samples": Param(
        2, "k: how many stored samples must match for the pixel to be background (at most "
        "n_samples)", low=1
    ),
    "shadow_threshold": Param(
        0.5, "a pixel is shadow if it is a darker version of the background by at most this "
        "factor (0.5: twice as dark is not a shadow; below 1)", above=0, high=1
    ),
    "seed": Param(
        0, "seed given to OpenCV's random generator (cv2.setRNGSeed) when the engine is "
        "created, for reproducible masks: KNN replaces stored samples at random; -1 leaves "
        "the generator alone", low=-1
    ),
    "learning_rate": LEARNING_RATE,
}


@register_engine(
    "knn",
    "OpenCV KNN per-pixel sample sets (Zivkovic & van der Heijden); static camera only",
    params=_KNN_PARAMS,
    common=("history", "dist2_threshold", "detect_shadows", "learning_rate", "roi"),
)
def make_knn(
    *,
    history: int,
    dist2_threshold: float,
    detect_shadows: bool,
    n_samples: int,
    knn_samples: int,
    shadow_threshold: float,
    seed: int,
    learning_rate: float,
) -> OpenCVSubtractor:
    """Build the ``knn`` engine (parameters as in :data:`_KNN_PARAMS`, OpenCV defaults).

    OpenCV's KNN draws from the calling thread's global generator (``cv::theRNG()``), so two
    runs over the same frames differ (about 6 % of the pixels of CDnet traffic over 300
    frames) unless it is seeded; ``seed`` does that once, here. Code that uses OpenCV's
    generator between frames (or a second KNN engine fed in alternation) still shifts it.
    """
    # As for mog2: what Param cannot state.
    _require(knn_samples <= n_samples, f"knn: parameter 'knn_samples' must be at most "
                                       f"n_samples={n_samples}, not {knn_samples!r}")
    _require(shadow_threshold < 1,
             f"knn: parameter 'shadow_threshold' must be below 1, not {shadow_threshold!r}")

    make = functools.partial(_new_knn, history=history, dist2_threshold=dist2_threshold,
                             detect_shadows=detect_shadows, n_samples=n_samples,
                             knn_samples=knn_samples, shadow_threshold=shadow_threshold)
    if seed >= 0:
        cv2.setRNGSeed(int(seed))
    # 1e-6: a sample kept for ~10^5 frames, frozen in practice (see OpenCVSubtractor).
    return OpenCVSubtractor(make, learning_rate=learning_rate, min_rate=1e-6,
                            first_frame_repeats=int(n_samples), name="knn",
                            seed=int(seed) if seed >= 0 else None,
                            model_size=("n_samples", int(n_samples), _knn_model_bytes))


def _new_knn(*, history: int, dist2_threshold: float, detect_shadows: bool, n_samples: int,
             knn_samples: int, shadow_threshold: float) -> Any:
    """A configured ``cv2.BackgroundSubtractorKNN`` (the ``make`` of the ``knn`` engine)."""
    sub = cv2.createBackgroundSubtractorKNN(
        history=int(history), dist2Threshold=float(dist2_threshold),
        detectShadows=bool(detect_shadows))
    sub.setNSamples(int(n_samples))
    sub.setkNNSamples(int(knn_samples))
    sub.setShadowThreshold(float(shadow_threshold))
    return sub


class FrameDifference(Engine):
    """Foreground where the gray level changed by more than ``threshold`` since the last frame.

    The first frame has no predecessor and gives an empty mask. ``learning_rate=0`` keeps the
    current reference frame (OpenCV's "do not update"); any other value replaces it with the
    new frame.

    Parameters
    ----------
    threshold : int
        Gray-level difference (0-255) a pixel must exceed to be foreground.
    morph_size : int
        Side of the elliptic structuring element of a morphological opening that removes
        isolated noise pixels; 0 or 1 turns it off.
    learning_rate : float
        The rate of a call to :meth:`apply` that gives none (negative: replace the reference).
    """

    def __init__(self, *, threshold: int = 25, morph_size: int = 0,
                 learning_rate: float = -1.0) -> None:
        self.threshold = int(threshold)
        self.morph_size = int(morph_size)
        self.learning_rate = float(learning_rate)
        self._kernel = (
            cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (self.morph_size, self.morph_size))
            if self.morph_size > 1
            else None
        )
        self._previous_gray: Optional[np.ndarray] = None
        self._previous_image: Optional[np.ndarray] = None

    @opencv_keywords
    def apply(
        self,
        image: np.ndarray,
        fgmask: Optional[np.ndarray] = None,
        learning_rate: float = -1.0,
    ) -> np.ndarray:
        """Next frame -> ``(H, W) uint8`` 0/255 mask; see :meth:`bgsub.engines.Engine.apply`."""
        previous = self._previous_gray
        image = check_frame(image, shape=None if previous is None else self._previous_image.shape)
        rate = check_learning_rate(learning_rate, default=self.learning_rate)
        check_fgmask(fgmask, image.shape[:2])
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        if previous is None:
            raw = np.zeros(gray.shape, np.uint8)
        else:
            _, raw = cv2.threshold(cv2.absdiff(gray, previous), self.threshold, 255,
                                   cv2.THRESH_BINARY)
            if self._kernel is not None:
                raw = cv2.morphologyEx(raw, cv2.MORPH_OPEN, self._kernel)
        if rate != 0.0 or previous is None:
            self._previous_gray = gray.copy()
            self._previous_image = image.copy()
        return _binarize_into(raw, fgmask)

    def get_background_image(self) -> Optional[np.ndarray]:
        """The reference (previous) frame, like the input, or ``None`` before the first frame."""
        return None if self._previous_image is None else self._previous_image.copy()


@register_engine(
    "framediff",
    "difference to the previous frame, thresholded; static camera only",
    params={
        "threshold": Param(25, "gray-level change (0-255) a pixel must exceed to be foreground",
                           low=0, high=254),
        "morph_size": Param(
            0, "side of an elliptic opening that removes speckle noise (0 or 1: off)",
            low=0, high=31
        ),
        "learning_rate": LEARNING_RATE,
    },
)
def make_framediff(*, threshold: int, morph_size: int, learning_rate: float) -> FrameDifference:
    """Build the ``framediff`` engine."""
    return FrameDifference(threshold=threshold, morph_size=morph_size,
                           learning_rate=learning_rate)
