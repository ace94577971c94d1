"""Motion-boundary data weights: Eq. 5 and its pictures."""

from __future__ import annotations

import numpy as np
import pytest

from stereodeblur.deconv import deblur_irls
from stereodeblur.deconv.weights import (
    PAPER_K_SIGMA,
    PaperWeights,
    hidden_weights,
    initial_weights_from_occlusion,
    residual_image,
    residual_norm,
    weights_image,
    write_weights_history,
)
from stereodeblur.errors import InputError
from stereodeblur.io.formats import read_png

SHAPE = (72, 96)


def call(update, residual, weights=None, n=1):
    """One update with the arguments deblur_irls passes (blurred and estimate unused here)."""
    plane = residual.shape[:2]
    weights = np.ones(plane, np.float32) if weights is None else weights
    blurred = np.full(residual.shape, 0.5, np.float32)
    return update(n, blurred, residual, blurred, weights)


# --- Eq. 5 ------------------------------------------------------------------------------------


@pytest.mark.parametrize("channels", [None, 3])
def test_paper_weights_equal_eq5(channels):
    rng = np.random.default_rng(0)
    shape = (6, 7) if channels is None else (6, 7, channels)
    residual = rng.normal(0.0, 0.03, shape).astype(np.float32)
    update = PaperWeights()
    w = call(update, residual)
    squared = residual.astype(np.float64) ** 2
    squared = squared if channels is None else squared.sum(axis=2)
    np.testing.assert_allclose(w, np.exp(-4000.0 / 3.0 * squared), rtol=1e-6)
    assert w.shape == (6, 7) and w.dtype == np.float32
    assert w.min() >= 0 and w.max() <= 1
    assert PAPER_K_SIGMA == pytest.approx(4000 / 3)
    (step,) = update.history
    np.testing.assert_array_equal(step.weights, w)
    np.testing.assert_allclose(step.residual_norm, np.sqrt(squared), rtol=1e-6)


def test_paper_weights_hand_values():
    residual = np.zeros((1, 3, 3), np.float32)
    residual[0, 1] = (0.01, 0.0, 0.0)
    residual[0, 2] = (0.03, 0.04, 0.0)  # norm 0.05
    w = call(PaperWeights(k_sigma=400.0), residual)
    np.testing.assert_allclose(w[0], [1.0, np.exp(-0.04), np.exp(-1.0)], rtol=1e-6)


def test_initial_weights_from_occlusion():
    mask = np.zeros((4, 5), bool)
    mask[1, 2] = mask[3, 0] = True
    w = initial_weights_from_occlusion(mask)
    np.testing.assert_array_equal(w, np.where(mask, 0.0, 1.0))
    assert w.dtype == np.float32
    np.testing.assert_array_equal(
        initial_weights_from_occlusion(mask, value=0.3), np.where(mask, 0.3, 1.0).astype(np.float32)
    )


# --- Eq. 5 on an exact model ------------------------------------------------------------------


@pytest.fixture
def exact_problem(box_blur, colour_image):
    def build(sigma, seed=0):
        blur = box_blur(SHAPE, 5, 11)
        sharp = colour_image(SHAPE)
        rng = np.random.default_rng(seed)
        blurred = (blur.forward(sharp) + rng.normal(0.0, sigma, sharp.shape)).astype(np.float32)
        return sharp, blurred, blur

    return build


def test_paper_weights_decay_on_noise_where_the_model_is_exact(exact_problem):
    # The failure of Eq. 5: sigma = 0.01 alone gives residual norms of about 0.015, where
    # exp(-4000/3 r^2) is about 0.7.
    _, blurred, blur = exact_problem(0.01)
    result = deblur_irls(blurred, blur, alpha=1e-3, num_irls=3, update_weights=PaperWeights())
    assert np.mean(result.weights_history[-1] > 0.9) < 0.5


# --- pictures ----------------------------------------------------------------------------------


def test_hidden_weights():
    share = np.array([[0.0, 0.1, 0.25], [0.5, 0.75, 1.0]])
    np.testing.assert_allclose(hidden_weights(share), [[1.0, 0.8, 0.5], [0.0, 0.0, 0.0]])
    assert hidden_weights(share).dtype == np.float32
    np.testing.assert_allclose(hidden_weights(share, slope=1.0)[1], [0.5, 0.25, 0.0])


def test_weight_and_residual_images(tmp_path):
    weights = np.array([[0.0, 0.5, 1.0]], np.float32)
    np.testing.assert_array_equal(weights_image(weights), [[0, 128, 255]])
    residual = np.zeros((1, 3, 3), np.float32)
    residual[0, 1, 0] = 0.05
    residual[0, 2] = (0.3, 0.0, 0.0)
    picture = residual_image(residual, full_scale=0.1)
    assert picture.dtype == np.uint8
    np.testing.assert_array_equal(picture, [[0, 128, 255]])
    np.testing.assert_allclose(residual_norm(residual), [[0.0, 0.05, 0.3]], rtol=1e-6)

    update = PaperWeights()
    rng = np.random.default_rng(3)
    for n in (1, 2):
        call(update, rng.normal(0, 0.02, (8, 9, 3)).astype(np.float32), n=n)
    written = write_weights_history(tmp_path / "w", update.history)
    assert sorted(p.name for p in written) == [
        "residual_01.png",
        "residual_02.png",
        "weights_01.png",
        "weights_02.png",
    ]
    np.testing.assert_allclose(
        read_png(tmp_path / "w" / "weights_02.png"),
        update.history[1].weights,
        atol=0.5 / 255 + 1e-6,
    )


def test_bad_inputs():
    with pytest.raises(InputError):
        PaperWeights(k_sigma=0.0)
    with pytest.raises(InputError):
        initial_weights_from_occlusion(np.zeros(5, bool))
    with pytest.raises(InputError):
        residual_image(np.zeros((3, 3)), full_scale=0.0)
