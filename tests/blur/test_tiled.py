"""The tiled float32 products (:mod:`stereodeblur.blur._tiled`) against scipy in float64."""

from __future__ import annotations

import numba
import numpy as np
import pytest
import scipy.sparse as sp

from stereodeblur.blur._tiled import (
    TILE,
    padded_planes,
    tile_rows,
    tiled_pixels,
    tiled_product,
    to_planar,
)
from stereodeblur.blur.operator import SparseBlur, dot_test


def _matrix(n: int, seed: int, *, per_row: int = 6, spread: int | None = None) -> sp.csr_matrix:
    """Random square float32 CSR with duplicates, empty rows and far columns."""
    rng = np.random.default_rng(seed)
    spread = n if spread is None else spread
    rows = np.repeat(np.arange(n), rng.integers(0, per_row + 1, n))
    cols = np.clip(rows + rng.integers(-spread, spread + 1, rows.size), 0, n - 1)
    cols[: min(3, cols.size)] = n - 1  # the farthest offset from the first rows
    values = rng.uniform(0.1, 1, rows.size).astype(np.float32)
    matrix = sp.csr_matrix((values, (rows, cols)), shape=(n, n), dtype=np.float32)
    matrix.indices = matrix.indices.astype(np.int32)
    matrix.indptr = matrix.indptr.astype(np.int32)
    return matrix


@pytest.mark.parametrize("n", [1, 15, 16, 17, 100, 333])
@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_products_match_scipy(n, channels):
    m = _matrix(n, seed=n + channels)
    tiled = tile_rows(m.indptr, m.indices, m.data, n)
    assert tiled.padded_rows == TILE * -(-n // TILE)
    x = np.random.default_rng(1).standard_normal((n, channels)).astype(np.float32)
    expected = m.astype(np.float64) @ x.astype(np.float64)
    atol = 1e-5 * max(1.0, np.abs(expected).max())
    np.testing.assert_allclose(tiled_pixels(tiled, to_planar(x, tiled.margin)), expected, atol=atol)
    scale = np.random.default_rng(2).uniform(0, 1, n).astype(np.float32)
    out = np.full((channels, 5 + tiled.padded_rows), np.nan, np.float32)
    tiled_product(tiled, to_planar(x, tiled.margin), out, shift=5, scale=scale)
    np.testing.assert_allclose(out[:, 5 : 5 + n].T, scale[:, None] * expected, atol=atol)
    assert np.all(out[:, 5 + n :] == 0)  # the last tile's padding rows
    assert np.isnan(out[:, :5]).all()  # nothing before the shift


def test_duplicates_are_summed_and_tiles_share_offsets():
    m = sp.csr_matrix(
        (np.float32([1, 2, 4]), np.int32([3, 3, 0]), np.int32([0, 2, 3, 3, 3])), shape=(4, 4)
    )
    tiled = tile_rows(m.indptr, m.indices, m.data, 4)
    assert tiled.num_tiles == 1
    offsets = tiled.starts.astype(np.int64) - tiled.margin
    assert offsets.tolist() == [-1, 3]  # row 1 -> column 0 and row 0 -> column 3, sorted
    np.testing.assert_array_equal(tiled.values[1, :4], [3, 0, 0, 0])
    np.testing.assert_array_equal(tiled.values[0, :4], [0, 4, 0, 0])


def test_result_does_not_depend_on_threads():
    m = _matrix(20000, seed=3, per_row=12, spread=700)
    tiled = tile_rows(m.indptr, m.indices, m.data, m.shape[1])
    assert tiled.values.size >= 1 << 16  # several ranges on several threads
    x = np.random.default_rng(4).standard_normal((m.shape[0], 3)).astype(np.float32)
    planes = to_planar(x, tiled.margin)
    both = tiled_pixels(tiled, planes)
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        one = tiled_pixels(tile_rows(m.indptr, m.indices, m.data, m.shape[1]), planes)
    finally:
        numba.set_num_threads(previous)
    np.testing.assert_array_equal(one, both)


def test_padded_planes_have_zero_margins():
    planes = padded_planes(2, 5, 3)
    assert planes.shape == (2, 11)
    assert np.all(planes[:, :3] == 0) and np.all(planes[:, 8:] == 0)


def test_rectangular_matrices_are_refused():
    m = sp.csr_matrix(np.ones((2, 3), np.float32))
    with pytest.raises(ValueError, match="square"):
        tile_rows(m.indptr, m.indices.astype(np.int32), m.data, 3)


@pytest.mark.parametrize("channels", [None, 3])
def test_sparse_blur_float32_dot_test(channels):
    """The float32 forward and adjoint (both tiled) are adjoint to float32 rounding."""
    shape = (23, 19)
    op = SparseBlur(_matrix(shape[0] * shape[1], seed=5, spread=60), shape)
    full = shape if channels is None else shape + (channels,)
    rng = np.random.default_rng(6)
    x = rng.standard_normal(full).astype(np.float32)
    y = rng.standard_normal(full).astype(np.float32)
    lhs = np.vdot(op.forward(x).astype(np.float64), y)
    rhs = np.vdot(x.astype(np.float64), op.adjoint(y))
    assert abs(lhs - rhs) <= 1e-5 * max(abs(lhs), abs(rhs))
    assert dot_test(op, full, seed=7) < 1e-12  # float64: the CSR kernels
