"""The settings of the coarse-to-fine patch-motion reader, in one place: :class:`FlowConfig`.

Its defaults are those of the ``grbm`` engine (tuned on the development data); the engine's
``Param`` table is generated from the fields' metadata (:func:`bgsub.settings.config_params`).
Pixel quantities are in pixels of the frames given to :func:`~bgsub.motion.estimate_flow`
(the engine's working size) unless a field says otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

from bgsub.motion.global_motion import MODELS
from bgsub.settings import check_settings, setting

__all__ = ["FlowConfig"]


@dataclass(frozen=True)
class FlowConfig:
    """How :func:`~bgsub.motion.estimate_flow` reads patch motion between two frames.

    Every field is a :func:`~bgsub.settings.setting` (default, bounds, meaning); construction
    raises :class:`~bgsub.errors.InputError` for a value of the wrong type or out of bounds.
    ``0`` means "automatic" or "none" for ``levels``, ``max_disp``, ``coarse_stride``,
    ``max_patches`` and ``refine_stride``, as in the engines' parameters.
    """

    stride: int = setting(8, "patch grid step in working-size pixels", low=1)
    levels: int = setting(0, "pyramid levels (0 = enough for max_motion)", low=0)
    max_motion: float = setting(
        32.0, "largest camera motion per frame to plan the pyramid for (working px); a frame "
              "too small for the levels it needs reads less (MotionRangeWarning)", above=0)
    max_disp: int = setting(0, "the patch-motion model's displacement range (px per axis; "
                               "0 = the model's own, bgsub.motion.model_range)", low=0)
    coarse_stride: int = setting(0, "patch grid step at the coarser pyramid levels, in each "
                                    "level's own pixels (0 = stride; at least 4)", low=0)
    coarse_model: str = setting("affine", "motion model fitted at the coarser levels to "
                                          "pre-warp the next", choices=MODELS)
    min_texture: float = setting(0.02, "patches with a lower texture weight are not evaluated",
                                 low=0, high=1)
    texture_scale: float = setting(
        1e-5, "structure-tensor eigenvalue (gray in [0, 1]) at which a patch's texture weight "
              "is 0.5: small = every textured patch counts alike, only near-flat and edge-only "
              "ones are down-weighted (suits blurred footage)", above=0)
    max_patches: int = setting(0, "evaluate at most this many patches per level, the most "
                                  "textured (0 = all)", low=0)
    dense: bool = setting(False, "also assemble the per-pixel (H, W, 2) field "
                                 "(FlowEstimate.dense)")
    ransac_threshold: float = setting(1.0, "RANSAC inlier distance of the coarse levels' fits, "
                                           "in each level's own pixels", above=0)
    iterations: int = setting(1, "readouts at the finest level, each re-warped by the last fit "
                                 "(more: a little more accurate, slower; docs/BENCHMARKS.md)",
                              low=1, high=10)
    search: int = setting(1, "also start the coarsest level from a (2 search + 1)^2 grid of "
                             "shifts (shaking cameras); 0 = prior and identity only",
                          low=0, high=8)
    coarse_iterations: int = setting(3, "readouts at the coarsest pyramid level, each "
                                        "re-warped by the last fit (finer levels start close "
                                        "and read once)", low=1, high=20)
    finest: int = setting(0, "pyramid level of the final readout (1 = half the working size: "
                             "faster, and better on blurry footage)", low=0)
    refine_stride: int = setting(16, "patch grid step of the finest-level readouts that only "
                                     "refine the pre-warp (iterations > 1; 0 = stride): "
                                     "2 x stride reads a quarter of the patches, ~15 % faster "
                                     "for the same accuracy", low=0)
    search_below: float = setting(0.9, "with search > 0: read the grid of shifts only when "
                                       "fewer than this fraction of the coarsest patches agree "
                                       "with the better of the previous motion and no motion "
                                       "(1 = always; always on a first frame)", low=0)
    start_tolerance: float = setting(0.015, "choose the coarsest level's start by photometric "
                                            "agreement: the fraction of textured pixels whose "
                                            "gray value (0-1) the next frame repeats to within "
                                            "this (0 = by the number of agreeing patches)",
                                     low=0)
    converged: float = setting(0.1, "stop re-reading the coarsest level once a readout moved "
                                    "its fitted motion by less than this many of that level's "
                                    "pixels at the corners: a steady pan the previous motion "
                                    "predicts reads it once, not coarse_iterations times "
                                    "(0 = always coarse_iterations readouts)", low=0)
    start_model: str = setting("translation", "motion model fitted to each start's readout at "
                                              "the coarsest level (its few patches fit a richer "
                                              "model's zoom to noise; the re-reads that follow "
                                              "fit coarse_model)", choices=MODELS)
    warn_range: bool = setting(True, "warn (MotionRangeWarning) when max_motion is beyond what "
                                     "the automatic pyramid reaches; off for callers that read "
                                     "beyond it from a prior or say so themselves")

    def __post_init__(self) -> None:
        check_settings(self)
