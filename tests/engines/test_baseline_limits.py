"""mog2 and knn refuse parameters OpenCV cannot run, and models larger than it can size,
before OpenCV sees them (its own failures are an assertion, an exabyte request or SIGSEGV)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from bgsub.engines import create_engine, parse_params
from bgsub.errors import InputError


def test_mog2_takes_up_to_255_mixtures_as_opencv_does():
    engine = create_engine("mog2", **parse_params("mog2", ["n_mixtures=255"]))
    assert engine.apply(np.zeros((16, 16, 3), np.uint8)).shape == (16, 16)
    with pytest.raises(InputError, match="'n_mixtures' must be at most 255, not 256"):
        parse_params("mog2", ["n_mixtures=256"])


def test_knn_model_size_is_checked_against_the_first_frame():
    # 320x240 colour: OpenCV's C int holds 320 * 240 * n * 3 * 4 bytes up to n = 2330.
    engine = create_engine("knn", n_samples=2331)
    with pytest.raises(InputError, match="n_samples=2331 .* 320x240 colour .* at most 2330 "):
        engine.apply(np.zeros((240, 320, 3), np.uint8))


def test_gray_frames_allow_more_samples():
    engine = create_engine("knn", n_samples=4700)
    with pytest.raises(InputError, match="320x240 gray .* at most 4660 "):
        engine.apply(np.zeros((240, 320), np.uint8))


def test_mog2_model_size_is_checked_against_the_first_frame():
    engine = create_engine("mog2", n_mixtures=255)
    with pytest.raises(InputError, match="n_mixtures=255 .* 1920x1080 colour .* at most 51 "):
        engine.apply(np.zeros((1080, 1920, 3), np.uint8))


def test_an_engine_with_a_size_check_still_pickles_before_its_first_frame():
    engine = pickle.loads(pickle.dumps(create_engine("knn", n_samples=60_000)))
    with pytest.raises(InputError, match="n_samples=60000"):
        engine.apply(np.zeros((48, 64, 3), np.uint8))
