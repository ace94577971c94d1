"""The linear-operator interface shared by blur operators, and the dot test.

An operator maps a sharp image to a blurred one over the same pixel grid. Images
are ``(H, W)`` or ``(H, W, C)``; every channel is blurred by the same matrix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class SparseBlur:
    """A blur operator held as a CSR matrix (rows: blurred pixels, columns: sharp pixels).

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix, shape (H*W, H*W)
        Row-major pixel order, ``index = y * W + x``.
    shape : tuple of int
        Image shape ``(H, W)``.
    """

    matrix: sp.csr_matrix
    shape: tuple[int, int]

    def __post_init__(self):
        n = self.shape[0] * self.shape[1]
        if self.matrix.shape != (n, n):
            raise ValueError(
                f"matrix shape {self.matrix.shape} does not match image shape {self.shape}"
            )
        matrix = sp.csr_matrix(self.matrix)
        object.__setattr__(self, "shape", tuple(int(v) for v in self.shape))
        object.__setattr__(self, "matrix", matrix)

    def _check(self, image: np.ndarray) -> np.ndarray:
        return _checked(image, self.shape)

    def _transposed(self) -> sp.csr_matrix:
        """``A^T`` as CSR (built on first use; the float32 products use the tiles instead)."""
        matrix_t = self.__dict__.get("_matrix_t")
        if matrix_t is None:
            matrix_t = _transpose(self.matrix)
            object.__setattr__(self, "_matrix_t", matrix_t)
        return matrix_t

    def _tiled(self):
        """``A`` and ``A^T`` as :class:`~._tiled.TiledMatrix` (built on first use), or None.

        Only compact matrices (float32 values, int32 indices) are tiled.
        """
        if not _is_compact(self.matrix):
            return None
        tiles = self.__dict__.get("_tiles")
        if tiles is None:
            from ._tiled import tile_rows

            M = self.matrix
            M_t = self.__dict__.get("_matrix_t")
            M_t = _transpose(M) if M_t is None else M_t
            tiles = (
                tile_rows(M.indptr, M.indices, M.data, M.shape[1]),
                tile_rows(M_t.indptr, M_t.indices, M_t.data, M_t.shape[1]),
            )
            object.__setattr__(self, "_tiles", tiles)
        return tiles

    def _apply(self, transposed: bool, image: np.ndarray) -> np.ndarray:
        image = self._check(image)
        n = self.matrix.shape[0]
        dtype = np.result_type(image.dtype, np.float32)
        flat = np.ascontiguousarray(image.reshape(n, -1), dtype=dtype)
        if dtype == np.float32 and (tiles := self._tiled()) is not None:
            return _tiled_apply(tiles[int(transposed)], flat).reshape(image.shape)
        M = self._transposed() if transposed else self.matrix
        if not _is_compact(M) or dtype != np.float64:
            return (M @ flat).astype(dtype, copy=False).reshape(image.shape)
        # Rows in parallel (numba): faster than scipy's single-threaded SpMV on 2 cores.
        from ._kernels import csr_matmat

        out = np.empty((M.shape[0], flat.shape[1]), dtype=dtype)
        csr_matmat(M.indptr, M.indices, M.data, flat, out)
        return out.reshape(image.shape)

    def forward(self, image: np.ndarray) -> np.ndarray:
        """Blur ``image``: ``A I``."""
        return self._apply(False, image)

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """Apply the transpose: ``A^T B``."""
        return self._apply(True, image)

    def gram(self, image: np.ndarray, squared_weights: np.ndarray | None = None) -> np.ndarray:
        """``A^T W^2 A I`` with ``W^2 = diag(squared_weights)``.

        Equals ``adjoint(squared_weights[..., None] * forward(image))`` up to rounding; on
        float32 images ``W^2 A I`` stays in the tiles' planar layout between the two products.

        Parameters
        ----------
        image : ndarray, shape (H, W) or (H, W, C)
        squared_weights : ndarray, shape (H, W), optional
            Per blurred pixel; all ones by default.
        """
        image = self._check(image)
        n = self.matrix.shape[0]
        squared = _flat_weights(squared_weights, self.shape)
        dtype = np.result_type(image.dtype, np.float32)
        if dtype != np.float32 or (tiles := self._tiled()) is None:
            blurred = self.forward(image)
            if squared is not None:
                blurred = blurred * squared.reshape(self.shape + (1,) * (image.ndim - 2))
            return self.adjoint(blurred)
        flat = np.ascontiguousarray(image.reshape(n, -1), dtype=dtype)
        return _tiled_gram(tiles, flat, squared).reshape(image.shape)


@dataclass(frozen=True, eq=False)
class TiledBlur:
    """A float32 :class:`SparseBlur` held only as the row tiles of ``A`` and ``A^T``
    (:mod:`._tiled`, what its float32 products read), without the CSR matrix: the same
    products in less memory, for operators that need nothing else (further observations).
    Images of another dtype are multiplied in float32. Make one with :meth:`of`."""

    tiles: tuple
    shape: tuple[int, int]

    @classmethod
    def of(cls, blur: SparseBlur):
        """``blur``'s tiles (built now if not yet) as a :class:`TiledBlur`; ``blur`` itself
        if it has none (not float32 values and int32 indices)."""
        tiles = blur._tiled()
        return blur if tiles is None else cls(tiles, blur.shape)

    @property
    def nnz(self) -> int:
        """Nonzero entries of ``A``."""
        return int(np.count_nonzero(self.tiles[0].values))

    def _flat(self, image: np.ndarray) -> np.ndarray:
        image = _checked(image, self.shape)
        n = self.shape[0] * self.shape[1]
        return np.ascontiguousarray(image.reshape(n, -1), dtype=np.float32)

    def forward(self, image: np.ndarray) -> np.ndarray:
        """Blur ``image``: ``A I`` (float32)."""
        return _tiled_apply(self.tiles[0], self._flat(image)).reshape(np.shape(image))

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """Apply the transpose: ``A^T B`` (float32)."""
        return _tiled_apply(self.tiles[1], self._flat(image)).reshape(np.shape(image))

    def gram(self, image: np.ndarray, squared_weights: np.ndarray | None = None) -> np.ndarray:
        """``A^T W^2 A I`` as :meth:`SparseBlur.gram` computes it on float32 images."""
        squared = _flat_weights(squared_weights, self.shape)
        return _tiled_gram(self.tiles, self._flat(image), squared).reshape(np.shape(image))


def _checked(image, shape) -> np.ndarray:
    """``image`` as an array, a ValueError unless its first two axes are ``shape``."""
    image = np.asarray(image)
    if image.shape[:2] != tuple(shape):
        raise ValueError(f"image shape {image.shape} does not match operator shape {shape}")
    return image


def _flat_weights(squared_weights, shape) -> np.ndarray | None:
    """``squared_weights`` (``shape``, or None) as a contiguous float32 vector, or None."""
    if squared_weights is None:
        return None
    squared = np.asarray(squared_weights)
    if squared.shape != tuple(shape):
        raise ValueError(f"squared_weights shape {squared.shape} does not match {shape}")
    return np.ascontiguousarray(squared.ravel(), dtype=np.float32)


def _tiled_apply(tiled, flat: np.ndarray) -> np.ndarray:
    """The tiled matrix ``tiled`` times the float32 ``(N, C)`` image ``flat``."""
    from ._tiled import tiled_pixels, to_planar

    return tiled_pixels(tiled, to_planar(flat, tiled.margin))


def _tiled_gram(tiles, flat: np.ndarray, squared: np.ndarray | None) -> np.ndarray:
    """``A^T W^2 A`` times ``flat`` with ``tiles`` = (``A``, ``A^T``), ``W^2 A`` kept in the
    tiles' planar layout."""
    from ._tiled import padded_planes, tiled_pixels, tiled_product, to_planar

    forward, adjoint = tiles
    weighted = padded_planes(flat.shape[1], flat.shape[0], adjoint.margin)
    tiled_product(
        forward, to_planar(flat, forward.margin), weighted, shift=adjoint.margin, scale=squared
    )
    return tiled_pixels(adjoint, weighted)


def merge_rows(base: SparseBlur, other: SparseBlur, mask: np.ndarray) -> SparseBlur:
    """The operator with ``other``'s rows at the pixels of ``mask`` and ``base``'s elsewhere.

    Parameters
    ----------
    base, other : SparseBlur
        Operators over the same image shape.
    mask : ndarray of bool, shape (H, W)
        Blurred pixels whose row comes from ``other``.
    """
    mask = np.asarray(mask, dtype=bool)
    if base.shape != other.shape or mask.shape != base.shape:
        raise ValueError(
            f"operators {base.shape}, {other.shape} and mask {mask.shape} must have one shape"
        )
    take = mask.ravel()
    a, b = base.matrix, other.matrix
    counts_a, counts_b = np.diff(a.indptr), np.diff(b.indptr)
    keep_a = np.repeat(~take, counts_a)
    keep_b = np.repeat(take, counts_b)
    rows = np.concatenate(
        [
            np.repeat(np.arange(take.size), counts_a)[keep_a],
            np.repeat(np.arange(take.size), counts_b)[keep_b],
        ]
    )
    order = np.argsort(rows, kind="stable")
    indices = np.concatenate([a.indices[keep_a], b.indices[keep_b]])[order]
    data = np.concatenate([a.data[keep_a], b.data[keep_b]])[order]
    indptr = np.zeros(take.size + 1, np.int64)
    np.cumsum(np.where(take, counts_b, counts_a), out=indptr[1:])
    index_dtype = np.int32 if indptr[-1] < np.iinfo(np.int32).max else np.int64
    matrix = sp.csr_matrix(
        (data, indices.astype(index_dtype), indptr.astype(index_dtype)), shape=a.shape
    )
    return SparseBlur(matrix, base.shape)


def without_motion(base: SparseBlur, mask: np.ndarray) -> SparseBlur:
    """The operator with identity rows (no blur) at the pixels of ``mask``."""
    n = base.shape[0] * base.shape[1]
    index = np.arange(n + 1, dtype=np.int32)
    still = sp.csr_matrix((np.ones(n, np.float32), index[:-1], index), shape=(n, n))
    return merge_rows(base, SparseBlur(still, base.shape), mask)


def _is_compact(matrix: sp.csr_matrix) -> bool:
    """Whether ``matrix`` has the int32 indices and float32 values of this package's operators.

    Only those take the numba kernels (one compiled version each); others use scipy.
    """
    return (
        matrix.indices.dtype == np.int32
        and matrix.indptr.dtype == np.int32
        and matrix.data.dtype == np.float32
    )


def _transpose(matrix: sp.csr_matrix) -> sp.csr_matrix:
    """``matrix.T`` as CSR, in parallel (numba) for compact matrices."""
    if not _is_compact(matrix):
        return matrix.T.tocsr()
    from ._kernels import transpose

    indptr, indices, data = transpose(matrix.indptr, matrix.indices, matrix.data, matrix.shape[1])
    return sp.csr_matrix((data, indices, indptr.astype(np.int32)), shape=matrix.shape[::-1])


def dot_test(operator, shape: tuple[int, ...], *, seed: int = 0) -> float:
    """Relative error ``|<A x, y> - <x, A^T y>| / max(|<A x, y>|, |<x, A^T y>|)``.

    ``x`` and ``y`` are drawn from a seeded generator, never global random state.
    """
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(shape)
    y = rng.standard_normal(shape)
    lhs = float(np.vdot(operator.forward(x), y))
    rhs = float(np.vdot(x, operator.adjoint(y)))
    return abs(lhs - rhs) / max(abs(lhs), abs(rhs), 1e-300)
