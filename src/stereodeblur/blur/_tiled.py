"""Sparse products in tiles of 16 rows that share their column offsets (SIMD-friendly).

A blur matrix row ``r`` has its entries at columns ``r + d`` for offsets ``d`` along the
pixel's trajectory, and neighbouring pixels have nearly the same trajectory. Sixteen
consecutive rows (a *tile*) are therefore stored with the union of their offsets: per
offset, one start and sixteen values (zero where a row has no entry there). A product
then reads sixteen consecutive values of the image per offset, which the compiler turns
into vector loads and fused multiply-adds; a CSR product gathers one value at a time.
The union costs some zero entries where neighbouring blurs differ (measurements:
``benchmarks/README.md``).

Images are planar here, ``(C, columns + 2 margin)`` with zero margins, so that every
offset's sixteen values are contiguous; :func:`to_planar` and :func:`from_planar`
convert from and to the package's ``(N, C)`` pixel-major layout. Each row's sum runs over
its tile's offsets in a fixed order, so results do not depend on the number of threads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .._threads import balanced_ranges, run_ranges

TILE = 16
"""Rows per tile: one AVX-512 vector or two AVX2 vectors of float32."""

_JIT = dict(cache=True, nogil=True, error_model="numpy")
_FAST = dict(_JIT, fastmath=True)


@dataclass(frozen=True, eq=False)
class TiledMatrix:
    """A sparse ``(num_rows, num_cols)`` float32 matrix in tiles of :data:`TILE` rows.

    Attributes
    ----------
    tile_ptr : ndarray of int64, shape (num_tiles + 1,)
        Tile ``t`` owns offsets ``tile_ptr[t] .. tile_ptr[t + 1] - 1``.
    starts : ndarray of uint64, shape (K,)
        Per offset ``d``, ``d + margin``: where the tile's first row reads in a padded plane
        (relative to the tile's first row).
    values : ndarray of float32, shape (K, TILE)
        Per offset, the entries of the tile's rows (zero where a row has none).
    margin : int
        Zero columns a padded plane needs on each side (largest ``|d|`` plus a tile).
    num_rows, num_cols : int
    """

    tile_ptr: np.ndarray
    starts: np.ndarray
    values: np.ndarray
    margin: int
    num_rows: int
    num_cols: int

    @property
    def num_tiles(self) -> int:
        return self.tile_ptr.size - 1

    @property
    def padded_rows(self) -> int:
        """Rows including the last tile's padding."""
        return TILE * self.num_tiles

    @property
    def nbytes(self) -> int:
        return self.tile_ptr.nbytes + self.starts.nbytes + self.values.nbytes


@numba.njit(**_JIT)
def _largest_offset(indptr, indices):  # pragma: no cover - compiled
    """``max |c - r|`` over the entries ``(r, c)`` of a CSR matrix (0 if empty)."""
    largest = 0
    for r in range(indptr.size - 1):
        for k in range(indptr[r], indptr[r + 1]):
            largest = max(largest, abs(np.int64(indices[k]) - r))
    return largest


@numba.njit(**_JIT, inline="always")
def _distinct_offsets(t, indptr, indices, shift, seen, out, base):  # pragma: no cover
    """Tile ``t``'s distinct offsets ``d + shift`` into ``out[base:]``; returns how many.

    ``seen`` (one per possible ``d + shift``) holds the last tile that met an offset, plus
    one, so it needs no clearing between tiles.
    """
    count = 0
    for r in range(t * 16, min(indptr.size - 1, t * 16 + 16)):
        for k in range(indptr[r], indptr[r + 1]):
            d = np.int64(indices[k]) - r + shift
            if seen[d] != t + 1:
                seen[d] = t + 1
                out[base + count] = d
                count += 1
    return count


@numba.njit(**_JIT)
def _count_offsets(first, last, indptr, indices, shift, counts):  # pragma: no cover
    """``counts[t]``: distinct offsets of tile ``t``, for tiles ``first .. last - 1``."""
    seen = np.zeros(2 * shift + 1, np.int64)
    scratch = np.empty(2 * shift + 1, np.int64)
    for t in range(first, last):
        counts[t] = _distinct_offsets(t, indptr, indices, shift, seen, scratch, 0)


@numba.njit(**_JIT)
def _fill_tiles(
    first, last, indptr, indices, data, shift, margin, tile_ptr, starts, values
):  # pragma: no cover - compiled
    """Sorted starts and the values of tiles ``first .. last - 1`` (``values`` zeroed)."""
    seen = np.zeros(2 * shift + 1, np.int64)
    position = np.empty(2 * shift + 1, np.int64)
    for t in range(first, last):
        base = tile_ptr[t]
        count = _distinct_offsets(t, indptr, indices, shift, seen, starts, base)
        # Insertion sort of the tile's offsets (a few dozen): increasing addresses.
        for i in range(base + 1, base + count):
            value = starts[i]
            j = i - 1
            while j >= base and starts[j] > value:
                starts[j + 1] = starts[j]
                j -= 1
            starts[j + 1] = value
        for i in range(base, base + count):
            position[starts[i]] = i
        for r in range(t * 16, min(indptr.size - 1, t * 16 + 16)):
            for k in range(indptr[r], indptr[r + 1]):
                d = np.int64(indices[k]) - r + shift
                values[position[d], r - t * 16] += data[k]
        for i in range(base, base + count):
            starts[i] = starts[i] - shift + margin


def tile_rows(indptr, indices, data, num_cols: int) -> TiledMatrix:
    """The square CSR matrix ``(indptr, indices, data)`` (float32) as a :class:`TiledMatrix`."""
    num_rows = indptr.size - 1
    if num_cols != num_rows:  # the padding rows of the last tile read within the margin
        raise ValueError(f"only square matrices are tiled, got {num_rows} x {num_cols}")
    num_tiles = -(-num_rows // TILE)
    shift = int(_largest_offset(indptr, indices))
    margin = shift + TILE
    row_ptr = np.asarray(indptr)[np.minimum(np.arange(num_tiles + 1) * TILE, num_rows)]
    ranges = balanced_ranges(row_ptr, 2 * numba.get_num_threads())
    counts = np.zeros(num_tiles, np.int64)
    run_ranges(_count_offsets, ranges, indptr, indices, shift, counts)
    tile_ptr = np.zeros(num_tiles + 1, np.int64)
    np.cumsum(counts, out=tile_ptr[1:])
    starts = np.empty(int(tile_ptr[-1]), np.int64)
    values = np.zeros((starts.size, TILE), np.float32)
    args = (indptr, indices, data, shift, margin, tile_ptr, starts, values)
    run_ranges(_fill_tiles, ranges, *args)
    return TiledMatrix(tile_ptr, starts.view(np.uint64), values, margin, num_rows, num_cols)


@numba.njit(**_FAST)
def _product_tiles3(
    first, last, tile_ptr, starts, values, planes, scale, out, shift, tile, pixels
):  # pragma: no cover - compiled
    """Rows ``i = 16 t + j`` of tiles ``first .. last - 1`` of ``M x`` for three planes.

    ``x[c, i + d]`` is ``planes[c, i + d + margin]``. ``pixels``: ``out`` is ``(N, 3)``
    and gets rows below ``N``; otherwise ``out[c, shift + i] = scale[i] (M x)[c, i]``
    (``scale`` empty: ones; rows past its end, the last tile's padding, get zero).
    ``tile`` is :data:`TILE`, passed as a variable: with a literal trip count the compiler
    unrolls the lane loop instead of vectorising it (five times slower).
    """
    acc = np.zeros((3, 16), np.float32)
    tile = np.uint64(tile)
    for t in range(first, last):
        a = np.uint64(t) * tile
        acc[:] = 0.0
        for k in range(np.uint64(tile_ptr[t]), np.uint64(tile_ptr[t + 1])):
            s = a + starts[k]
            v = values[k]
            for c in range(3):
                plane = planes[c]
                row = acc[c]
                for j in range(tile):
                    row[j] += v[j] * plane[s + j]
        if pixels:
            for j in range(min(tile, np.uint64(out.shape[0]) - a)):
                for c in range(3):
                    out[a + j, c] = acc[c, j]
        else:
            _store(acc, scale, out, a + np.uint64(shift), a, tile)


@numba.njit(**_FAST)
def _product_tiles1(
    first, last, tile_ptr, starts, values, planes, scale, out, shift, tile
):  # pragma: no cover - compiled
    """:func:`_product_tiles3` for one plane (``planes``, ``out``: one row), planar output."""
    acc = np.zeros((1, 16), np.float32)
    tile = np.uint64(tile)
    plane = planes[0]
    row = acc[0]
    for t in range(first, last):
        a = np.uint64(t) * tile
        acc[:] = 0.0
        for k in range(np.uint64(tile_ptr[t]), np.uint64(tile_ptr[t + 1])):
            s = a + starts[k]
            v = values[k]
            for j in range(tile):
                row[j] += v[j] * plane[s + j]
        _store(acc, scale, out, a + np.uint64(shift), a, tile)


@numba.njit(**_FAST, inline="always")
def _store(acc, scale, out, o, a, tile):  # pragma: no cover - compiled
    """``out[c, o + j] = scale[a + j] acc[c, j]`` (zero past ``scale``; no scale if empty)."""
    if scale.size:
        for j in range(tile):
            i = a + j
            w = scale[i] if i < scale.size else np.float32(0.0)
            for c in range(acc.shape[0]):
                out[c, o + j] = w * acc[c, j]
    else:
        for c in range(acc.shape[0]):
            for j in range(tile):
                out[c, o + j] = acc[c, j]


@numba.njit(**_JIT)
def _to_planar_rows(first, last, image, planes, margin):  # pragma: no cover - compiled
    if image.shape[1] == 3:  # a literal channel count lets the loop vectorise
        for i in range(first, last):
            planes[0, margin + i] = image[i, 0]
            planes[1, margin + i] = image[i, 1]
            planes[2, margin + i] = image[i, 2]
        return
    for i in range(first, last):
        for c in range(image.shape[1]):
            planes[c, margin + i] = image[i, c]


@numba.njit(**_JIT)
def _from_planar_rows(first, last, planes, image):  # pragma: no cover - compiled
    for i in range(first, last):
        for c in range(image.shape[1]):
            image[i, c] = planes[c, i]


def _row_ranges(num_rows: int) -> list[tuple[int, int]]:
    parts = 2 * numba.get_num_threads() if num_rows >= 1 << 14 else 1
    bounds = np.linspace(0, num_rows, parts + 1).round().astype(np.int64)
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]


def padded_planes(channels: int, size: int, margin: int) -> np.ndarray:
    """A float32 ``(channels, size + 2 margin)`` array with zero margins (interior unset)."""
    planes = np.empty((channels, size + 2 * margin), np.float32)
    planes[:, :margin] = 0.0
    planes[:, margin + size :] = 0.0
    return planes


def to_planar(image: np.ndarray, margin: int) -> np.ndarray:
    """``(N, C)`` float32 pixels as zero-padded planes ``(C, N + 2 margin)``."""
    planes = padded_planes(image.shape[1], image.shape[0], margin)
    run_ranges(_to_planar_rows, _row_ranges(image.shape[0]), image, planes, margin)
    return planes


def from_planar(planes: np.ndarray, num_rows: int) -> np.ndarray:
    """The first ``num_rows`` columns of ``(C, >= N)`` planes as ``(N, C)`` pixels."""
    image = np.empty((num_rows, planes.shape[0]), np.float32)
    run_ranges(_from_planar_rows, _row_ranges(num_rows), planes, image)
    return image


_NO_SCALE = np.zeros(0, np.float32)


def _tile_ranges(matrix: TiledMatrix) -> list[tuple[int, int]]:
    if matrix.values.size < 1 << 16:
        return [(0, matrix.num_tiles)]
    return balanced_ranges(matrix.tile_ptr, 2 * numba.get_num_threads())


def tiled_product(matrix: TiledMatrix, planes, out, *, shift: int = 0, scale=None) -> None:
    """``out[c, shift + i] = scale[i] (M x)[c, i]``; ``x`` as planes padded by ``matrix.margin``.

    ``out`` needs ``shift + matrix.padded_rows`` columns; the last tile's padding rows
    are written as zeros.
    """
    ranges = _tile_ranges(matrix)
    scale = _NO_SCALE if scale is None else scale
    common = (matrix.tile_ptr, matrix.starts, matrix.values)
    if planes.shape[0] == 3:
        run_ranges(_product_tiles3, ranges, *common, planes, scale, out, shift, TILE, False)
        return
    for c in range(planes.shape[0]):
        plane, target = planes[c : c + 1], out[c : c + 1]
        run_ranges(_product_tiles1, ranges, *common, plane, scale, target, shift, TILE)


def tiled_pixels(matrix: TiledMatrix, planes) -> np.ndarray:
    """``M x`` as ``(N, C)`` pixels; ``x`` as planes padded by ``matrix.margin``."""
    channels = planes.shape[0]
    if channels == 3:
        out = np.empty((matrix.num_rows, 3), np.float32)
        common = (matrix.tile_ptr, matrix.starts, matrix.values, planes, _NO_SCALE)
        run_ranges(_product_tiles3, _tile_ranges(matrix), *common, out, 0, TILE, True)
        return out
    out = np.empty((channels, matrix.padded_rows), np.float32)
    tiled_product(matrix, planes, out)
    if channels == 1:
        return out[0, : matrix.num_rows, None]
    return from_planar(out, matrix.num_rows)
