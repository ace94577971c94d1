"""SparseBlur: the parallel application and transpose agree with scipy."""

import numpy as np
import pytest
import scipy.sparse as sp

from stereodeblur.blur.operator import (
    SparseBlur,
    TiledBlur,
    dot_test,
    merge_rows,
    without_motion,
)

SHAPE = (12, 15)


def _random_matrix(seed, data_dtype, index_dtype, duplicates=False):
    rng = np.random.default_rng(seed)
    n = SHAPE[0] * SHAPE[1]
    nnz = 6 * n
    rows, cols = rng.integers(0, n, nnz), rng.integers(0, n, nnz)
    m = sp.coo_matrix((rng.random(nnz), (rows, cols)), shape=(n, n))
    m = (
        m.tocsr()
        if not duplicates
        else sp.csr_matrix(
            (m.data, m.col, np.searchsorted(np.sort(m.row), np.arange(n + 1))), shape=(n, n)
        )
    )
    m.data = m.data.astype(data_dtype)
    m.indices = m.indices.astype(index_dtype)
    m.indptr = m.indptr.astype(index_dtype)
    return m


@pytest.mark.parametrize("data_dtype", [np.float32, np.float64])
@pytest.mark.parametrize("index_dtype", [np.int32, np.int64])
@pytest.mark.parametrize("channels", [None, 1, 3, 4])
@pytest.mark.parametrize("image_dtype", [np.float32, np.float64])
def test_forward_and_adjoint_match_scipy(data_dtype, index_dtype, channels, image_dtype):
    m = _random_matrix(0, data_dtype, index_dtype)
    op = SparseBlur(m, SHAPE)
    shape = SHAPE if channels is None else SHAPE + (channels,)
    image = np.random.default_rng(1).random(shape).astype(image_dtype)
    flat = image.reshape(m.shape[0], -1).astype(np.float64)
    dense = m.astype(np.float64).toarray()
    out = op.forward(image)
    assert out.shape == shape and out.dtype == image_dtype
    tol = 1e-5 if image_dtype == np.float32 else 1e-12
    np.testing.assert_allclose(out.reshape(flat.shape), dense @ flat, rtol=tol)
    adj = op.adjoint(image)
    assert adj.shape == shape and adj.dtype == image_dtype
    np.testing.assert_allclose(adj.reshape(flat.shape), dense.T @ flat, rtol=tol)


def test_transpose_with_duplicates_and_unsorted_columns():
    m = _random_matrix(2, np.float32, np.int32, duplicates=True)
    assert not m.has_canonical_format
    op = SparseBlur(m, SHAPE)
    np.testing.assert_allclose(op._transposed().toarray(), m.toarray().T, rtol=1e-7)
    assert dot_test(op, SHAPE + (3,), seed=4) < 1e-12


def test_non_contiguous_and_integer_images():
    op = SparseBlur(_random_matrix(3, np.float32, np.int32), SHAPE)
    image = np.random.default_rng(5).random(SHAPE + (6,))[..., ::2]
    np.testing.assert_allclose(op.forward(image), op.forward(np.ascontiguousarray(image)))
    ints = (image[..., 0] * 255).astype(np.uint8)
    out = op.forward(ints)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, op.forward(ints.astype(np.float32)))


def test_shape_errors():
    op = SparseBlur(_random_matrix(3, np.float32, np.int32), SHAPE)
    with pytest.raises(ValueError, match="image shape"):
        op.forward(np.zeros((SHAPE[1], SHAPE[0])))
    with pytest.raises(ValueError, match="matrix shape"):
        SparseBlur(sp.eye(10, format="csr"), SHAPE)


def test_merge_rows_takes_each_row_from_the_chosen_operator():
    a = SparseBlur(_random_matrix(3, np.float32, np.int32), SHAPE)
    b = SparseBlur(_random_matrix(4, np.float32, np.int32), SHAPE)
    mask = np.random.default_rng(5).random(SHAPE) < 0.3
    merged = merge_rows(a, b, mask)
    take = mask.ravel()[:, None]
    expected = np.where(take, b.matrix.toarray(), a.matrix.toarray())
    np.testing.assert_array_equal(merged.matrix.toarray(), expected)
    assert merged.matrix.indices.dtype == np.int32 and merged.matrix.data.dtype == np.float32
    assert dot_test(merged, SHAPE + (2,)) < 1e-12
    with pytest.raises(ValueError, match="one shape"):
        merge_rows(a, b, mask[:-1])


def test_without_motion_gives_identity_rows_in_the_mask_only():
    a = SparseBlur(_random_matrix(3, np.float32, np.int32), SHAPE)
    mask = np.random.default_rng(6).random(SHAPE) < 0.3
    still = without_motion(a, mask)
    image = np.random.default_rng(7).random(SHAPE + (3,)).astype(np.float32)
    out = still.forward(image)
    np.testing.assert_array_equal(out[mask], image[mask])
    np.testing.assert_allclose(out[~mask], a.forward(image)[~mask], rtol=1e-6)
    assert dot_test(still, SHAPE + (3,)) < 1e-6


@pytest.mark.parametrize("channels", [None, 3])
def test_tiled_blur_gives_the_products_of_its_sparse_blur(channels):
    m = _random_matrix(2, np.float32, np.int32)
    op = SparseBlur(m, SHAPE)
    tiled = TiledBlur.of(op)
    assert isinstance(tiled, TiledBlur) and tiled.nnz == m.nnz
    shape = SHAPE if channels is None else SHAPE + (channels,)
    rng = np.random.default_rng(3)
    image = rng.random(shape).astype(np.float32)
    squared = rng.random(SHAPE).astype(np.float32)
    for name, args in (("forward", ()), ("adjoint", ()), ("gram", ()), ("gram", (squared,))):
        got, expected = getattr(tiled, name)(image, *args), getattr(op, name)(image, *args)
        assert got.shape == shape and got.dtype == np.float32
        np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(tiled.forward(image.astype(np.float64)), op.forward(image))
    assert dot_test(tiled, SHAPE) < 1e-5
    with pytest.raises(ValueError, match="does not match"):
        tiled.forward(np.zeros((3, 4), np.float32))


def test_tiled_blur_of_a_non_compact_matrix_is_the_sparse_blur():
    op = SparseBlur(_random_matrix(4, np.float64, np.int64), SHAPE)
    assert TiledBlur.of(op) is op
