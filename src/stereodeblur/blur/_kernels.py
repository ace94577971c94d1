"""Numba kernels that assemble blur matrices and apply them (the hot path).

All sampling rules (positions, bilinear and cubic taps, snapping, the border rule) come
from :mod:`.trajectories`; this module only accumulates and stores them.

Assembly works item by item: an item is a blurred pixel (homography, gather) or
a source pixel of the extended grid (displacement, splat). Every item's
``num_samples`` positions give at most ``4 * num_samples`` taps (``16 * num_samples``
cubic ones), which are
summed per target pixel in a small dense accumulator over the taps' bounding
box and emitted in increasing target order. Indices are int32, values float32.

Parallelism: every kernel is a serial numba function that releases the GIL
(``nogil``) and works on a contiguous range of rows; a persistent pool of
``numba.get_num_threads()`` Python threads runs several ranges at once and the
results are joined in order. Compared with ``prange`` this compiles several
times faster and, as its idle threads block instead of spinning, it does not
collapse when the machine is oversubscribed (an OpenMP ``prange`` matrix
product can be ten times slower than a serial one on a loaded 2-core machine).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit

from .._threads import balanced_ranges, run_ranges
from .trajectories import (
    clamp,
    displacement_point,
    homography_point,
    keys_weight,
    split_coordinate,
)

_ACCUMULATOR_CELLS = 1 << 16
"""Bounding boxes larger than this (in pixels) fall back to sorting the taps."""

_KIND_HOMOGRAPHY = 0
_KIND_DISPLACEMENT = 1
_MIN_CHUNK = 4096
"""Fewer rows than this per chunk are not worth a thread."""

_JIT = dict(cache=True, nogil=True, error_model="numpy")
_NO_VISIBILITY = np.zeros((1, 1, 0), np.int16)


def _chunks(num_rows: int, per_thread: int = 8) -> list[tuple[int, int]]:
    """Contiguous row ranges, several per thread so that uneven costs balance out."""
    threads = numba.get_num_threads()
    count = max(1, min(per_thread * threads, num_rows // _MIN_CHUNK))
    bounds = np.linspace(0, num_rows, count + 1).round().astype(np.int64)
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def _nnz_ranges(indptr: np.ndarray, parts: int) -> list[tuple[int, int]]:
    """At most ``parts`` contiguous row ranges with about equal numbers of entries."""
    return balanced_ranges(indptr, parts)


@njit(**_JIT)
def _merge_taps(
    px, py, n, drop_outside, height, width, divisor, acc, mark, touched, out_idx, out_val, out_pos
):
    """Sum the bilinear taps of ``n`` positions per pixel; write them sorted; return the count.

    ``px``/``py`` are already clamped when gathering (``drop_outside`` false);
    when splatting, taps outside the image are dropped. Values are divided by
    ``divisor``. Small bounding boxes use a dense accumulator that is cleared
    and scanned whole; larger ones track the touched cells and sort them.
    """
    xmin, xmax = px[:n].min(), px[:n].max()
    ymin, ymax = py[:n].min(), py[:n].max()
    # Taps of a position p lie in [floor(p), floor(p) + 1] (snapping stays inside).
    bx0 = np.int64(np.floor(xmin))
    bx1 = np.int64(np.floor(xmax)) + 1
    by0 = np.int64(np.floor(ymin))
    by1 = np.int64(np.floor(ymax)) + 1
    if bx1 < 0 or by1 < 0 or bx0 >= width or by0 >= height:
        return 0
    bw = bx1 - bx0 + 1
    bh = by1 - by0 + 1
    area = bw * bh
    if area > acc.size:
        return _merge_taps_sorted(
            px, py, n, drop_outside, height, width, divisor, out_idx, out_val, out_pos
        )

    if area <= 8 * n:
        # Dense: every touched cell ends up positive, untouched cells stay zero.
        acc[:area] = 0.0
        for k in range(n):
            x0, fx = split_coordinate(px[k])
            y0, fy = split_coordinate(py[k])
            base = (y0 - by0) * bw + (x0 - bx0)
            gx = 1.0 - fx
            acc[base] += gx * (1.0 - fy)
            if fx > 0.0:
                acc[base + 1] += fx * (1.0 - fy)
            if fy > 0.0:
                acc[base + bw] += gx * fy
                if fx > 0.0:
                    acc[base + bw + 1] += fx * fy
        count = 0
        for ly in range(max(0, -by0), min(bh, height - by0)):
            row = (by0 + ly) * width + bx0
            for lx in range(max(0, -bx0), min(bw, width - bx0)):
                v = acc[ly * bw + lx]
                if v > 0.0:
                    out_idx[out_pos + count] = row + lx
                    out_val[out_pos + count] = v / divisor
                    count += 1
        return count

    # Sparse: visit samples in the direction of travel so `touched` comes out nearly sorted.
    backwards = (py[n - 1] < py[0]) or (py[n - 1] == py[0] and px[n - 1] < px[0])
    nt = 0
    for kk in range(n):
        k = n - 1 - kk if backwards else kk
        x0, fx = split_coordinate(px[k])
        y0, fy = split_coordinate(py[k])
        for t in range(4):
            tx = x0 + (t & 1)
            ty = y0 + (t >> 1)
            wx = fx if (t & 1) else 1.0 - fx
            wy = fy if (t >> 1) else 1.0 - fy
            w = wx * wy
            if w <= 0.0:
                continue
            if drop_outside and (tx < 0 or tx >= width or ty < 0 or ty >= height):
                continue
            local = (ty - by0) * bw + (tx - bx0)
            if mark[local] == 0:
                mark[local] = 1
                touched[nt] = local
                nt += 1
                acc[local] = w
            else:
                acc[local] += w
    # Insertion sort: nearly linear for monotone trajectories.
    for i in range(1, nt):
        v = touched[i]
        j = i - 1
        while j >= 0 and touched[j] > v:
            touched[j + 1] = touched[j]
            j -= 1
        touched[j + 1] = v
    for i in range(nt):
        local = touched[i]
        mark[local] = 0
        gy = by0 + local // bw
        gx = bx0 + local % bw
        out_idx[out_pos + i] = gy * width + gx
        out_val[out_pos + i] = acc[local] / divisor
    return nt


@njit(**_JIT)
def _merge_taps_sorted(px, py, n, drop_outside, height, width, divisor, out_idx, out_val, out_pos):
    """Fallback of :func:`_merge_taps` for huge bounding boxes: sort all taps (insertion sort)."""
    idx = np.empty(4 * n, np.int64)
    val = np.empty(4 * n, np.float64)
    m = 0
    for k in range(n):
        x0, fx = split_coordinate(px[k])
        y0, fy = split_coordinate(py[k])
        for t in range(4):
            tx = x0 + (t & 1)
            ty = y0 + (t >> 1)
            wx = fx if (t & 1) else 1.0 - fx
            wy = fy if (t >> 1) else 1.0 - fy
            w = wx * wy
            if w <= 0.0:
                continue
            if drop_outside and (tx < 0 or tx >= width or ty < 0 or ty >= height):
                continue
            g = ty * width + tx
            j = m - 1
            while j >= 0 and idx[j] > g:
                idx[j + 1] = idx[j]
                val[j + 1] = val[j]
                j -= 1
            idx[j + 1] = g
            val[j + 1] = w
            m += 1
    count = 0
    i = 0
    while i < m:
        g = idx[i]
        total = 0.0
        while i < m and idx[i] == g:
            total += val[i]
            i += 1
        out_idx[out_pos + count] = g
        out_val[out_pos + count] = total / divisor
        count += 1
    return count


@njit(inline="always", **_JIT)
def _cubic_sample_taps(x, y, height, width, drop_outside, tx, ty, tw):
    """The non-zero Keys taps of the position ``(x, y)`` into ``tx``, ``ty``, ``tw`` (at most
    16, row by row); returns their count. Taps outside the image are clamped to it when
    gathering and dropped when splatting."""
    x0, fx = split_coordinate(x)
    y0, fy = split_coordinate(y)
    m = 0
    for dy in range(-1, 3):
        wy = keys_weight(fy - dy)
        row = y0 + dy
        if wy == 0.0 or (drop_outside and not 0 <= row < height):
            continue
        row = min(max(row, 0), height - 1)
        for dx in range(-1, 3):
            w = wy * keys_weight(fx - dx)
            col = x0 + dx
            if w == 0.0 or (drop_outside and not 0 <= col < width):
                continue
            tx[m] = min(max(col, 0), width - 1)
            ty[m] = row
            tw[m] = w
            m += 1
    return m


@njit(**_JIT)
def _merge_cubic_taps(
    px, py, n, drop_outside, height, width, divisor, acc, taps, out_idx, out_val, out_pos
):
    """:func:`_merge_taps` with Keys' cubic taps (:func:`_cubic_sample_taps`); ``taps``:
    scratch ``(tx, ty, tw)`` for ``16 * n`` of them (and, summing in place, for one position's
    four column weights and columns).

    The accumulator is cleared over the bounding box and summed into position by position
    (the column weights computed once per position), in the order of
    :func:`_cubic_sample_taps`; a cell whose sum is exactly zero (the weights can be
    negative), or which no tap reaches, is dropped. Bounding boxes larger than the
    accumulator sort all taps instead.
    """
    # Taps of a position p lie in [floor(p) - 1, floor(p) + 2]; those in the image count.
    bx0 = max(np.int64(np.floor(px[:n].min())) - 1, 0)
    bx1 = min(np.int64(np.floor(px[:n].max())) + 2, width - 1)
    by0 = max(np.int64(np.floor(py[:n].min())) - 1, 0)
    by1 = min(np.int64(np.floor(py[:n].max())) + 2, height - 1)
    if bx1 < bx0 or by1 < by0:
        return 0
    bw = bx1 - bx0 + 1
    area = bw * (by1 - by0 + 1)
    tx, ty, tw = taps
    if area > acc.size:
        m = 0
        for k in range(n):
            m += _cubic_sample_taps(
                px[k], py[k], height, width, drop_outside, tx[m:], ty[m:], tw[m:]
            )
        flat = ty[:m] * width + tx[:m]
        order = np.argsort(flat, kind="mergesort")  # stable: sums in sample order
        count = 0
        i = 0
        while i < m:
            g = flat[order[i]]
            total = 0.0
            while i < m and flat[order[i]] == g:
                total += tw[order[i]]
                i += 1
            if total != 0.0:
                out_idx[out_pos + count] = g
                out_val[out_pos + count] = total / divisor
                count += 1
        return count
    acc[:area] = 0.0  # a cell no tap reaches stays 0 and is dropped, as a zero sum is
    wx, cols = tw[:4], tx[:4]  # one position's column weights and columns (scratch)
    for k in range(n):
        x0, fx = split_coordinate(px[k])
        y0, fy = split_coordinate(py[k])
        for dx in range(-1, 3):  # the column weights once per position
            wx[dx + 1] = keys_weight(fx - dx)
            col = x0 + dx
            if drop_outside and not 0 <= col < width:
                wx[dx + 1] = 0.0
            cols[dx + 1] = min(max(col, 0), width - 1) - bx0
        for dy in range(-1, 3):
            wy = keys_weight(fy - dy)
            row = y0 + dy
            if wy == 0.0 or (drop_outside and not 0 <= row < height):
                continue
            base = (min(max(row, 0), height - 1) - by0) * bw
            for c in range(4):
                if wx[c] != 0.0:
                    acc[base + cols[c]] += wy * wx[c]
    count = 0
    local = 0
    for row in range(by0, by1 + 1):
        first = row * width + bx0
        for c in range(bw):
            if acc[local] != 0.0:
                out_idx[out_pos + count] = first + c
                out_val[out_pos + count] = acc[local] / divisor
                count += 1
            local += 1
    return count


@njit(**_JIT)
def _item_positions(
    kind, item, px, py, homographies, labels, visible, item_x, item_y, item_src, flows, fractions
):
    """Fill ``px``/``py`` with the sample positions of one item (see trajectories).

    With per-instant ``visible`` segments (homography kernels, :mod:`.visibility`) every
    instant samples the segment visible then; where that is a surface hidden at the
    reference instant (label < 0), the pixel's own segment stands in.
    """
    height, width = labels.shape
    n = px.size
    if kind == _KIND_HOMOGRAPHY:
        y = item // width
        x = item - y * width
        own = labels[y, x]
        layered = visible.shape[2] == n
        for k in range(n):
            lab = own
            if layered and visible[y, x, k] >= 0:
                lab = visible[y, x, k]
            qx, qy = homography_point(homographies, lab, k, float(x), float(y))
            px[k] = clamp(qx, width - 1)
            py[k] = clamp(qy, height - 1)
        return
    src = item_src[item]
    sy = src // width
    sx = src - sy * width
    fu = flows[0, sy, sx, 0]
    fv = flows[0, sy, sx, 1]
    bu = flows[1, sy, sx, 0]
    bv = flows[1, sy, sx, 1]
    x = float(item_x[item])
    y = float(item_y[item])
    for k in range(n):
        px[k], py[k] = displacement_point(x, y, fractions[k], fu, fv, bu, bv)


@njit(**_JIT)
def _grow(out_idx, out_val, pos, needed):
    """The output arrays with room for ``needed`` more entries after ``pos`` (doubled)."""
    capacity = out_idx.size
    while pos + needed > capacity:
        capacity = 2 * capacity
    if capacity == out_idx.size:
        return out_idx, out_val
    grown_idx = np.empty(capacity, np.int32)
    grown_idx[:pos] = out_idx[:pos]
    grown_val = np.empty(capacity, np.float32)
    grown_val[:pos] = out_val[:pos]
    return grown_idx, grown_val


@njit(**_JIT)
def _reaches(px, py, n, table, height, width, cubic):
    """Whether a tap of the ``n`` positions can fall on a pixel counted in ``table``.

    ``table`` is the summed-area table ``(H + 1, W + 1)`` of the pixels wanted; taps of a
    position ``p`` lie in ``[floor(p), floor(p) + 1]`` (as in :func:`_merge_taps`), cubic
    ones in ``[floor(p) - 1, floor(p) + 2]``.
    """
    low, high = (1, 2) if cubic else (0, 1)
    bx0 = max(np.int64(np.floor(px[:n].min())) - low, 0)
    bx1 = min(np.int64(np.floor(px[:n].max())) + high, width - 1)
    by0 = max(np.int64(np.floor(py[:n].min())) - low, 0)
    by1 = min(np.int64(np.floor(py[:n].max())) + high, height - 1)
    if bx0 > bx1 or by0 > by1:
        return False
    inside = table[by1 + 1, bx1 + 1] - table[by0, bx1 + 1] - table[by1 + 1, bx0] + table[by0, bx0]
    return inside > 0


@njit(**_JIT)
def _copy_row(item, indptr, indices, values, out_idx, out_val, pos):
    """Row ``item`` of a CSR matrix appended at ``pos``: ``(out_idx, out_val, count)``."""
    a = indptr[item]
    c = indptr[item + 1] - a
    out_idx, out_val = _grow(out_idx, out_val, pos, c)
    out_idx[pos : pos + c] = indices[a : a + c]
    out_val[pos : pos + c] = values[a : a + c]
    return out_idx, out_val, c


@njit(**_JIT)
def _assemble_range(
    first,
    last,
    kind,
    homographies,
    labels,
    visible,
    item_x,
    item_y,
    item_src,
    flows,
    fractions,
    select,
    cubic,
):
    """Taps of items ``first .. last - 1``: ``(counts int64, indices int32, values float32)``.

    ``cubic``: Keys' cubic taps instead of bilinear ones.

    ``select = (take, other_indptr, other_indices, other_values, table)``: items with
    ``take[item]`` copy row ``item`` of the other CSR matrix instead of computing theirs;
    with a summed-area ``table`` (not ``(1, 1)``), items none of whose taps can reach a
    pixel it counts get no entries. Empty ``take`` and a ``(1, 1)`` table: every item's taps.
    """
    take, other_indptr, other_indices, other_values, table = select
    height, width = labels.shape
    n = fractions.size
    drop_outside = kind == _KIND_DISPLACEMENT
    divisor = float(n) if kind == _KIND_HOMOGRAPHY else 1.0
    some_taken = take.size > 0
    restricted = table.shape[0] > 1
    acc = np.empty(_ACCUMULATOR_CELLS, np.float64)
    mark = np.zeros(_ACCUMULATOR_CELLS, np.uint8)
    touched = np.empty(4 * n, np.int64)
    taps = (np.empty(16 * n, np.int64), np.empty(16 * n, np.int64), np.empty(16 * n, np.float64))
    px = np.empty(n, np.float64)
    py = np.empty(n, np.float64)
    counts = np.empty(last - first, np.int64)
    capacity = max(16 * (last - first), 8 * n)
    out_idx = np.empty(capacity, np.int32)
    out_val = np.empty(capacity, np.float32)
    pos = np.int64(0)  # not a literal: one compiled version of the callees
    for item in range(first, last):
        if some_taken and take[item]:
            out_idx, out_val, c = _copy_row(
                item, other_indptr, other_indices, other_values, out_idx, out_val, pos
            )
        else:
            out_idx, out_val = _grow(out_idx, out_val, pos, (16 if cubic else 4) * n)
            _item_positions(
                kind,
                item,
                px,
                py,
                homographies,
                labels,
                visible,
                item_x,
                item_y,
                item_src,
                flows,
                fractions,
            )
            if restricted and not _reaches(px, py, n, table, height, width, cubic):
                c = 0
            elif cubic:
                c = _merge_cubic_taps(
                    px, py, n, drop_outside, height, width, divisor, acc, taps, out_idx, out_val,
                    pos,
                )  # fmt: skip
            else:
                c = _merge_taps(
                    px, py, n, drop_outside, height, width, divisor, acc, mark, touched, out_idx,
                    out_val, pos,
                )  # fmt: skip
        counts[item - first] = c
        pos += c
    return counts, out_idx[:pos], out_val[:pos]


_SELECT_ALL = (
    np.zeros(0, np.bool_),
    np.zeros(1, np.int64),
    np.zeros(0, np.int32),
    np.zeros(0, np.float32),
    np.zeros((1, 1), np.int64),
)


def _assemble(
    kind,
    num_items,
    homographies,
    labels,
    visible,
    item_x,
    item_y,
    item_src,
    flows,
    fractions,
    select=_SELECT_ALL,
    cubic=False,
):
    """CSR arrays ``(indptr int64, indices int32, values float32)`` of all items' taps."""
    parts = run_ranges(
        _assemble_range,
        _chunks(num_items),
        kind,
        homographies,
        labels,
        visible,
        item_x,
        item_y,
        item_src,
        flows,
        fractions,
        select,
        cubic,
    )
    indptr = np.zeros(num_items + 1, np.int64)
    np.cumsum(np.concatenate([p[0] for p in parts]), out=indptr[1:])
    indices = np.empty(indptr[-1], np.int32)
    values = np.empty(indptr[-1], np.float32)
    position = 0
    for i in range(len(parts)):  # copy and free one part at a time
        _, part_indices, part_values = parts[i]
        parts[i] = None
        indices[position : position + part_indices.size] = part_indices
        values[position : position + part_values.size] = part_values
        position += part_indices.size
        del part_indices, part_values
    return indptr, indices, values


def assemble_homography(
    homographies: np.ndarray,
    labels: np.ndarray,
    num_samples: int,
    visible=None,
    substitute=None,
    *,
    cubic: bool = False,
):
    """CSR arrays of the homography operator (rows already divided by ``num_samples``).

    ``cubic``: Keys' cubic taps instead of bilinear ones (:mod:`.trajectories`).
    ``visible`` (int16 or int32 ``(num_samples, H, W)``) gives the segment of every pixel at
    every instant (:mod:`.visibility`); None: ``labels`` throughout. ``substitute``:
    ``(take, indptr, indices, values)``, a bool mask over the pixels and a CSR matrix (int32
    indices, float32 values) whose rows the pixels of the mask take instead of theirs.
    """
    dummy = np.zeros(1, np.int32)
    flows = np.zeros((2, 1, 1, 2), np.float64)
    fractions = np.zeros(num_samples, np.float64)
    if visible is None:
        visible = _NO_VISIBILITY
    else:  # each pixel's instants side by side: one cache line per pixel, not one per instant
        visible = np.ascontiguousarray(np.moveaxis(visible, 0, -1))
    select = _SELECT_ALL
    if substitute is not None:
        take, indptr, indices, values = substitute
        select = (
            np.ascontiguousarray(take, dtype=np.bool_).ravel(),
            np.asarray(indptr, dtype=np.int64),
            np.asarray(indices, dtype=np.int32),
            np.asarray(values, dtype=np.float32),
            _SELECT_ALL[4],
        )
    return _assemble(
        _KIND_HOMOGRAPHY,
        labels.size,
        homographies,
        labels,
        visible,
        dummy,
        dummy,
        dummy,
        flows,
        fractions,
        select,
        bool(cubic),
    )


def summed_area(mask: np.ndarray) -> np.ndarray:
    """Summed-area table ``(H + 1, W + 1)`` int64 of a bool ``(H, W)`` mask."""
    table = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), np.int64)
    np.cumsum(np.cumsum(mask, axis=0, dtype=np.int64), axis=1, out=table[1:, 1:])
    return table


def assemble_splats(
    labels_shape: tuple[int, int],
    item_x: np.ndarray,
    item_y: np.ndarray,
    item_src: np.ndarray,
    flows: np.ndarray,
    fractions: np.ndarray,
    rows=None,
    *,
    cubic: bool = False,
):
    """Per source item, the summed splat weights onto blurred pixels (CSR arrays).

    ``cubic``: Keys' cubic taps instead of bilinear ones (:mod:`.trajectories`).
    ``rows`` (bool ``labels_shape``): only the items some of whose taps can fall on these
    blurred pixels are splatted (the others get no entries), so the splats onto them are
    complete and those onto other pixels are not.
    """
    homographies = np.zeros((1, 1, 3, 3), np.float64)
    labels = np.zeros(labels_shape, np.int32)
    select = _SELECT_ALL
    if rows is not None:
        select = _SELECT_ALL[:4] + (summed_area(np.asarray(rows, dtype=bool)),)
    return _assemble(
        _KIND_DISPLACEMENT,
        item_x.size,
        homographies,
        labels,
        _NO_VISIBILITY,
        item_x,
        item_y,
        item_src,
        flows,
        fractions,
        select,
        bool(cubic),
    )


@njit(**_JIT)
def _count_columns(first, last, indptr, indices, counts):
    """``counts[c]`` = entries of column ``c`` in rows ``first .. last - 1``."""
    counts[:] = 0
    for k in range(indptr[first], indptr[last]):
        counts[indices[k]] += 1


@njit(**_JIT)
def _column_positions(counts):
    """Turn per-chunk column counts (chunks, cols) into write positions in place; return indptr."""
    num_chunks, num_cols = counts.shape
    indptr = np.empty(num_cols + 1, np.int64)
    running = 0
    for c in range(num_cols):
        indptr[c] = running
        for t in range(num_chunks):
            n = counts[t, c]
            counts[t, c] = running
            running += n
    indptr[num_cols] = running
    return indptr


@njit(**_JIT)
def _scatter_columns(first, last, indptr, indices, data, row_label, position, out_idx, out_val):
    """Write the entries of rows ``first .. last - 1`` into their columns' output rows."""
    for r in range(first, last):
        label = row_label[r]
        for k in range(indptr[r], indptr[r + 1]):
            c = indices[k]
            p = position[c]
            out_idx[p] = label
            out_val[p] = data[k]
            position[c] = p + 1


def transpose(indptr, indices, data, num_cols, row_label=None):
    """CSR arrays ``(indptr int64, indices, data)`` of the transpose of a CSR matrix.

    Entry ``(r, c, v)`` becomes ``(c, row_label[r], v)`` (``row_label`` defaults to
    ``r``). Within every output row the entries keep the order of ``r``: each chunk
    of rows counts its entries per column, which gives every chunk its own write
    positions, then the chunks scatter independently.
    """
    indptr = np.asarray(indptr, dtype=np.int64)
    num_rows = indptr.size - 1
    if row_label is None:
        row_label = np.arange(num_rows, dtype=indices.dtype)
    nnz = int(indptr[-1])
    # One chunk per thread (each needs a count array over the columns), of about equal nnz.
    parts = numba.get_num_threads() if nnz >= _MIN_CHUNK * 16 else 1
    ranges = _nnz_ranges(indptr, parts)
    counts = np.empty((len(ranges), num_cols), np.int64)
    run_ranges(
        lambda a, b: _count_columns(a, b, indptr, indices, counts[_index(ranges, a)]), ranges
    )
    out_indptr = _column_positions(counts)
    out_idx = np.empty(nnz, row_label.dtype)
    out_val = np.empty(nnz, data.dtype)
    run_ranges(
        lambda a, b: _scatter_columns(
            a, b, indptr, indices, data, row_label, counts[_index(ranges, a)], out_idx, out_val
        ),
        ranges,
    )
    return out_indptr, out_idx, out_val


def _index(ranges, first: int) -> int:
    return [r[0] for r in ranges].index(first)


@njit(**_JIT)
def _merge_rows(first, last, indptr, indices, values, merged_col, merged_val, unique, totals):
    """Merge adjacent duplicate columns of rows ``first .. last - 1``; their counts and sums.

    ``merged_*`` may be ``indices``/``values`` themselves: writes never overtake reads.
    """
    for z in range(first, last):
        a = indptr[z]
        b = indptr[z + 1]
        total = 0.0
        m = 0
        k = a
        while k < b:
            col = indices[k]
            v = 0.0
            while k < b and indices[k] == col:
                v += values[k]
                k += 1
            merged_col[a + m] = col
            merged_val[a + m] = v
            total += v
            m += 1
        totals[z] = total
        unique[z] = m


@njit(**_JIT)
def _write_normalised(
    first, last, indptr, merged_col, merged_val, totals, min_total, out_indptr, out_idx, out_val
):
    """Rows ``first .. last - 1`` divided by their sums, or identity rows below ``min_total``
    (rows given no room in ``out_indptr`` stay empty)."""
    for z in range(first, last):
        p = out_indptr[z]
        if p == out_indptr[z + 1]:
            continue
        if totals[z] >= min_total:
            a = indptr[z]
            for i in range(out_indptr[z + 1] - p):
                out_idx[p + i] = merged_col[a + i]
                out_val[p + i] = merged_val[a + i] / totals[z]
        else:
            out_idx[p] = z
            out_val[p] = 1.0


def normalise_rows(indptr, indices, values, min_total, rows=None):
    """Rows divided by their sums; rows summing to less than ``min_total`` become identity rows.

    Columns must be non-decreasing within each row; duplicates are merged. The
    merge happens in place in ``indices`` and ``values``, which are overwritten.
    ``rows`` (bool, one per row): only these rows are kept, the others come out empty.
    """
    num_rows = indptr.size - 1
    unique = np.empty(num_rows, np.int64)
    totals = np.empty(num_rows, np.float64)
    ranges = _chunks(num_rows)
    run_ranges(_merge_rows, ranges, indptr, indices, values, indices, values, unique, totals)
    covered = totals >= min_total
    counts = np.where(covered, unique, 1)
    if rows is not None:
        counts[~np.asarray(rows, dtype=bool).ravel()] = 0
    out_indptr = np.zeros(num_rows + 1, np.int64)
    np.cumsum(counts, out=out_indptr[1:])
    out_idx = np.empty(out_indptr[-1], np.int32)
    out_val = np.empty(out_indptr[-1], np.float32)
    run_ranges(
        _write_normalised,
        ranges,
        indptr,
        indices,
        values,
        totals,
        float(min_total),
        out_indptr,
        out_idx,
        out_val,
    )
    return out_indptr, out_idx, out_val


@njit(**_JIT)
def _matmat_rows(first, last, indptr, indices, data, x, out):
    """Rows ``first .. last - 1`` of ``out = A @ x``, accumulated in float64.

    ``indices`` is read as unsigned (``uint32`` view of the int32 column indices) and ``x``,
    ``out`` flat: numba then emits no negative-index wraparound in the inner loop, which
    makes the product about a third faster.
    """
    channels = np.uint64(x.shape[1])
    xf = x.ravel()
    of = out.ravel()
    one = np.uint64(1)
    two = np.uint64(2)
    if channels == 3:
        for r in range(first, last):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for k in range(np.uint64(indptr[r]), np.uint64(indptr[r + 1])):
                c = np.uint64(indices[k]) * channels
                w = np.float64(data[k])
                a0 += w * xf[c]
                a1 += w * xf[c + one]
                a2 += w * xf[c + two]
            o = np.uint64(r) * channels
            of[o] = a0
            of[o + one] = a1
            of[o + two] = a2
    else:
        for r in range(first, last):
            for ch in range(channels):
                a = 0.0
                for k in range(np.uint64(indptr[r]), np.uint64(indptr[r + 1])):
                    a += np.float64(data[k]) * xf[np.uint64(indices[k]) * channels + ch]
                of[np.uint64(r) * channels + ch] = a


def csr_matmat(indptr, indices, data, x, out) -> None:
    """``out = A @ x`` for CSR ``A`` and C-contiguous ``x`` (n, C), ``out`` (m, C).

    Rows are split into ranges of about equal work, two per thread; small
    products run in the calling thread.
    """
    work = int(indptr[-1]) * x.shape[1]
    parts = 2 * numba.get_num_threads() if work >= 64 * _MIN_CHUNK else 1
    columns = indices.view(np.uint32)
    run_ranges(_matmat_rows, _nnz_ranges(indptr, parts), indptr, columns, data, x, out)
