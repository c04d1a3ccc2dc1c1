"""The moving-camera engine's foreground stages, after the camera stage has decided the motion:

* compare (:meth:`Foreground.compare`): the compensated model, warped into the frame, scores it
  brought to the model's exposure, and the motion evidence is made (the vectors' in this
  thread, the frames' own in the engine's second thread);
* decide (:meth:`Foreground.is_cut`, :meth:`Foreground.decide`): a new shot, or the mask: the
  compensated model's score (the still-camera model's while the camera is still) fused with the
  motion evidence, less the blobs new since the last frame, grown over the last objects'
  colours, with the holes it and the frame's edges enclose filled, less the shadows (on a
  moving camera);
* learn (:meth:`Foreground.learn`): the models' update, deferred to the next frame, where it
  runs in the second thread beside the motion front end.

The settings of the policies these stages apply (exposure matching, the scene cut, the
still-camera switch, the shadows) are one :class:`ForegroundConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np

from bgsub._util import FieldWarp
from bgsub.background.compensated import CompensatedBackground
from bgsub.background.fusion import Fusion
from bgsub.background.layers import LayerWarps, choose_layers
from bgsub.background.object_colour import ObjectColours
from bgsub.background.persistence import BlobPersistence
from bgsub.background.scene_cut import SceneCut
from bgsub.background.shadow import ShadowVeto
from bgsub.motion.result import MotionResult
from bgsub.settings import check_settings, setting

__all__ = ["ForegroundConfig", "Comparison", "Lesson", "Foreground"]


@dataclass(frozen=True)
class ForegroundConfig:
    """Settings of the foreground policies: exposure matching
    (:func:`~bgsub.background.exposure.match_exposure`), the scene cut
    (:class:`~bgsub.background.scene_cut.SceneCut`), the still-camera switch
    (:class:`~bgsub.background.still_switch.StillCameraSwitch`) and the shadows
    (:class:`~bgsub.background.shadow.ShadowVeto`)."""

    match_exposure: bool = setting(True, "divide each frame by its brightness gain against "
                                         "the compensated background model (the median ratio "
                                         "of their colours) before the model compares and "
                                         "learns it, while the model follows the gain at its "
                                         "learning rate, so auto exposure or a whole frame's "
                                         "flicker is not taken for foreground")
    scene_cut: float = setting(0.5, "restart the model when more than this fraction of the "
                                    "pixels with history differ from it while few motion "
                                    "vectors agree with the fitted motion (cut_support)",
                               low=0, high=1)
    cut_support: float = setting(0.35, "a scene cut (scene_cut) needs fewer than this fraction "
                                       "of the motion vectors to agree with the fitted motion "
                                       "(more than 80 % of the pixels differing is a cut "
                                       "whatever the motion)", low=0, high=1)
    still_model: float = setting(0.15, "take the camera as still, and use a never-warped sample "
                                       "background model (water, foam, leaves), while that "
                                       "model calls less than this fraction of the frame "
                                       "foreground and still_snr and still_versus agree "
                                       "(0 = off)", low=0, high=1)
    still_snr: float = setting(4.0, "the camera is taken as still (still_model) only while the "
                                    "fitted camera motion is less than this many times the "
                                    "scatter of the motion vectors about it (no rigid motion "
                                    "stands out)", low=0)
    still_versus: float = setting(4.0, "the camera is taken as still (still_model) only while "
                                       "the sample model calls at most this many times the "
                                       "fraction the compensated model calls, plus 0.5 %, "
                                       "where that one is not blind (a slow pan drifts the "
                                       "never-warped model's fine texture into false "
                                       "foreground; 0 = no comparison)", low=0)
    still_steady: float = setting(0.04, "the camera is not taken as still while its fitted "
                                        "motion (the frame centre's) keeps one step of at "
                                        "least 0.5 px over still_window frames, each within "
                                        "this share of it: a pan, however much water or a "
                                        "flat region scatters the vectors (0 = off)",
                                  low=0, high=1)
    still_window: int = setting(9, "the still-camera tests (still_model, still_snr, "
                                   "still_versus, still_steady) are medians over this many "
                                   "frames", low=1)
    still_radius: float = setting(5.0, "the still-camera model's match radius (gray levels) "
                                       "at a pixel that holds still; it widens with the "
                                       "pixel's own usual distance to its samples "
                                       "(still_spread), up to 20, so water and leaves keep a "
                                       "wide one", above=0, high=20)
    still_spread: float = setting(5.0, "the still-camera model's radius at a pixel widens by "
                                       "this many times the pixel's usual distance to its "
                                       "samples (0 = one radius of 20 for every pixel)", low=0)
    still_pause: int = setting(0, "1 = the still-camera model learns nothing while the camera "
                                  "moves rigidly (a view that is gone when the camera stops): "
                                  "a third of a millisecond less a frame at 160 px wide, the "
                                  "fast preset's; 0 = it learns every frame", low=0, high=1)

    shadow: float = setting(0.5, "clear from a moving camera's mask the shadows: where the frame "
                                 "is the compensated background darker, by a brightness ratio "
                                 "between this and 0.95, with its chromaticity (shadow_chroma) "
                                 "and texture (shadow_texture) (0 = off)", low=0, high=0.95)
    shadow_chroma: float = setting(0.03, "a shadow's chromaticity (each channel's share of the "
                                         "brightness) differs from the background's by at most "
                                         "this", low=0, high=1)
    shadow_texture: float = setting(0.7, "a shadow's brightness correlates with the "
                                         "background's by at least this over 5x5 windows (or "
                                         "both are flat there)", low=0, high=1)

    def __post_init__(self) -> None:
        check_settings(self)


@dataclass
class Comparison:
    """What the compare stage found in a frame."""

    score: np.ndarray  # (h, w) float32: the background difference (above 1 = differs)
    violation: Optional[np.ndarray]  # (h, w) float32 in [0, 1]: motion against the camera's
    along: Optional[np.ndarray]  # (h, w) float32: the frames' evidence of the camera's motion
    exposed: np.ndarray  # the frame at the compensated model's exposure, (h, w[, 3]) uint8
    gain: float  # what the frame was divided by to get there


@dataclass
class Lesson:
    """A frame's update of the models, deferred to the next frame."""

    exposed: np.ndarray  # the frame at the compensated model's exposure (h, w[, 3]) uint8
    gain: float
    work: np.ndarray  # the frame as it came, for the still-camera model
    mask: np.ndarray  # (h, w) uint8 0/255: the frame's mask, copied (apply may return it)
    violation: Optional[np.ndarray]  # the motion evidence, for Fusion.learn_slowly
    confirmed: Optional[np.ndarray]  # (h, w) bool: Fusion.confirmed
    rate: float  # the caller's learning rate


class Foreground:
    """The compare, decide and learn stages (module docstring) over the compensated model
    ``bg`` and the ``fusion``, with the policies ``exposure`` (``(frame, model) -> (exposed,
    gain)``), ``scene_cut``, ``still_switch``, ``persistence``, ``object_colours`` and
    ``shadows``;
    ``alongside`` is the engine's second thread's
    :meth:`~bgsub.engines.threads.SecondThread.alongside`."""

    def __init__(self, bg: CompensatedBackground, fusion: Fusion, *, exposure: Callable,
                 scene_cut: SceneCut, still_switch: Any, persistence: BlobPersistence,
                 object_colours: ObjectColours, shadows: ShadowVeto,
                 alongside: Callable) -> None:
        self.bg, self.fusion, self.exposure = bg, fusion, exposure
        self.scene_cut, self.still_switch = scene_cut, still_switch
        self.persistence, self.object_colours = persistence, object_colours
        self.shadows = shadows
        self.alongside = alongside
        self.lesson: Optional[Lesson] = None

    def compare(self, work: np.ndarray, prev: np.ndarray, result: MotionResult,
                matrix: np.ndarray, applied: np.ndarray, *, frozen: bool,
                fixed: bool, parallax: Optional[FieldWarp] = None,
                layers: Optional[LayerWarps] = None) -> Comparison:
        """The :class:`Comparison` of ``work`` (the frame, (h, w[, 3]) uint8; ``prev`` the
        previous one) with the model warped by ``applied`` (3, 3; a ``frozen`` model is warped
        sharp and forgets what the previous frame saw only in part) and the ``parallax`` field,
        or block by block by the better of it and the ``layers``' warps
        (:func:`~bgsub.background.layers.choose_layers`); the motion evidence of
        ``result``'s vectors and of the frames, against the camera's ``matrix`` (3, 3), the
        vectors' with the fixed violation threshold when ``fixed`` (a refused small region's
        vectors are one consistent motion, not noise about the camera's)."""
        image: list = []

        def evidence() -> None:
            image.append(self.fusion.image_evidence(result.points, result.disp, result.weights,
                                                    matrix, prev, work, parallax))

        # The frames' evidence is the longer job: the vectors' map is made in this thread.
        with self.alongside(evidence):
            # (A held-back motion is applied later, with the plane's motion alone.)
            move = parallax if np.array_equal(applied, matrix) else None
            others = ([] if move is None or layers is None or frozen else
                      [self.bg.warped_copy(applied, warp) for warp in layers.warps])
            self.bg.warp(applied, sharp=frozen, parallax=move)
            if frozen:
                self.bg.forget_partly_seen(applied)
            exposed, gain = self.exposure(work, self.bg)
            score = self.bg.score(exposed)
            if others:
                score = choose_layers(self.bg, others, exposed, score, block=layers.block,
                                      keep=layers.keep)
            vectors = self.fusion.vector_evidence(
                result.points, result.disp, result.evidence_weights, matrix, work.shape[:2],
                noise_scale=0.0 if fixed else None)
        against, along = image[0] if image[0] is not None else (None, None)
        return Comparison(score=score, violation=self.fusion.combined(vectors, against),
                          along=along, exposed=exposed, gain=gain)

    def young(self) -> np.ndarray:
        """``(h, w) bool``: the pixels without enough history to count in :meth:`is_cut`."""
        return self.bg.age < self.bg.config.min_age

    def is_cut(self, compared: Comparison, result: MotionResult, young: np.ndarray) -> bool:
        """Whether the frame starts a new shot (:class:`SceneCut`), not counting the ``young``
        pixels ((h, w) bool: :meth:`young`, and those outside a region of interest)."""
        return self.scene_cut.is_cut(compared.score, young, result)

    def decide(self, work: np.ndarray, gray: np.ndarray, result: MotionResult,
               matrix: np.ndarray, compared: Comparison, rate: float, *,
               region: Any) -> np.ndarray:
        """The (h, w) uint8 0/255 mask of the frame ``work`` (``gray`` its gray image) seen
        with motion ``result`` and camera motion ``matrix``, cleared outside ``region`` (its
        ``clear_outside``: the frame less its frame-fixed overlays) and, on a moving camera, of
        its shadows; its :class:`Lesson`, at learning rate ``rate``, is kept for
        :meth:`learn`."""
        still = self.still_switch.judge(work, result, compensated=self.bg,
                                        compensated_score=compared.score)
        score = compared.score if still is None else still
        mask = self.persistence.filter(self.fusion.mask(score, compared.violation), matrix)
        mask = self.object_colours.grow(mask, work)
        # learn_slowly's closing is left to the update, which the second thread runs.
        mask = self.fusion.close_by_edges(mask, gray)
        region.clear_outside(mask)
        confirmed = self.fusion.confirmed(mask, compared.violation, compared.along)
        self.lesson = Lesson(exposed=compared.exposed, gain=compared.gain, work=work,
                             mask=mask.copy(), violation=compared.violation,
                             confirmed=confirmed, rate=rate)
        if still is None:
            # The models learn a shadow as part of its object (the lesson above): it leaves
            # with it, and shade learnt into the background would stay behind as a ghost.
            self.shadows.veto(mask, compared.exposed, self.bg)
        return mask

    def learn(self) -> None:
        """The last frame's deferred update of the models, if any."""
        if self.lesson is not None:
            u, self.lesson = self.lesson, None
            slow = self.fusion.learn_slowly(u.mask, u.violation)
            self.object_colours.learn(u.work, u.mask)
            self.bg.update(u.exposed, slow, u.rate, exposure=u.gain, confirmed=u.confirmed)
            self.still_switch.update(u.work, slow, u.rate)

    def restart(self, frame: np.ndarray) -> None:
        """Start over from ``frame`` (the first frame, a new shot): nothing left to learn."""
        self.lesson = None
        for part in (self.persistence, self.object_colours, self.bg, self.still_switch):
            part.restart(frame)
