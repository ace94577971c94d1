"""The fused row kernels of CG and the prior against plain numpy formulas."""

import numpy as np
import pytest

from stereodeblur.deconv import _normal_equations, cg
from stereodeblur.deconv.prior import add_weighted_laplacian, smoothness_weights

# Shapes with one row or column, widths below and above the lane count, 1, 3 and 4 channels.
SHAPES = [(1, 1, 1), (1, 7, 3), (9, 1, 3), (5, 3, 1), (13, 21, 3), (6, 40, 4), (32, 48, 3)]


def random_arrays(shape, count, seed):
    rng = np.random.default_rng(seed)
    return [rng.standard_normal(shape).astype(np.float32) for _ in range(count)]


def numpy_laplacian(x, wx, wy):
    """``dx^T (wx dx x) + dy^T (wy dy x)`` in float64 with numpy differences."""
    x, wx, wy = (a.astype(np.float64) for a in (x, wx, wy))
    flux_x = wx[:, :-1] * np.diff(x, axis=1)  # weights of the last column are unused
    flux_y = wy[:-1] * np.diff(x, axis=0)
    out = np.zeros_like(x)
    out[:, 1:] += flux_x
    out[:, :-1] -= flux_x
    out[1:] += flux_y
    out[:-1] -= flux_y
    return out


def channel_row_dots(a, b):
    return np.einsum("ijc,ijc->ic", a.astype(np.float64), b.astype(np.float64))


@pytest.mark.parametrize("threaded", [False, True])
@pytest.mark.parametrize("shape", SHAPES)
def test_weighted_laplacian_and_its_dots_match_numpy(shape, threaded, monkeypatch):
    if threaded:  # several row ranges on the worker threads
        monkeypatch.setattr(cg, "PARALLEL_MIN_SIZE", 1)
    x, start = random_arrays(shape, 2, seed=sum(shape))
    wx, wy = (np.abs(a) for a in random_arrays(shape, 2, seed=7))
    out = start.copy()
    partial = np.full((shape[0], shape[2]), np.nan)
    add_weighted_laplacian(x, wx, wy, out, partial)
    expected = start + numpy_laplacian(x, wx, wy)
    np.testing.assert_allclose(out, expected, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(partial, channel_row_dots(x, out), rtol=1e-12, atol=1e-12)


def test_weighted_laplacian_is_symmetric_positive():
    shape = (11, 17, 3)
    x, y = random_arrays(shape, 2, seed=3)
    wx, wy = (np.abs(a) for a in random_arrays(shape, 2, seed=4))
    partial = np.empty((shape[0], 3))
    lx, ly = np.zeros(shape, np.float32), np.zeros(shape, np.float32)
    add_weighted_laplacian(x, wx, wy, lx, partial)
    assert np.all(partial.sum(axis=0) > 0)
    add_weighted_laplacian(y, wx, wy, ly, partial)
    left = np.vdot(y.astype(np.float64), lx)
    right = np.vdot(x.astype(np.float64), ly)
    assert abs(left - right) <= 1e-5 * abs(left)


@pytest.mark.parametrize("shape", SHAPES)
def test_cg_vector_kernels_match_numpy(shape):
    x, r, p, q = random_arrays(shape, 4, seed=11)
    rng = np.random.default_rng(12)
    step = rng.uniform(0.1, 2.0, shape[2]).astype(np.float32)
    coef = np.tile(step, shape[1])
    partial = np.full((shape[0], shape[2]), np.nan)

    cg._channel_dots(p, q, partial)
    np.testing.assert_allclose(partial, channel_row_dots(p, q), rtol=1e-12, atol=1e-12)

    r_new = r.copy()
    cg._update_residual(r_new, q, coef, partial)
    np.testing.assert_array_equal(r_new, r - step * q)
    np.testing.assert_allclose(partial, channel_row_dots(r_new, r_new), rtol=1e-12, atol=1e-12)

    x_new, p_new = x.copy(), p.copy()
    beta = np.tile(step[::-1].copy(), shape[1])
    cg._update_iterate(x_new, p_new, r, coef, beta)
    np.testing.assert_array_equal(x_new, x + step * p)
    np.testing.assert_array_equal(p_new, r + step[::-1] * p)


@pytest.mark.parametrize("threaded", [False, True])
@pytest.mark.parametrize("shape", SHAPES)
def test_smoothness_weights_match_numpy(shape, threaded, monkeypatch):
    if threaded:
        monkeypatch.setattr(cg, "PARALLEL_MIN_SIZE", 1)
    alpha, exponent, epsilon = 2e-3, 0.8, 0.01
    rng = np.random.default_rng(sum(shape))
    image = rng.uniform(0, 1, shape).astype(np.float32)
    image[::2, ::3] = 0.5  # exact zeros and differences below epsilon
    image[1::4] += rng.uniform(-0.02, 0.02, image[1::4].shape).astype(np.float32)
    wx = np.full(shape, np.nan, np.float32)
    wy = np.full(shape, np.nan, np.float32)
    partial = np.full((shape[0], 1), np.nan)
    smoothness_weights(image, alpha, exponent, epsilon, wx, wy, partial)

    def expected(difference):
        size = np.abs(difference.astype(np.float64))
        weight = alpha * np.maximum(size, epsilon) ** (exponent - 2)
        small = 0.5 * exponent * epsilon ** (exponent - 2) * size**2
        small += (1 - 0.5 * exponent) * epsilon**exponent
        return weight, np.where(size >= epsilon, size**exponent, small).sum(axis=(1, 2))

    weight_x, h_x = expected(np.diff(image, axis=1))
    weight_y, h_y = expected(np.diff(image, axis=0))
    np.testing.assert_allclose(wx[:, :-1], weight_x, rtol=1e-6)
    np.testing.assert_allclose(wy[:-1], weight_y, rtol=1e-6)
    assert np.all(wx[:, -1] == 0) and np.all(wy[-1] == 0)
    h_y = np.append(h_y, 0.0)  # the last row has no y difference
    np.testing.assert_allclose(partial[:, 0], h_x + h_y, rtol=1e-6)


@pytest.mark.parametrize("shape", SHAPES)
def test_weighted_residual_matches_numpy(shape):
    blurred, reblurred = random_arrays(shape, 2, seed=5)
    squared = np.random.default_rng(6).uniform(0, 1, shape[:2]).astype(np.float32)
    residual = np.full(shape, np.nan, np.float32)
    partial = np.full((shape[0], 1), np.nan)
    _normal_equations._residual(blurred, reblurred, squared, residual, partial)
    np.testing.assert_array_equal(residual, blurred - reblurred)
    expected = np.einsum("ij,ijc->i", squared.astype(np.float64), residual.astype(np.float64) ** 2)
    np.testing.assert_allclose(partial[:, 0], expected, rtol=1e-12)
