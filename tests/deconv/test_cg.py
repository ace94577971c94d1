import numpy as np
import pytest

from stereodeblur.deconv import conjugate_gradient
from stereodeblur.errors import InputError


def spd_matrix(n: int, seed: int, *, rank: int | None = None) -> np.ndarray:
    """``Q^T Q + n I`` (well conditioned), or a rank-deficient PSD ``Q^T Q`` if ``rank``."""
    rng = np.random.default_rng(seed)
    q = rng.standard_normal((rank or n, n))
    return q.T @ q if rank else q.T @ q + n * np.eye(n)


def matrix_operator(matrix: np.ndarray):
    """The same matrix on every channel of an ``(H, W[, C])`` array (pixels flattened)."""

    def apply(x):
        flat = x.reshape(matrix.shape[0], -1)
        return (matrix @ flat).reshape(x.shape).astype(x.dtype)

    return apply


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-10), (np.float32, 1e-5)])
def test_cg_equals_dense_solve_per_channel(dtype, tol):
    shape = (6, 5, 3)
    n = shape[0] * shape[1]
    matrix = spd_matrix(n, seed=1)
    rng = np.random.default_rng(2)
    # Channels with very different scales: per-channel step sizes must handle them.
    rhs = rng.standard_normal(shape) * np.array([1.0, 1e3, 1e-3])
    result = conjugate_gradient(matrix_operator(matrix), rhs.astype(dtype), num_iterations=n)
    expected = np.linalg.solve(matrix, rhs.reshape(n, 3)).reshape(shape)
    assert result.solution.dtype == dtype
    for c in range(3):
        error = np.linalg.norm(result.solution[..., c] - expected[..., c])
        assert error <= tol * np.linalg.norm(expected[..., c])
    assert result.residual_norms.shape == (n + 1, 3)
    assert result.num_iterations == n


def test_cg_grey_warm_start_and_history():
    shape = (8, 4)
    n = 32
    matrix = spd_matrix(n, seed=3)
    rng = np.random.default_rng(4)
    rhs = rng.standard_normal(shape)
    expected = np.linalg.solve(matrix, rhs.reshape(n)).reshape(shape)
    initial = expected + 1e-3 * rng.standard_normal(shape)
    kept = initial.copy()
    result = conjugate_gradient(matrix_operator(matrix), rhs, initial=initial, num_iterations=3)
    np.testing.assert_array_equal(initial, kept)  # the starting point is not modified
    assert result.solution.shape == shape
    true_start = np.linalg.norm(rhs.reshape(n) - matrix @ initial.reshape(n))
    np.testing.assert_allclose(result.residual_norms[0, 0], true_start, rtol=1e-10)
    true_end = np.linalg.norm(rhs.reshape(n) - matrix @ result.solution.reshape(n))
    np.testing.assert_allclose(result.residual_norms[-1, 0], true_end, rtol=1e-6)
    assert true_end < 0.5 * true_start


def test_cg_rtol_stops_each_channel():
    shape = (10, 10, 2)
    n = 100
    matrix = spd_matrix(n, seed=5)
    rng = np.random.default_rng(6)
    rhs = rng.standard_normal(shape)
    result = conjugate_gradient(matrix_operator(matrix), rhs, num_iterations=200, rtol=1e-6)
    assert result.num_iterations < 200
    final = np.linalg.norm((rhs.reshape(n, 2) - matrix @ result.solution.reshape(n, 2)), axis=0)
    assert np.all(final <= 1.01e-6 * np.linalg.norm(rhs.reshape(n, 2), axis=0))


def test_cg_semidefinite_consistent_system():
    n = 20
    matrix = spd_matrix(n, seed=7, rank=12)
    rng = np.random.default_rng(8)
    rhs = (matrix @ rng.standard_normal(n)).reshape(4, 5)  # in the range of the matrix
    result = conjugate_gradient(matrix_operator(matrix), rhs, num_iterations=60, rtol=1e-12)
    residual = rhs.reshape(n) - matrix @ result.solution.reshape(n)
    assert np.linalg.norm(residual) <= 1e-8 * np.linalg.norm(rhs)
    assert np.all(np.isfinite(result.solution))


def test_cg_zero_rhs_stays_zero():
    result = conjugate_gradient(lambda x: 2 * x, np.zeros((3, 4, 3), np.float32))
    assert result.num_iterations == 0
    np.testing.assert_array_equal(result.solution, 0)


def test_cg_bad_input():
    with pytest.raises(InputError, match="rhs"):
        conjugate_gradient(lambda x: x, np.zeros(5))
    with pytest.raises(InputError, match="initial"):
        conjugate_gradient(lambda x: x, np.ones((3, 3)), initial=np.zeros((3, 4)))
    with pytest.raises(InputError, match="operator returned"):
        conjugate_gradient(lambda x: x[:2], np.ones((3, 3)))
    with pytest.raises(InputError, match="num_iterations"):
        conjugate_gradient(lambda x: x, np.ones((3, 3)), num_iterations=-1)
