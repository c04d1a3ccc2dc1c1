"""bgsub.motion.flowfield: patch displacements coarse to fine, and the dense field.

The coarse-to-fine mechanics are tested with an exact block-matching oracle in the model's place
(same contract, no training noise); the gated RBM itself is tested on random dots with the
shipped translation model.
"""

import dataclasses
import re
import warnings

import cv2
import numpy as np
import pytest

from helpers import OracleMatcher, random_texture, shifted
from bgsub.errors import InputError, ModelError
from bgsub.motion import FlowConfig
from bgsub.motion.flowfield import FlowEstimate, dense_from_patches, estimate_flow


def _flow(frame1, frame2, *, model, prior=None, **settings):
    """:func:`estimate_flow` with a :class:`FlowConfig` of ``settings``."""
    return estimate_flow(frame1, frame2, FlowConfig(**settings), model=model, prior=prior)


def test_small_shift_recovered_at_one_level():
    h, w = 96, 128
    base = random_texture(h, w)[:h, :w]
    moved = shifted(base, 2, -1, h, w)
    flow = _flow(base, moved, model=OracleMatcher(), levels=1, min_texture=0.0)
    inner = flow.valid & (flow.centres[:, 0] > 10) & (flow.centres[:, 0] < w - 10)
    assert inner.sum() > 20
    np.testing.assert_allclose(np.median(flow.disp[inner], axis=0), [2, -1], atol=1e-6)


def test_large_pan_recovered_coarse_to_fine():
    h, w = 192, 256
    base = random_texture(h, w, seed=1)[:h, :w]
    moved = shifted(base, 11, 4, h, w)  # far beyond the +-3 px of one level
    one = _flow(base, moved, model=OracleMatcher(), levels=1, min_texture=0.0)
    c2f = _flow(base, moved, model=OracleMatcher(), levels=3, min_texture=0.0)
    inner = (c2f.centres[:, 0] > 20) & (c2f.centres[:, 0] < w - 20)
    assert c2f.levels == 3
    med = np.median(c2f.disp[inner & c2f.valid], axis=0)
    np.testing.assert_allclose(med, [11, 4], atol=0.6)
    assert np.median(np.abs(one.disp[inner, 0] - 11)) > 5  # one level cannot see it


def test_dense_field_full_size_and_nan_where_unknown():
    h, w = 90, 124
    base = random_texture(h, w, seed=2)[:h, :w]
    moved = shifted(base, -2, 1, h, w)
    flow = _flow(base, moved, model=OracleMatcher(), levels=1, dense=True,
                         min_texture=0.0)
    d = flow.dense
    assert d.shape == (h, w, 2) and d.dtype == np.float32
    known = np.isfinite(d).all(axis=2)
    assert known[h // 2, w // 2]
    np.testing.assert_allclose(d[30:60, 30:90].reshape(-1, 2).mean(0), [-2, 1], atol=0.3)
    # The last column of patches ends before the frame's right edge here: unknown, not made up.
    assert not known[:, -1].any()


@pytest.mark.parametrize("stride", [3, 6])
def test_pixels_an_invalid_patch_shares_with_valid_ones_get_their_flow(stride):
    """No 1-px unknown lines where an invalid patch sits among valid ones that cover it."""
    rows, cols, p = 5, 7, 13
    half = (p - 1) // 2
    ys, xs = np.mgrid[0:rows, 0:cols]
    centres = np.stack([half + stride * xs.ravel(), half + stride * ys.ravel()], 1)
    n = rows * cols
    valid = np.ones(n, bool)
    valid[2 * cols + 3] = False  # the middle patch
    flow = FlowEstimate(
        centres=centres.astype(np.float32), disp=np.tile([1.5, -0.5], (n, 1)).astype(np.float32),
        confidence=np.ones(n, np.float32), texture=np.ones(n, np.float32), valid=valid,
        grid_shape=(rows, cols), stride=stride, prewarp=np.eye(3),
        residual=np.zeros((n, 2), np.float32))
    h, w = half * 2 + stride * (rows - 1) + 1, half * 2 + stride * (cols - 1) + 1
    d = dense_from_patches(flow, shape=(h, w), patch_size=p)
    cy, cx = centres[2 * cols + 3][::-1]
    np.testing.assert_allclose(d[cy, cx], [1.5, -0.5])  # its centre: covered by its neighbours
    assert np.isfinite(d).all()
    # A patch whose neighbours are all invalid too leaves its centre unknown.
    lonely = np.zeros(n, bool)
    lonely[0] = True
    alone = dense_from_patches(dataclasses.replace(flow, valid=lonely), shape=(h, w), patch_size=p)
    assert np.isfinite(alone[:p, :p]).all() and not np.isfinite(alone[p + stride:, :]).any()


def test_flat_frames_give_no_valid_patches():
    flat = np.full((80, 80), 128, np.uint8)
    flow = _flow(flat, flat, model=OracleMatcher(), levels=2)
    assert not flow.valid.any()
    assert np.all(flow.weights == 0)


def test_gated_rbm_reads_shift_of_random_dots():
    from bgsub.model.rbm import load_model

    try:
        model = load_model("dots-translation-3px")
    except ModelError as err:
        pytest.skip(f"shipped model not installed: {err}")
    rng = np.random.default_rng(5)
    h, w = 64, 64
    dots = (rng.random((h + 8, w + 8)) < 0.1).astype(np.float32)
    x = dots[4:4 + h, 4:4 + w]
    y = dots[4 - 1:4 - 1 + h, 4 - 2:4 - 2 + w]  # content moves by (+2, +1)
    flow = _flow(x, y, model=model, levels=1, min_texture=0.0)
    good = flow.valid
    assert good.sum() > 10
    np.testing.assert_allclose(np.median(flow.disp[good], axis=0), [2, 1], atol=0.26)


def test_final_readout_at_a_coarser_level_is_in_full_resolution_pixels():
    h, w = 192, 256
    base = random_texture(h, w, seed=3)[:h, :w]
    moved = shifted(base, 6, -2, h, w)
    flow = _flow(base, moved, model=OracleMatcher(), levels=3, finest=1, stride=8,
                         min_texture=0.0)
    inner = flow.valid & (flow.centres[:, 0] > 20) & (flow.centres[:, 0] < w - 20)
    assert flow.centres[:, 0].max() > w / 2 + 40  # centres span the full-size frame
    np.testing.assert_allclose(np.median(flow.disp[inner], axis=0), [6, -2], atol=0.6)


def _random_contrast_model():
    from bgsub.model.rbm import GatedRBM

    model = GatedRBM.create(patch_size=13, n_factors=32, n_hidden=16, init_scale=0.05,
                            rng=np.random.default_rng(2), normalization="contrast")
    model.meta["max_disp"] = 3
    return model


def test_refining_grid_shares_the_final_grids_first_frame_patches():
    """With refine_stride a multiple of stride, the refining readout's first-frame patches are
    taken from the final grid's (computed once); the result must be the same as cutting them
    anew, which a max_patches above the patch count forces."""
    h, w = 96, 128
    base = random_texture(h, w, seed=4)[:h, :w]
    moved = shifted(base, 1, 1, h, w)
    model = _random_contrast_model()
    kwargs = dict(model=model, levels=2, stride=6, iterations=2, refine_stride=12,
                  min_texture=0.0)
    shared = _flow(base, moved, **kwargs)
    fresh = _flow(base, moved, max_patches=10**6, **kwargs)
    np.testing.assert_array_equal(shared.valid, fresh.valid)
    np.testing.assert_allclose(shared.disp, fresh.disp, atol=1e-5)
    np.testing.assert_allclose(shared.prewarp, fresh.prewarp, atol=1e-6)


def test_coarser_refining_grid_still_recovers_a_large_pan():
    h, w = 192, 256
    base = random_texture(h, w, seed=1)[:h, :w]
    moved = shifted(base, 11, 4, h, w)
    flow = _flow(base, moved, model=OracleMatcher(), levels=3, iterations=2, stride=8,
                         refine_stride=16, min_texture=0.0)
    inner = (flow.centres[:, 0] > 20) & (flow.centres[:, 0] < w - 20)
    np.testing.assert_allclose(np.median(flow.disp[inner & flow.valid], axis=0), [11, 4],
                               atol=0.6)
    assert flow.stride == 8  # the result is on the final grid


def test_level_texture_map_equals_the_tiling_texture_at_patch_centres():
    from bgsub.motion.patches import level_texture_map
    from bgsub.model.tiling import patch_grid, texture_map

    gray = random_texture(60, 80, seed=5)[:60, :80].astype(np.float32) / 255
    gray[:, :25] = 0.3
    centres, _ = patch_grid(gray.shape, patch_size=13, stride=4)
    ci = centres.astype(int)
    expected = texture_map(gray, window=13)[ci[:, 1], ci[:, 0]]
    got = level_texture_map(gray, 13)[ci[:, 1], ci[:, 0]]
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-9)
    assert expected.max() > 1e-4 and got.min() >= 0.0


class UnderReadingMatcher(OracleMatcher):
    """The oracle's integer shift halved, rounded away from zero (3 -> 2, 2 -> 1, 1 -> 1): like
    the gated RBM on blurred frames, it reads a motion as a smaller one in the right
    direction."""

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        disp, conf, flat = super().patch_motion(x_raw, y_raw, max_disp=max_disp)
        return (np.sign(disp) * np.ceil(np.abs(disp) / 2)).astype(np.float32), conf, flat


@pytest.mark.parametrize("converged", [0.0, 0.25])
@pytest.mark.parametrize("with_prior", [False, True])
def test_coarsest_level_is_read_until_it_converges(with_prior, converged):
    """An under-reading model leaves the pre-warp short after one readout of the coarsest
    level; re-reading it after each re-warp converges (with a prior too: the start's readout
    counts as the first). Every readout moves the fit by a pixel or more, so stopping at
    convergence (``converged``) must not cut the re-reads short."""
    h, w = 192, 256
    base = random_texture(h, w, seed=6)[:h, :w]
    moved = shifted(base, 6, 0, h, w)  # 3 px at the coarser of 2 levels
    prior = np.eye(3) if with_prior else None

    def prewarp_x(coarse_iterations):
        flow = _flow(base, moved, model=UnderReadingMatcher(), levels=2, stride=8, search=0,
                     iterations=1, coarse_iterations=coarse_iterations, prior=prior,
                     min_texture=0.0, converged=converged)
        return flow.prewarp[0, 2]

    assert abs(prewarp_x(1) - 6) > 1.5  # 3 read as 2: 4 px
    assert abs(prewarp_x(3) - 6) < 0.5


class ClippingMatcher(OracleMatcher):
    """Reads shifts a little beyond its range as the edge of the range (like the gated RBM)."""

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        disp, conf, flat = super().patch_motion(x_raw, y_raw, max_disp=max_disp + 3)
        return np.clip(disp, -max_disp, max_disp), conf, flat


def test_start_candidates_get_no_support_from_clipped_readings():
    """A wrong start (beyond the model's range from the true motion) reads the edge of the
    range everywhere, a consistent but meaningless group; it must not win over the right one."""
    from bgsub.motion.patches import PatchGrids
    from bgsub.motion.starts import StartSearch

    h, w = 96, 128
    base = random_texture(h, w, seed=7)[:h, :w]
    moved = shifted(base, 2, 0, h, w)
    g1, g2 = base.astype(np.float32) / 255, moved.astype(np.float32) / 255
    wrong = np.array([[1.0, 0, -3.0], [0, 1.0, 0], [0, 0, 1]])  # residual 5: read as 3
    model = ClippingMatcher()
    grids = PatchGrids(model, min_texture=0.0, max_patches=None, texture_scale=2e-3)
    search = StartSearch(g1, g2, level=0, grids=grids, stride=8, model=model, max_disp=3,
                         fit_model="affine", threshold=1.0, tolerance=0.0)
    chosen = search.best([wrong, np.eye(3)], fallback=np.eye(3)).motion
    assert abs(chosen[0, 2] - 2) < 0.5, chosen


def test_smaller_texture_scale_weighs_weak_texture_alike_and_still_drops_flat_patches():
    """``texture_scale`` sets where the texture weight reaches 0.5: a small one lets a
    low-contrast (blurred) texture count like a strong one, while flat patches stay out."""
    h, w = 96, 128
    base = random_texture(h, w, seed=3)[:h, :w].astype(np.float32) / 255
    weak = (0.5 + 0.1 * (base - base.mean())).astype(np.float32)  # a tenth of the contrast
    weak[:, :40] = 0.5  # flat band
    moved = shifted(weak, 1, 0, h, w)
    strong = lambda f: f.texture[f.centres[:, 0] > 60]  # noqa: E731
    flat = lambda f: f.texture[f.centres[:, 0] < 30]  # noqa: E731
    large = _flow(weak, moved, model=OracleMatcher(), levels=1, min_texture=0.0,
                  texture_scale=2e-3)
    small = _flow(weak, moved, model=OracleMatcher(), levels=1, min_texture=0.0,
                  texture_scale=1e-5)
    assert np.median(strong(large)) < 0.1  # a large scale: weak texture counts little
    assert np.median(strong(small)) > 0.6
    assert np.all(flat(small) < 0.01) and np.all(flat(large) < 0.01)


@pytest.mark.parametrize("search_below, grid_read", [(0.5, True), (0.0, False), (1.0, True)])
def test_a_shake_beyond_the_range_is_found_by_the_grid_of_starts(search_below, grid_read):
    """A shake the coarsest level cannot see from the prior (a still camera) is found from the
    grid of shifted starts, which is read only when the start's support is below
    ``search_below``."""
    h, w = 128, 160
    base = random_texture(h, w, seed=4)[:h, :w]
    # 4 px at level 1: beyond the matcher's +-3 (clipped), 2 px from the grid's +4 px start.
    moved = shifted(base, 8, 0, h, w)
    model = CountingMatcher()
    flow = _flow(base, moved, model=model, levels=2, stride=8, min_texture=0.0, search=1,
                 coarse_iterations=1, search_below=search_below, prior=np.eye(3))
    inner = flow.valid & (flow.centres[:, 0] > 20) & (flow.centres[:, 0] < w - 20)
    found = inner.sum() > 10 and abs(np.median(flow.disp[inner, 0]) - 8) < 0.5
    assert found == grid_read


@pytest.mark.parametrize("prior, grid_read", [(np.eye(3), False), (None, True)])
def test_the_grid_of_starts_is_read_only_without_a_supported_start(prior, grid_read):
    """With a prior whose start most patches agree with, the grid is not read; on a first
    frame (no prior) it always is."""
    h, w = 128, 160
    base = random_texture(h, w, seed=4)[:h, :w]
    moved = shifted(base, 2, 0, h, w)
    kw = dict(levels=2, stride=8, min_texture=0.0, search=1, prior=prior)
    counts = []
    for search_below in (0.5, 1.0):
        model = CountingMatcher()
        flow = _flow(base, moved, model=model, search_below=search_below, **kw)
        assert abs(np.median(flow.disp[flow.valid, 0]) - 2) < 0.5
        counts.append(model.patches)
    # Without the grid 2 starts are read instead of 10 (the later levels cost the same).
    assert (counts[0] < counts[1] / 2) == (not grid_read)
    assert (counts[0] == counts[1]) == grid_read


class CountingMatcher(ClippingMatcher):
    """Clips like the gated RBM and counts the patches it reads."""

    def __init__(self):
        self.patches = 0

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        self.patches += len(x_raw)
        return super().patch_motion(x_raw, y_raw, max_disp=max_disp)


class NoMotionMatcher(OracleMatcher):
    """Reads "no motion", confidently, whatever the patches show (like the gated RBM on a sharp
    patch against its motion-blurred counterpart): its readings cannot tell starts apart."""

    def patch_motion(self, x_raw, y_raw, *, max_disp):
        n = len(x_raw)
        return np.zeros((n, 2), np.float32), np.ones(n, np.float32), np.zeros(n, bool)


def test_photometric_agreement_is_high_only_under_the_true_motion():
    from bgsub.motion.starts import photometric_agreement

    h, w = 96, 128
    base = random_texture(h, w, seed=5)[:h, :w].astype(np.float32) / 255
    moved = shifted(base, 3, -2, h, w)
    truth = np.array([[1.0, 0, 3], [0, 1.0, -2], [0, 0, 1]])
    assert photometric_agreement(base, moved, truth, tolerance=0.015) > 0.9
    assert photometric_agreement(base, moved, np.eye(3), tolerance=0.015) < 0.3


def test_photometric_agreement_counts_pixels_mapped_outside_as_disagreeing():
    """A motion that maps half the frame outside the other explains only the half it keeps."""
    from bgsub.motion.starts import photometric_agreement

    h, w = 96, 128
    base = random_texture(h, w, seed=6)[:h, :w].astype(np.float32) / 255
    flat = np.full_like(base, 0.5)
    half = np.array([[1.0, 0, w / 2], [0, 1.0, 0], [0, 0, 1]])
    assert photometric_agreement(base, base, np.eye(3), tolerance=0.01) == 1.0
    assert 0.4 < photometric_agreement(base, base, half, tolerance=1.0) < 0.6
    assert photometric_agreement(flat, flat, np.eye(3), tolerance=0.01) == 0.0  # no texture


@pytest.mark.parametrize("tolerance, start_x", [(0.0, 0.0), (0.015, 6.0)])
def test_start_tolerance_lets_the_images_decide_what_the_readings_cannot(tolerance, start_x):
    """Readings that say "no motion" whatever the start agree with every start alike; by patch
    support the first candidate (no motion) wins the tie, by photometric agreement the start
    under which the frames match (the previous motion, here the true one)."""
    h, w = 128, 160
    base = random_texture(h, w, seed=8)[:h, :w]
    moved = shifted(base, 6, 0, h, w)
    prior = np.array([[1.0, 0, 6], [0, 1.0, 0], [0, 0, 1]])
    flow = _flow(base, moved, model=NoMotionMatcher(), levels=2, stride=8,
                         min_texture=0.0, prior=prior, start_tolerance=tolerance)
    assert abs(flow.prewarp[0, 2] - start_x) < 0.25, flow.prewarp


@pytest.mark.parametrize("prior_x, skipped", [(6.0, 2), (None, 1)])
def test_a_converged_coarsest_level_skips_its_re_reads(prior_x, skipped):
    """A start that already matches the motion (the prior of a steady pan) reads no residual:
    the coarsest level has converged and its two re-reads are skipped. From no motion, the
    first readout finds it (3 px at level 1) and the second confirms it: only the third is
    skipped. Either way the motion reached is the one of all the re-reads."""
    from bgsub.model.tiling import patch_grid

    h, w = 192, 256
    base = random_texture(h, w, seed=6)[:h, :w]
    moved = shifted(base, 6, 0, h, w)
    prior = None if prior_x is None else np.array([[1.0, 0, prior_x], [0, 1, 0], [0, 0, 1]])
    kw = dict(levels=2, stride=8, iterations=1, coarse_iterations=3, prior=prior,
              min_texture=0.0)
    patches, prewarps = [], []
    for converged in (0.0, 0.1):
        model = CountingMatcher()
        flow = _flow(base, moved, model=model, converged=converged, **kw)
        patches.append(model.patches)
        prewarps.append(flow.prewarp)
    n_coarsest = len(patch_grid((h // 2, w // 2), patch_size=13, stride=8)[0])
    assert patches[0] - patches[1] == skipped * n_coarsest
    np.testing.assert_allclose(prewarps[1], prewarps[0], atol=1e-4)
    assert abs(prewarps[1][0, 2] - 6) < 0.05


def _pyramid_kwargs(model):
    return dict(model=model, levels=3, stride=6, iterations=2, refine_stride=12,
                min_texture=0.0, start_tolerance=0.015)


def test_a_prepared_first_frame_gives_the_same_flow_without_recutting_it(monkeypatch):
    """prepare_first_frame does ahead of time what estimate_flow does on its first frame: the
    flow is the same, and estimate_flow then projects no first-frame patch itself."""
    from bgsub.model import readout
    from bgsub.motion.flowfield import FramePyramid, prepare_first_frame

    h, w = 96, 128
    base = random_texture(h, w, seed=5)[:h, :w]
    moved = shifted(base, 3, -2, h, w)
    model = _random_contrast_model()
    kwargs = _pyramid_kwargs(model)
    expected = _flow(base, moved, prior=np.eye(3), search=1, **kwargs)

    first = FramePyramid(base)
    prepare_first_frame(first, FlowConfig(**{k: v for k, v in kwargs.items() if k != 'model'}),
                        model=kwargs['model'])
    sides = []
    real = readout.patch_features
    monkeypatch.setattr(readout, "patch_features",
                        lambda m, raw, *, side: sides.append(side) or real(m, raw, side=side))
    got = _flow(first, FramePyramid(moved), prior=np.eye(3), search=1, **kwargs)
    assert sides and "x" not in sides  # every readout happened, none re-projected frame 1
    np.testing.assert_array_equal(got.disp, expected.disp)
    np.testing.assert_array_equal(got.valid, expected.valid)
    np.testing.assert_array_equal(got.prewarp, expected.prewarp)


def test_a_frame_pyramid_serves_as_second_frame_then_first():
    """A video's frames as FramePyramids: frame b is the second frame of (a, b) and the first of
    (b, c); the flows equal those computed from plain arrays."""
    from bgsub.motion.flowfield import FramePyramid

    h, w = 96, 128
    a = random_texture(h, w, seed=6)[:h, :w]
    b, c = shifted(a, 2, 1, h, w), shifted(a, 4, 2, h, w)
    kwargs = _pyramid_kwargs(_random_contrast_model())
    pa, pb, pc = FramePyramid(a), FramePyramid(b), FramePyramid(c)
    for (x, y), (px, py) in (((a, b), (pa, pb)), ((b, c), (pb, pc))):
        np.testing.assert_array_equal(_flow(px, py, **kwargs).disp,
                                      _flow(x, y, **kwargs).disp)
    # Reading the same pair again from the kept first-frame work changes nothing either.
    np.testing.assert_array_equal(_flow(pb, pc, **kwargs).disp,
                                  _flow(b, c, **kwargs).disp)


@pytest.mark.parametrize("change, words", [
    (dict(first=np.full((60, 80), 200.0, np.float32)), "float frames must be gray values in"),
    (dict(first=np.zeros((60, 80), np.uint16)), "frames must be uint8 or float in [0, 1]"),
    (dict(prior=np.eye(2)), "prior must be a finite (3, 3) homography"),
])
def test_bad_estimate_flow_options_are_input_errors(change, words):
    base = random_texture(60, 80, seed=3)[:60, :80]
    with pytest.raises(InputError, match=re.escape(words)):
        _flow(change.get("first", base), base, model=OracleMatcher(), levels=1,
              prior=change.get("prior"))


@pytest.mark.parametrize("fill, where", [(np.nan, np.s_[10:20, 10:20]), (np.nan, np.s_[:, :]),
                                         (np.inf, np.s_[5, 7])])
def test_a_float_frame_with_nan_or_inf_is_refused_before_any_warning(fill, where):
    base = random_texture(60, 80, seed=3)[:60, :80].astype(np.float32) / 255
    bad = base.copy()
    bad[where] = fill
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's "All-NaN slice" would come first otherwise
        for pair in ((bad, base), (base, bad)):
            with pytest.raises(InputError, match="frame contains NaN or infinite values"):
                _flow(*pair, model=OracleMatcher(), levels=1)


def test_a_max_motion_beyond_the_pyramid_the_frame_allows_warns_with_its_reach():
    # 160x120 allows 2 levels (the coarsest 4 patches across), which read (3 - 1) * 2 = 4 px
    # with the oracle's range of 3; 20 px would need 4 levels.
    from bgsub.motion.flowfield import MotionRangeWarning

    base = random_texture(120, 160, seed=3)[:120, :160]
    with pytest.warns(MotionRangeWarning, match=r"max_motion=20 px .* 160x120 frames: the 2 "
                                                r"pyramid levels .* up to about 4 px"):
        flow = _flow(base, base, model=OracleMatcher(), max_motion=20, search=0)
    assert flow.levels == 2


@pytest.mark.parametrize("options", [dict(max_motion=4), dict(max_motion=20, search=4),
                                     dict(max_motion=20, levels=2)])
def test_a_max_motion_within_reach_or_fixed_levels_do_not_warn(options):
    base = random_texture(120, 160, seed=3)[:120, :160]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _flow(base, base, model=OracleMatcher(), **options)


def test_a_model_name_reads_with_that_shipped_model():
    from bgsub.model.rbm import load_model

    base = random_texture(60, 80, seed=3)
    first, second = base[:60, :80], shifted(base, 2, 1, 60, 80)
    by_name = _flow(first, second, model="dots-translation", levels=1)
    loaded = _flow(first, second, model=load_model("dots-translation"), levels=1)
    other = _flow(first, second, model="natural", levels=1)
    assert np.array_equal(by_name.disp, loaded.disp)
    assert not np.array_equal(by_name.disp, other.disp)


def test_a_pyramids_8_bit_level_0_is_the_gray_frame_it_was_built_from():
    from bgsub.motion.flowfield import FramePyramid

    rng = np.random.default_rng(3)
    gray = rng.integers(0, 256, (24, 32), dtype=np.uint8)
    pyramid = FramePyramid(gray)
    assert np.array_equal(pyramid.gray8(), gray)
    assert pyramid.gray8() is pyramid.gray8()  # converted once
    bgr = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    from_bgr = FramePyramid(bgr).gray8()
    assert from_bgr.dtype == np.uint8
    assert np.array_equal(from_bgr, cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
