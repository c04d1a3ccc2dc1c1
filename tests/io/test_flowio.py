"""Middlebury .flo files, the colour wheel, arrows and endpoint error."""

from __future__ import annotations

import numpy as np
import pytest

from bgsub.errors import InputError, OutputError
from bgsub.io.flowio import (
    add_colour_wheel,
    arrow_grid,
    colour_scale,
    colour_wheel,
    draw_flow_arrows,
    endpoint_error,
    flow_picture,
    flow_to_color,
    read_flo,
    write_flo,
)


def _field(h: int = 5, w: int = 7) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.normal(0, 3, (h, w, 2)).astype(np.float32)


def test_flo_round_trip_keeps_values_and_unknown(tmp_path):
    flow = _field()
    flow[1, 2] = np.nan
    flow[3, 4, 1] = np.nan  # one unknown component makes the whole vector unknown
    path = write_flo(tmp_path / "f.flo", flow)
    back = read_flo(path)
    assert back.shape == (5, 7, 2) and back.dtype == np.float32
    unknown = np.isnan(back).any(axis=2)
    assert unknown[1, 2] and unknown[3, 4] and unknown.sum() == 2
    assert np.isnan(back[3, 4]).all()
    np.testing.assert_array_equal(back[~unknown], flow[~unknown])


def test_flo_layout_is_middlebury(tmp_path):
    flow = np.zeros((2, 3, 2), np.float32)
    flow[0, 1] = (1.5, -2.0)
    flow[1, 2] = np.nan
    raw = write_flo(tmp_path / "f.flo", flow).read_bytes()
    assert len(raw) == 12 + 2 * 3 * 2 * 4
    assert np.frombuffer(raw[:4], "<f4")[0] == np.float32(202021.25)
    assert tuple(np.frombuffer(raw[4:12], "<i4")) == (3, 2)  # width, then height
    data = np.frombuffer(raw[12:], "<f4").reshape(2, 3, 2)
    assert tuple(data[0, 1]) == (1.5, -2.0)
    assert (data[1, 2] > 1e9).all()


def test_flo_bad_tag_is_input_error(tmp_path):
    path = tmp_path / "bad.flo"
    path.write_bytes(np.array([1.0], "<f4").tobytes() + np.array([2, 2], "<i4").tobytes() + bytes(32))
    with pytest.raises(InputError) as caught:
        read_flo(path)
    assert f"not a .flo file (tag 1, expected 202021.25): {path}" == str(caught.value)


def test_flo_truncated_is_input_error(tmp_path):
    raw = write_flo(tmp_path / "f.flo", _field()).read_bytes()
    cut = tmp_path / "cut.flo"
    cut.write_bytes(raw[:-8])
    with pytest.raises(InputError, match="truncated"):
        read_flo(cut)


def test_flo_missing_file_is_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_flo(tmp_path / "nope.flo")


def test_write_flo_refuses_existing_file(tmp_path):
    path = write_flo(tmp_path / "f.flo", _field())
    with pytest.raises(OutputError, match="exists"):
        write_flo(path, _field())
    write_flo(path, _field() * 2, overwrite=True)
    np.testing.assert_array_equal(read_flo(path), _field() * 2)


def test_flow_to_color_known_directions():
    flow = np.zeros((1, 6, 2), np.float32)
    flow[0, 0] = (1, 0)  # right
    flow[0, 1] = (0, 1)  # down
    flow[0, 2] = (-1, 0)  # left
    flow[0, 3] = (0, -1)  # up
    flow[0, 4] = (0, 0)  # still
    flow[0, 5] = np.nan  # unknown
    bgr = flow_to_color(flow, max_magnitude=1.0)
    assert bgr.dtype == np.uint8 and bgr.shape == (1, 6, 3)
    b, g, r = (bgr[0, :, k].astype(int) for k in range(3))
    assert r[0] == 255 and g[0] == 0 and b[0] == 0  # right: red
    assert r[1] == 255 and g[1] > 200 and b[1] == 0  # down: yellow
    assert r[2] == 0 and g[2] > 150 and b[2] == 255  # left: cyan-blue
    assert b[3] == 255 and g[3] == 0 and r[3] < 128  # up: blue-violet
    assert tuple(bgr[0, 4]) == (255, 255, 255)  # no motion: white
    assert tuple(bgr[0, 5]) == (0, 0, 0)  # unknown: black


def test_flow_to_color_saturation_follows_magnitude():
    flow = np.array([[[0.5, 0], [1.0, 0]]], np.float32)
    bgr = flow_to_color(flow).astype(int)  # default max = the largest magnitude
    assert bgr[0, 1, 1] == 0 and bgr[0, 0, 1] > 100  # half magnitude: paler red


def test_draw_flow_arrows_draws_along_the_vector():
    image = np.zeros((40, 60), np.uint8)
    points, vectors = np.array([[10.0, 20.0]]), np.array([[30.0, 0.0]])
    out = draw_flow_arrows(image, points, vectors, color=(0, 255, 0))
    assert out.shape == (40, 60, 3) and image.max() == 0  # input untouched
    green = out[..., 1] > 0
    assert green[20, 25] and green[20, 39]  # the shaft
    assert not green[5, 25] and not green[20, 50]


def test_arrow_grid_samples_the_field():
    flow = np.zeros((32, 48, 2), np.float32)
    flow[..., 0] = np.arange(48)[None, :]
    points, vectors = arrow_grid(flow, step=16)
    assert points.shape == (6, 2)
    np.testing.assert_array_equal(vectors[:, 0], points[:, 0])


def test_endpoint_error_and_unknown():
    est = np.array([[3.0, 4.0], [1.0, 1.0], [np.nan, 0.0]], np.float32)
    gt = np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]], np.float32)
    err = endpoint_error(est, gt)
    np.testing.assert_allclose(err[:2], [5.0, 0.0])
    assert np.isnan(err[2])


def test_read_middlebury_ground_truth(shared_data):
    path = shared_data / "flow" / "Middlebury_RubberWhale" / "flow10.flo"
    if not path.is_file():
        pytest.skip(f"{path} not available")
    flow = read_flo(path)
    assert flow.shape == (388, 584, 2) and flow.dtype == np.float32
    known = np.isfinite(flow).all(axis=2)
    assert 0.5 < known.mean() < 1.0  # RubberWhale has occluded / unknown pixels
    assert np.abs(flow[known]).max() < 10  # small motions, as the README says


def test_existing_file_message_speaks_to_api_and_cli(tmp_path):
    path = write_flo(tmp_path / "f.flo", _field())
    with pytest.raises(OutputError) as err:
        write_flo(path, _field())
    assert str(err.value) == (f"{path}: already exists (overwrite=True, or --overwrite on the "
                              "command line, replaces it)")


@pytest.mark.parametrize("shape", [(0, 0, 2), (0, 4, 2), (3, 0, 2)])
def test_write_flo_says_an_empty_field_is_empty(tmp_path, shape):
    with pytest.raises(ValueError, match=r"flow is empty \(shape"):
        write_flo(tmp_path / "f.flo", np.zeros(shape, np.float32))
    assert not (tmp_path / "f.flo").exists()


def test_write_flo_wrong_shape_still_names_the_shape(tmp_path):
    with pytest.raises(ValueError, match=r"must be \(H, W, 2\), got shape \(2, 3\)"):
        write_flo(tmp_path / "f.flo", np.zeros((2, 3), np.float32))


@pytest.mark.parametrize("bad", [0, 0.0, -1, float("nan"), float("inf")])
def test_max_magnitude_must_be_above_zero(bad):
    from bgsub.io.flowio import flow_picture

    with pytest.raises(InputError, match="max_magnitude must be a number of pixels above 0"):
        flow_to_color(_field(), max_magnitude=bad)
    image = np.zeros((5, 7), np.uint8)
    with pytest.raises(InputError, match="max_magnitude"):
        flow_picture(_field(), image=image, arrows=True, max_magnitude=bad)


def test_max_magnitude_none_is_the_largest_magnitude():
    flow = _field()
    largest = float(np.hypot(*np.moveaxis(flow.astype(np.float64), 2, 0)).max())
    automatic = flow_to_color(flow, max_magnitude=None)
    assert np.array_equal(automatic, flow_to_color(flow, max_magnitude=largest))
    assert not np.array_equal(automatic, flow_to_color(flow, max_magnitude=2 * largest))


def test_a_small_max_magnitude_draws_every_vector_beyond_it_darker():
    flow = _field()
    tiny = flow_to_color(flow, max_magnitude=1e-3)
    assert tiny.shape == (5, 7, 3) and tiny.mean() < 0.6 * flow_to_color(flow).mean()


# --------------------------------------------------------------------------------------------
# The colour wheel (the colour code's legend)
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("degrees", [0, 45, 90, 135, 180, 225, 270, 315])
def test_wheel_pixel_at_an_angle_has_flow_to_colors_colour_of_that_direction(degrees):
    size, magnitude = 65, 4.0  # odd size: the centre is a pixel, the rim points exact
    wheel, disc = colour_wheel(magnitude, size=size)
    theta = np.radians(degrees)
    centre, radius = (size - 1) / 2, size / 2 - 1
    r = 0.75 * radius
    x, y = centre + r * np.cos(theta), centre + r * np.sin(theta)
    xi, yi = int(round(x)), int(round(y))
    assert disc[yi, xi]
    # The direction's own colour, at the speed that radius stands for.
    vector = np.array([[[np.cos(theta), np.sin(theta)]]]) * 0.75 * magnitude
    expected = flow_to_color(vector, max_magnitude=magnitude)[0, 0].astype(int)
    # (rounding the position moves the angle by under a degree)
    assert np.abs(wheel[yi, xi].astype(int) - expected).max() <= 6


def test_wheel_centre_is_white_right_is_red_and_outside_the_disc_is_left_out():
    wheel, disc = colour_wheel(2.0, size=65)
    assert (wheel[32, 32] == 255).all()
    b, g, r = wheel[32, 62].astype(int)
    assert r > 200 and g < 60 and b < 60  # right = red (Middlebury)
    assert not disc[0, 0] and disc[32, 32] and disc.sum() > 0.7 * 65 * 65


def test_colour_scale_is_the_given_or_the_largest_known_magnitude():
    flow = np.zeros((2, 2, 2))
    flow[0, 0] = (3, 4)
    flow[1, 1] = np.nan
    assert colour_scale(flow) == 5.0
    assert colour_scale(flow, max_magnitude=2.5) == 2.5
    assert colour_scale(np.full((2, 2, 2), np.nan)) == 0.0


def test_legend_goes_in_the_bottom_right_corner_only():
    flow = np.zeros((120, 160, 2), np.float32)
    flow[..., 0] = 1.0
    plain = flow_picture(flow, max_magnitude=2.0)
    shown = flow_picture(flow, max_magnitude=2.0, legend=True)
    changed = np.any(shown != plain, axis=2)
    ys, xs = np.nonzero(changed)
    assert changed.any() and ys.min() > 120 // 2 and xs.min() > 160 // 2
    # The wheel as colour_wheel draws it, 24 px (a fifth of 120), 4 px from the corner.
    wheel, disc = colour_wheel(2.0, size=24)
    assert (shown[-4 - 24:-4, -4 - 24:-4][disc] == wheel[disc]).all()


def test_legend_leaves_tiny_pictures_alone():
    picture = np.zeros((30, 40, 3), np.uint8)
    assert (add_colour_wheel(picture, 3.0) == picture).all()
