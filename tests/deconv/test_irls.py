import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from stereodeblur.deconv import deblur_irls, gradient, gradient_adjoint
from stereodeblur.deconv.irls import Observation
from stereodeblur.errors import InputError


def psnr(image: np.ndarray, reference: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((image.astype(np.float64) - reference) ** 2)))


def difference_matrices(height: int, width: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Forward differences on a row-major grid, zero rows in the last column / row."""

    def one_dimensional(n):
        d = sp.diags([-np.ones(n), np.ones(n - 1)], [0, 1], shape=(n, n)).tolil()
        d[n - 1, :] = 0
        return d.tocsr()

    dx = sp.kron(sp.identity(height), one_dimensional(width))
    dy = sp.kron(one_dimensional(height), sp.identity(width))
    return dx.tocsr(), dy.tocsr()


def smoothed_power(c: np.ndarray, exponent: float, epsilon: float) -> np.ndarray:
    """``|c|^p`` above ``epsilon``, its quadratic continuation (the IRLS majoriser) below."""
    c = np.abs(c)
    small = (
        0.5 * exponent * epsilon ** (exponent - 2) * c**2 + (1 - 0.5 * exponent) * epsilon**exponent
    )
    return np.where(c >= epsilon, c**exponent, small)


def energy(image, blurred, operator, weights, alpha, exponent, epsilon, scale=None):
    """The objective of ``deblur_irls``, computed with numpy and scipy only (``scale``: the
    per-pixel factor of alpha, at each difference's first pixel)."""
    image = np.asarray(image, np.float64)
    residual = blurred - operator.matrix.astype(np.float64) @ image.reshape(weights.size, -1)
    data = np.sum(weights.reshape(-1, 1).astype(np.float64) ** 2 * residual**2)
    scale = np.ones(weights.shape) if scale is None else scale.astype(np.float64)
    dx = np.diff(image, axis=1)
    dy = np.diff(image, axis=0)
    prior = (scale[:, :-1] * smoothed_power(dx, exponent, epsilon)).sum()
    prior += (scale[:-1] * smoothed_power(dy, exponent, epsilon)).sum()
    return data + 2 * alpha / exponent * prior


def blurred_camera(camera_image, box_blur, shape, *, low=5, high=11, noise=0.005, seed=0):
    sharp = camera_image(shape)
    operator = box_blur(shape, low, high, seed=seed)
    rng = np.random.default_rng(seed)
    blurred = operator.forward(sharp) + rng.normal(0, noise, shape).astype(np.float32)
    return sharp, operator, blurred.astype(np.float32)


# --- gradients ----------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(7, 9), (6, 5, 3)])
def test_gradient_matches_numpy_and_adjoint_dot_test(shape):
    rng = np.random.default_rng(0)
    image = rng.standard_normal(shape)
    gx, gy = rng.standard_normal(shape), rng.standard_normal(shape)
    dx, dy = gradient(image)
    expected_dx = np.zeros(shape)
    expected_dx[:, :-1] = np.diff(image, axis=1)
    expected_dy = np.zeros(shape)
    expected_dy[:-1] = np.diff(image, axis=0)
    np.testing.assert_allclose(dx, expected_dx, rtol=0, atol=1e-14)
    np.testing.assert_allclose(dy, expected_dy, rtol=0, atol=1e-14)
    lhs = np.vdot(dx, gx) + np.vdot(dy, gy)
    rhs = np.vdot(image, gradient_adjoint(gx, gy))
    assert abs(lhs - rhs) <= 1e-12 * max(abs(lhs), abs(rhs))


def test_gradient_float32_and_constant_image():
    dx, dy = gradient(np.full((5, 6, 3), 0.3, np.float32))
    assert dx.dtype == np.float32
    np.testing.assert_array_equal(dx, 0)
    np.testing.assert_array_equal(dy, 0)
    np.testing.assert_array_equal(gradient_adjoint(dx, dy), 0)


# --- the normal equations -----------------------------------------------------------------


@pytest.mark.parametrize("channels", [None, 3])
@pytest.mark.parametrize("exponent", [0.8, 2.0])
@pytest.mark.parametrize("scaled", [False, True])
def test_one_irls_step_solves_the_weighted_normal_equations(box_blur, channels, exponent, scaled):
    """Eq. 7-8 with W^2 in the data term (and alpha scaled per pixel), against a sparse
    direct solve in float64."""
    height, width = 20, 24
    shape = (height, width) if channels is None else (height, width, channels)
    rng = np.random.default_rng(1)
    operator = box_blur((height, width), 3, 7, seed=1)
    blurred = rng.random(shape).astype(np.float32)
    weights = rng.uniform(0.2, 1.0, (height, width)).astype(np.float32)
    scale = rng.uniform(0.1, 10.0, (height, width)).astype(np.float32) if scaled else None
    alpha, epsilon = 0.05, 0.01
    result = deblur_irls(
        blurred,
        operator,
        weights=weights,
        alpha=alpha,
        alpha_scale=scale,
        exponent=exponent,
        num_irls=1,
        num_cg=400,
    )
    a = operator.matrix.astype(np.float64)
    w2 = sp.diags(weights.astype(np.float64).ravel() ** 2)
    dx, dy = difference_matrices(height, width)
    flat = blurred.reshape(height * width, -1).astype(np.float64)
    s = np.ones(height * width) if scale is None else scale.astype(np.float64).ravel()
    for c in range(flat.shape[1]):
        rho_x = s * np.maximum(np.abs(dx @ flat[:, c]), epsilon) ** (exponent - 2)
        rho_y = s * np.maximum(np.abs(dy @ flat[:, c]), epsilon) ** (exponent - 2)
        normal = a.T @ w2 @ a + alpha * (dx.T @ sp.diags(rho_x) @ dx + dy.T @ sp.diags(rho_y) @ dy)
        expected = spla.spsolve(normal.tocsc(), a.T @ (w2 @ flat[:, c]))
        got = result.image.reshape(height * width, -1)[:, c]
        assert np.max(np.abs(got - expected)) < 2e-4


# --- recovery -----------------------------------------------------------------------------


def test_noise_free_inversion_of_a_well_conditioned_blur(camera_image, box_blur):
    shape = (48, 64)
    sharp = camera_image(shape)
    operator = box_blur(shape, 5, 11, seed=2, identity=0.3)  # condition number about 8
    blurred = operator.forward(sharp)
    result = deblur_irls(blurred, operator, alpha=1e-8)
    assert psnr(blurred, sharp) < 30
    assert psnr(result.image, sharp) > 40


def test_deblurring_a_natural_image_improves_psnr(camera_image, box_blur):
    sharp, operator, blurred = blurred_camera(camera_image, box_blur, (64, 80))
    result = deblur_irls(blurred, operator)
    assert result.image.dtype == np.float32
    assert result.image.shape == blurred.shape
    assert psnr(result.image, sharp) > psnr(blurred, sharp) + 4


@pytest.mark.parametrize(("masked", "scaled"), [(False, False), (True, False), (False, True)])
def test_energy_does_not_increase(camera_image, box_blur, masked, scaled):
    sharp, operator, blurred = blurred_camera(camera_image, box_blur, (48, 64), seed=3)
    rng = np.random.default_rng(3)
    weights = scale = None
    if masked:
        weights = rng.uniform(0, 1, sharp.shape).astype(np.float32)
        weights[10:20, 20:30] = 0
    if scaled:
        scale = np.exp(rng.uniform(-2.5, 2.5, sharp.shape)).astype(np.float32)
    alpha, exponent, epsilon = 1e-3, 0.8, 0.01
    result = deblur_irls(blurred, operator, weights=weights, alpha_scale=scale, num_irls=8)
    energies = np.array([entry.energy for entry in result.history])
    assert len(energies) == 9
    assert np.all(np.diff(energies) <= 1e-6 * energies[:-1])
    assert energies[-1] < 0.8 * energies[0]
    # The reported energy is the documented objective, computed independently.
    used = np.ones(sharp.shape, np.float32) if weights is None else weights
    expected = energy(
        result.image, blurred.reshape(-1, 1), operator, used, alpha, exponent, epsilon, scale
    )
    np.testing.assert_allclose(result.history[-1].energy, expected, rtol=1e-4)
    last = result.history[-1]
    assert last.energy == pytest.approx(last.data_term + last.prior_term)
    assert last.weights_mean == pytest.approx(float(used.mean()), rel=1e-6)


@pytest.mark.parametrize("fill", [None, 1.0])
def test_zero_weight_mask_is_filled_by_the_prior(camera_image, box_blur, fill):
    shape = (64, 80)
    sharp, operator, blurred = blurred_camera(camera_image, box_blur, shape, low=5, high=9)
    top, left, size = 26, 34, 10
    hole = (slice(top, top + size), slice(left, left + size))
    weights = np.ones(shape, np.float32)
    weights[hole] = 0
    corrupted = blurred.copy()
    if fill is not None:
        corrupted[hole] = fill  # data that must not matter: it has zero weight
    result = deblur_irls(corrupted, operator, weights=weights)
    image = result.image
    assert np.all(np.isfinite(image))
    ring = np.zeros(shape, bool)
    ring[top - 3 : top + size + 3, left - 3 : left + size + 3] = True
    ring[hole] = False
    low, high = sharp[ring].min(), sharp[ring].max()
    assert image[hole].min() >= low - 0.05
    assert image[hole].max() <= high + 0.05
    # Away from the hole (beyond the blur's reach of 4 px) the image is still recovered.
    far = np.ones(shape, bool)
    far[top - 8 : top + size + 8, left - 8 : left + size + 8] = False
    assert psnr(image[far], sharp[far]) > psnr(blurred[far], sharp[far]) + 4


# --- structure ----------------------------------------------------------------------------


def test_multichannel_equals_channel_by_channel(colour_image, box_blur):
    shape = (32, 48)
    sharp = colour_image(shape)
    operator = box_blur(shape, 5, 9, seed=4)
    blurred = operator.forward(sharp)
    weights = np.random.default_rng(4).uniform(0.5, 1, shape).astype(np.float32)
    together = deblur_irls(blurred, operator, weights=weights, num_irls=4).image
    for c in range(3):
        alone = deblur_irls(blurred[..., c], operator, weights=weights, num_irls=4).image
        np.testing.assert_allclose(together[..., c], alone, rtol=0, atol=1e-5)


def test_deterministic(colour_image, box_blur):
    shape = (32, 48)
    operator = box_blur(shape, 5, 9, seed=5)
    blurred = operator.forward(colour_image(shape))
    first = deblur_irls(blurred, operator, num_irls=3)
    second = deblur_irls(blurred, operator, num_irls=3)
    np.testing.assert_array_equal(first.image, second.image)
    assert first.history == second.history


def test_row_ranges_on_worker_threads_give_the_same_result(colour_image, box_blur, monkeypatch):
    """Small images run on the calling thread; force ranges on the worker threads: same bits."""
    from stereodeblur.deconv import cg

    shape = (40, 48)
    operator = box_blur(shape, 5, 9, seed=10)
    blurred = operator.forward(colour_image(shape))
    serial = deblur_irls(blurred, operator, num_irls=3)
    monkeypatch.setattr(cg, "PARALLEL_MIN_SIZE", 1)
    threaded = deblur_irls(blurred, operator, num_irls=3)
    np.testing.assert_array_equal(threaded.image, serial.image)
    assert threaded.history == serial.history


def test_update_weights_hook_and_progress(camera_image, box_blur):
    sharp, operator, blurred = blurred_camera(camera_image, box_blur, (32, 48), seed=6)
    calls, progress = [], []

    def residual_weights(n, blurred_arg, residual, estimate, weights):
        # The residual is B - A I of the current estimate; the arguments are read-only.
        expected = blurred - operator.forward(np.array(estimate))
        np.testing.assert_allclose(residual, expected, atol=1e-6)
        assert not residual.flags.writeable and not estimate.flags.writeable
        np.testing.assert_array_equal(blurred_arg, blurred)
        calls.append((n, weights.copy()))
        return np.exp(-(4000 / 3) * residual**2)  # the shape of Eq. 5

    result = deblur_irls(
        blurred,
        operator,
        num_irls=4,
        update_weights=residual_weights,
        progress=lambda report: progress.append((report.stage, report.done, report.total)),
    )
    assert [n for n, _ in calls] == [1, 2, 3]
    np.testing.assert_array_equal(calls[0][1], 1.0)  # iteration 0 used the initial weights
    assert progress == [("IRLS", n, 4) for n in range(1, 5)]
    assert len(result.weights_history) == 4
    np.testing.assert_array_equal(result.weights_history[0], 1.0)
    np.testing.assert_array_equal(result.weights, result.weights_history[-1])
    assert result.weights.min() < 1.0
    assert [entry.weights_mean for entry in result.history[1:]] == pytest.approx(
        [float(w.mean()) for w in result.weights_history], rel=1e-6
    )


class _ForwardAdjointOnly:
    """An operator without ``gram``: the solver falls back to forward then adjoint."""

    def __init__(self, operator):
        self.shape, self.forward, self.adjoint = operator.shape, operator.forward, operator.adjoint


def test_gram_and_forward_adjoint_paths_agree(colour_image, box_blur):
    shape = (32, 48)
    operator = box_blur(shape, 5, 9, seed=8)
    blurred = operator.forward(colour_image(shape))
    weights = np.random.default_rng(8).uniform(0.2, 1.0, shape)
    fused = deblur_irls(blurred, operator, weights=weights, num_irls=3)
    plain = deblur_irls(blurred, _ForwardAdjointOnly(operator), weights=weights, num_irls=3)
    np.testing.assert_allclose(fused.image, plain.image, atol=1e-5)
    energies = [entry.energy for entry in fused.history]
    assert energies == pytest.approx([entry.energy for entry in plain.history], rel=1e-6)


def test_initial_continues_an_earlier_run_exactly(colour_image, box_blur):
    """IRLS state is the estimate alone: 3 + 3 iterations from a warm start equal 6."""
    shape = (32, 48)
    operator = box_blur(shape, 5, 9, seed=9)
    blurred = operator.forward(colour_image(shape))
    first = deblur_irls(blurred, operator, num_irls=3)
    resumed = deblur_irls(blurred, operator, num_irls=3, initial=first.image)
    whole = deblur_irls(blurred, operator, num_irls=6)
    np.testing.assert_array_equal(resumed.image, whole.image)
    assert resumed.history[0].energy == pytest.approx(first.history[-1].energy, rel=1e-12)
    assert resumed.history[1:] == tuple(
        dataclasses.replace(entry, iteration=entry.iteration - 3) for entry in whole.history[4:]
    )
    np.testing.assert_array_equal(blurred, operator.forward(colour_image(shape)))  # not modified


def test_no_weights_history_without_hook(box_blur):
    operator = box_blur((16, 16), 3, 5)
    result = deblur_irls(np.full((16, 16), 0.5, np.float32), operator, num_irls=2)
    assert result.weights_history is None
    np.testing.assert_array_equal(result.weights, 1.0)
    np.testing.assert_allclose(result.image, 0.5, atol=1e-6)  # a constant image is a fixed point


def test_bad_input(box_blur):
    operator = box_blur((16, 16), 3, 5)
    image = np.zeros((16, 16), np.float32)
    with pytest.raises(InputError, match="weights"):
        deblur_irls(image, operator, weights=np.ones((16, 15)))
    with pytest.raises(InputError, match="weights"):
        deblur_irls(image, operator, weights=np.full((16, 16), 1.5))
    with pytest.raises(InputError, match="operator shape"):
        deblur_irls(np.zeros((16, 17)), operator)
    with pytest.raises(InputError, match="initial"):
        deblur_irls(image, operator, initial=np.zeros((16, 15)))
    with pytest.raises(InputError, match="initial"):
        deblur_irls(image, operator, initial=np.full((16, 16), np.nan))
    with pytest.raises(InputError, match="alpha_scale"):
        deblur_irls(image, operator, alpha_scale=np.ones((16, 15)))
    with pytest.raises(InputError, match="alpha_scale"):
        deblur_irls(image, operator, alpha_scale=np.full((16, 16), -1.0))
    with pytest.raises(InputError, match="exponent"):
        deblur_irls(image, operator, exponent=0)
    with pytest.raises(InputError, match="epsilon"):
        deblur_irls(image, operator, epsilon=0)
    with pytest.raises(InputError, match="num_cg"):
        deblur_irls(image, operator, num_cg=2.5)
    with pytest.raises(InputError, match="blurred"):
        deblur_irls(np.zeros(16), operator)
    with pytest.raises(InputError, match="update_weights"):
        deblur_irls(image, operator, num_irls=2, update_weights=lambda *args: np.ones((3, 3)))


# --- further observations -----------------------------------------------------------------


def test_an_observation_adds_its_data_term(colour_image, box_blur):
    """The same blurred frame observed twice with weights w is one observation with w sqrt 2."""
    shape = (32, 48)
    operator = box_blur(shape, 5, 9, seed=10)
    blurred = operator.forward(colour_image(shape))
    weights = np.random.default_rng(10).uniform(0.2, 0.7, shape).astype(np.float32)
    twice = deblur_irls(
        blurred,
        operator,
        weights=weights,
        num_irls=3,
        observations=[Observation(operator, blurred, weights)],
    )
    once = deblur_irls(blurred, operator, weights=weights * np.sqrt(2), num_irls=3)
    np.testing.assert_allclose(twice.image, once.image, atol=2e-4)
    assert [e.energy for e in twice.history] == pytest.approx(
        [e.energy for e in once.history], rel=1e-4
    )


def test_robust_weights_drop_an_observation_the_operator_does_not_explain(camera_image, box_blur):
    shape = (32, 48)
    sharp, operator, blurred = blurred_camera(camera_image, box_blur, shape, seed=11)
    alone = deblur_irls(blurred, operator, num_irls=5)
    wrong = np.random.default_rng(11).random(shape).astype(np.float32)  # another image
    bad = [Observation(operator, wrong, np.ones(shape, np.float32))]
    plain = deblur_irls(blurred, operator, num_irls=5, observations=bad)
    robust = deblur_irls(blurred, operator, num_irls=5, observations=bad, robust_scale=0.01)
    assert psnr(plain.image, sharp) < psnr(alone.image, sharp) - 3
    assert psnr(robust.image, sharp) > psnr(alone.image, sharp) - 0.5
    # a second, correct observation with other noise helps
    noisy = operator.forward(sharp) + np.random.default_rng(12).normal(0, 0.005, shape)
    good = [Observation(operator, noisy.astype(np.float32), np.ones(shape, np.float32))]
    both = deblur_irls(blurred, operator, num_irls=5, observations=good, robust_scale=0.01)
    assert psnr(both.image, sharp) > psnr(alone.image, sharp) + 0.3


def test_bad_observations(box_blur):
    operator = box_blur((16, 16), 3, 5)
    image = np.zeros((16, 16), np.float32)
    with pytest.raises(InputError, match="observation blurred"):
        deblur_irls(image, operator, observations=[Observation(operator, image[:8], image)])
    with pytest.raises(InputError, match="observation weights"):
        deblur_irls(image, operator, observations=[Observation(operator, image, image + 2)])
    with pytest.raises(InputError, match="robust_scale"):
        deblur_irls(image, operator, robust_scale=0.0)
