"""Motion-boundary data weights: Eq. 5, the adaptive weights and the scene-flow band."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy import ndimage
from skimage import data, transform

from stereodeblur.blur.operator import SparseBlur
from stereodeblur.deconv import deblur_irls
from stereodeblur.deconv.noise import auto_alpha
from stereodeblur.deconv.weights import (
    PAPER_K_SIGMA,
    AdaptiveWeights,
    PaperWeights,
    adaptive_initial_weights,
    boundary_band_width,
    initial_weights_from_occlusion,
    motion_boundaries,
    motion_boundary_band,
    residual_image,
    residual_norm,
    weights_image,
    write_weights_history,
)
from stereodeblur.errors import InputError
from stereodeblur.evaluation.metrics import psnr
from stereodeblur.geometry.camera import Exposure, StereoCamera
from stereodeblur.io.formats import read_png
from stereodeblur.sceneflow.model import SceneFlow

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


# --- adaptive weights on an exact model -------------------------------------------------------


@pytest.fixture
def exact_problem(box_blur, colour_image):
    def build(sigma, seed=0):
        blur = box_blur(SHAPE, 5, 11)
        sharp = colour_image(SHAPE)
        rng = np.random.default_rng(seed)
        blurred = (blur.forward(sharp) + rng.normal(0.0, sigma, sharp.shape)).astype(np.float32)
        return sharp, blurred, blur

    return build


@pytest.mark.parametrize("sigma", [0.0, 0.01])
def test_adaptive_weights_stay_near_one_where_the_model_is_exact(sigma, exact_problem):
    _, blurred, blur = exact_problem(sigma)
    update = AdaptiveWeights()
    result = deblur_irls(
        blurred, blur, alpha=auto_alpha(blurred), num_irls=5, update_weights=update
    )
    assert len(result.weights_history) == 5 and len(update.history) == 4
    for w in result.weights_history[1:]:
        assert w.min() >= 0 and w.max() <= 1
        assert np.mean(w > 0.9) > 0.9
    assert np.mean(result.weights_history[-1] > 0.9) > 0.95


def test_paper_weights_decay_on_noise_where_the_model_is_exact(exact_problem):
    # The failure of Eq. 5 the adaptive weights avoid: sigma = 0.01 alone gives residual
    # norms of about 0.015, where exp(-4000/3 r^2) is about 0.7.
    _, blurred, blur = exact_problem(0.01)
    result = deblur_irls(blurred, blur, alpha=1e-3, num_irls=3, update_weights=PaperWeights())
    assert np.mean(result.weights_history[-1] > 0.9) < 0.5


def test_adaptive_weights_ignore_one_outlying_pixel():
    rng = np.random.default_rng(1)
    residual = rng.normal(0.0, 0.01, (40, 40, 3)).astype(np.float32)
    residual[20, 20] = 0.05  # 5 sigma in every channel, a single pixel
    w = call(AdaptiveWeights(noise_sigma=0.01), residual)
    assert w[20, 20] > 0.5
    assert np.mean(w > 0.9) > 0.99


def test_adaptive_weights_formula():
    rng = np.random.default_rng(2)
    residual = rng.normal(0.0, 0.01, (30, 40, 3))
    residual[5:15, 10:20] += 0.2
    update = AdaptiveWeights(noise_sigma=0.004, smoothing=0.0, first_step=0.5, step_decay=0.5)
    previous = np.full((30, 40), 0.8, np.float32)
    w = call(update, residual, previous, n=3)
    e = np.sqrt(np.mean(residual**2, axis=2))
    scale = 2.5 * max(np.median(e), 0.004, 0.003)
    v = 1 / (1 + (e / scale) ** 4)
    step = 0.5 * 0.5**2
    np.testing.assert_allclose(w, (1 - step) * 0.8 + step * v, rtol=1e-5, atol=1e-6)
    assert update.history[-1].scale == pytest.approx(scale)
    assert update.step(1) == 0.5 and update.step(3) == 0.125


# --- adaptive weights where the model is wrong ------------------------------------------------


def _shift(image, dx):
    """``out(y, x) = image(y, x - dx)``, clamped at the borders."""
    return image[:, np.clip(np.arange(image.shape[1]) - dx, 0, image.shape[1] - 1)]


def two_layer_problem(sigma, seed=0):
    """A disc moving right over a static background, rendered exactly.

    The blurred frame averages 9 instants of the composite; the operator gives every
    pixel its layer's blur at the reference instant (disc: box of 9 along x; background:
    identity), so it is wrong only where disc and background mix during the exposure.
    """
    height, width = SHAPE
    background = transform.resize(data.astronaut() / 255.0, (*SHAPE, 3), anti_aliasing=True)
    foreground = transform.resize(data.coffee() / 255.0, (*SHAPE, 3), anti_aliasing=True)
    ys, xs = np.mgrid[0:height, 0:width]
    disc = (ys - 36) ** 2 / 18**2 + (xs - 48) ** 2 / 22**2 <= 1
    shifts = np.arange(-4, 5)
    frames, masks = [], []
    for dx in shifts:
        moved = _shift(disc, dx)
        frames.append(np.where(moved[..., None], _shift(foreground, dx), background))
        masks.append(moved)
    sharp = np.where(disc[..., None], foreground, background).astype(np.float32)
    mixed = np.any([m != disc for m in masks], axis=0)
    rng = np.random.default_rng(seed)
    blurred = np.mean(frames, axis=0) + rng.normal(0.0, sigma, sharp.shape)

    rows = np.arange(height * width).reshape(SHAPE)
    taps = np.where(disc[..., None], shifts, 0)  # (H, W, 9) displacement of every tap
    cols = ys[..., None] * width + np.clip(xs[..., None] - taps, 0, width - 1)
    matrix = sp.csr_matrix(
        (
            np.full(cols.size, 1.0 / shifts.size),
            (np.broadcast_to(rows[..., None], cols.shape).ravel(), cols.ravel()),
        ),
        shape=(height * width, height * width),
        dtype=np.float32,
    )
    return sharp, blurred.astype(np.float32), SparseBlur(matrix, SHAPE), mixed


def test_two_layer_model_is_wrong_only_at_mixed_pixels():
    sharp, blurred, blur, mixed = two_layer_problem(0.0)
    error = np.abs(blur.forward(sharp) - blurred).max(axis=2)
    assert error[~mixed].max() < 1e-5
    assert np.mean(error[mixed] > 0.02) > 0.5 and 0.05 < mixed.mean() < 0.15


@pytest.mark.parametrize("sigma", [0.0, 0.01])
def test_adaptive_weights_go_low_where_the_model_is_wrong_and_converge(sigma):
    sharp, blurred, blur, mixed = two_layer_problem(sigma)
    alpha = auto_alpha(blurred)
    update = AdaptiveWeights()
    result = deblur_irls(blurred, blur, alpha=alpha, num_irls=10, update_weights=update)
    plain = deblur_irls(blurred, blur, alpha=alpha, num_irls=10)

    w = result.weights_history[-1]
    low = w < 0.5
    distance = ndimage.distance_transform_edt(~mixed)
    assert low.sum() > 0.1 * mixed.sum()  # it does find the mixed pixels...
    assert np.mean(distance[low] <= 3) > 0.7  # ...and little else
    change = np.abs(result.weights_history[-1] - result.weights_history[-2])
    assert np.mean(change > 0.05) < 0.01
    assert psnr(result.image, sharp) > psnr(plain.image, sharp) + 1.0


# --- motion boundaries of a scene flow -------------------------------------------------------


def two_segment_flow(right_twist, occlusion=None, shape=(24, 32)):
    """Left half segment 0 (static), right half segment 1, both on one plane 3 m away."""
    height, width = shape
    focal = 0.8 * width
    K = np.array([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1]])
    labels = np.zeros(shape, np.int32)
    labels[:, width // 2 :] = 1
    return SceneFlow(
        StereoCamera(K, 0.12),
        labels=labels,
        normals=np.array([[0, 0, 1 / 3.0], [0, 0, 1 / 3.0]]),
        twists=np.array([np.zeros(6), right_twist]),
        occlusion=np.zeros(shape, bool) if occlusion is None else occlusion,
    )


def test_motion_boundaries_and_band():
    flow = two_segment_flow(np.array([0.3, 0, 0, 0, 0, 0]))  # 0.3 m: 2.56 px per frame
    columns = np.arange(32)
    boundary = motion_boundaries(flow)
    np.testing.assert_array_equal(
        boundary, np.broadcast_to((columns == 15) | (columns == 16), (24, 32))
    )
    band = motion_boundary_band(flow, 2.0)
    np.testing.assert_array_equal(
        band, np.broadcast_to((columns >= 13) & (columns <= 18), (24, 32))
    )
    assert not motion_boundaries(flow, flow_threshold=3.0).any()


def test_same_motion_is_no_boundary():
    twist = np.array([0.3, 0, 0, 0, 0.01, 0])
    flow = SceneFlow(
        two_segment_flow(twist).camera,
        labels=two_segment_flow(twist).labels,
        normals=np.array([[0, 0, 1 / 3.0], [0, 0, 1 / 3.0]]),
        twists=np.array([twist, twist]),
        occlusion=np.zeros((24, 32), bool),
    )
    assert not motion_boundaries(flow).any()
    assert not motion_boundary_band(flow, 3.0).any()


def test_band_includes_occlusions():
    occlusion = np.zeros((24, 32), bool)
    occlusion[5, 5] = True
    flow = two_segment_flow(np.zeros(6), occlusion)
    band = motion_boundary_band(flow, 1.0)
    ys, xs = np.mgrid[0:24, 0:32]
    np.testing.assert_array_equal(band, (ys - 5) ** 2 + (xs - 5) ** 2 <= 1)
    assert not motion_boundary_band(flow, 1.0, include_occlusion=False).any()


def test_band_width_scales_with_relative_blur():
    exposure = Exposure(frame_rate=20.0, exposure=0.04)
    slow = two_segment_flow(np.array([0.3, 0, 0, 0, 0, 0]))
    fast = two_segment_flow(np.array([1.2, 0, 0, 0, 0, 0]))
    for flow in (slow, fast):
        u = flow.flow()[..., 0]
        difference = np.abs(u[:, 16] - u[:, 15])
        expected = 1.0 + 0.125 * 0.8 * np.quantile(difference, 0.9)
        assert boundary_band_width(flow, exposure) == pytest.approx(expected)
    assert boundary_band_width(fast, exposure) > boundary_band_width(slow, exposure)
    assert boundary_band_width(two_segment_flow(np.zeros(6)), exposure, margin=1.5) == 1.5


def test_adaptive_initial_weights():
    flow = two_segment_flow(np.array([1.2, 0, 0, 0, 0, 0]))
    exposure = Exposure(frame_rate=20.0, exposure=0.04)
    w = adaptive_initial_weights(flow, exposure, width=2.0)
    band = motion_boundary_band(flow, 2.0)
    np.testing.assert_array_equal(w, np.where(band, 0.3, 1.0).astype(np.float32))


# --- pictures ----------------------------------------------------------------------------------


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


@pytest.mark.parametrize(
    "kwargs",
    [
        {"threshold": 0.0},
        {"min_sigma": -1.0},
        {"smoothing": -1.0},
        {"first_step": 0.0},
        {"step_decay": 1.5},
        {"noise_sigma": -0.1},
    ],
)
def test_adaptive_weights_reject_bad_parameters(kwargs):
    with pytest.raises(InputError):
        AdaptiveWeights(**kwargs)


def test_bad_inputs():
    with pytest.raises(InputError):
        PaperWeights(k_sigma=0.0)
    with pytest.raises(InputError):
        call(AdaptiveWeights(), np.zeros((4, 5, 3)), weights=np.ones((5, 4), np.float32))
    with pytest.raises(InputError):
        initial_weights_from_occlusion(np.zeros(5, bool))
    with pytest.raises(InputError):
        motion_boundary_band(two_segment_flow(np.zeros(6)), -1.0)
    with pytest.raises(InputError):
        residual_image(np.zeros((3, 3)), full_scale=0.0)
