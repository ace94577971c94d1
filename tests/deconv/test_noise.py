"""Noise estimation and the prior weight set from it."""

from __future__ import annotations

import numpy as np
import pytest

from stereodeblur.deconv.noise import (
    ALPHA_MAX,
    ALPHA_MIN,
    ALPHA_POWER,
    ALPHA_SCALE,
    alpha_from_sigma,
    auto_alpha,
    estimate_noise_sigma,
)
from stereodeblur.errors import InputError

SHAPE = (120, 160)


@pytest.fixture
def blurred_colour(box_blur, colour_image):
    return box_blur(SHAPE, 5, 13).forward(colour_image(SHAPE))


@pytest.fixture
def blurred_grey(box_blur, camera_image):
    return box_blur(SHAPE, 5, 13, seed=1).forward(camera_image(SHAPE))


@pytest.mark.parametrize("sigma", [0.005, 0.01, 0.02])
@pytest.mark.parametrize("which", ["blurred_colour", "blurred_grey"])
def test_estimate_within_20_percent_on_blurred_natural_image(sigma, which, request):
    clean = request.getfixturevalue(which)
    rng = np.random.default_rng(7)
    noisy = (clean + rng.normal(0.0, sigma, clean.shape)).astype(np.float32)
    assert estimate_noise_sigma(noisy) == pytest.approx(sigma, rel=0.2)


def test_estimate_of_pure_noise_is_unbiased():
    rng = np.random.default_rng(3)
    noisy = 0.5 + rng.normal(0.0, 0.01, (200, 200, 3))
    assert estimate_noise_sigma(noisy) == pytest.approx(0.01, rel=0.03)


def test_estimate_ignores_edges():
    rng = np.random.default_rng(4)
    steps = np.where(np.arange(160) % 40 < 20, 0.2, 0.8) * np.ones((120, 1))
    noisy = steps + rng.normal(0.0, 0.01, steps.shape)
    assert estimate_noise_sigma(noisy) == pytest.approx(0.01, rel=0.1)


def test_noiseless_blurred_image_reads_small(blurred_colour, blurred_grey):
    assert estimate_noise_sigma(blurred_colour) < 0.003
    assert estimate_noise_sigma(blurred_grey) < 0.003


def test_auto_alpha_is_monotone_in_sigma(blurred_colour):
    rng = np.random.default_rng(5)
    noise = rng.standard_normal(blurred_colour.shape)
    sigmas = [0.0, 0.002, 0.005, 0.01, 0.015, 0.02, 0.04]
    alphas = [auto_alpha(blurred_colour + s * noise) for s in sigmas]
    assert all(b >= a for a, b in zip(alphas, alphas[1:], strict=False))
    # Strictly increasing where the rule is not clamped.
    assert alphas[2] < alphas[3] < alphas[4] < alphas[5]
    assert alphas[0] == pytest.approx(ALPHA_MIN)
    assert ALPHA_MIN <= min(alphas) and max(alphas) <= ALPHA_MAX


def test_alpha_from_sigma_rule_and_clamp():
    sigma = 0.01
    assert alpha_from_sigma(sigma) == pytest.approx(ALPHA_SCALE * sigma**ALPHA_POWER)
    assert alpha_from_sigma(0.0) == ALPHA_MIN
    assert alpha_from_sigma(1.0) == ALPHA_MAX
    assert alpha_from_sigma(0.02, scale=1.0, power=1.0, alpha_min=1e-6, alpha_max=1.0) == (
        pytest.approx(0.02)
    )
    grid = np.linspace(0, 0.1, 101)
    values = [alpha_from_sigma(s) for s in grid]
    assert np.all(np.diff(values) >= 0)


def test_auto_alpha_matches_rule_on_estimate(blurred_grey):
    rng = np.random.default_rng(6)
    noisy = blurred_grey + rng.normal(0.0, 0.01, blurred_grey.shape)
    assert auto_alpha(noisy) == alpha_from_sigma(estimate_noise_sigma(noisy))


@pytest.mark.parametrize(
    "image",
    [np.zeros(10), np.zeros((2, 5)), np.full((8, 8), np.nan), np.array([["a"] * 4] * 4)],
)
def test_estimate_rejects_bad_images(image):
    with pytest.raises(InputError):
        estimate_noise_sigma(image)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"sigma": -0.1},
        {"sigma": float("nan")},
        {"sigma": 0.01, "scale": 0.0},
        {"sigma": 0.01, "power": -1.0},
        {"sigma": 0.01, "alpha_min": 0.0},
        {"sigma": 0.01, "alpha_min": 1e-2, "alpha_max": 1e-3},
    ],
)
def test_alpha_from_sigma_rejects_bad_values(kwargs):
    sigma = kwargs.pop("sigma")
    with pytest.raises(InputError):
        alpha_from_sigma(sigma, **kwargs)
