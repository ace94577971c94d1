"""Row selection between two CSR matrices of one shape (compiled, rows in parallel)."""

from __future__ import annotations

import numba
import numpy as np

from .._threads import balanced_ranges, run_ranges


@numba.njit(cache=True, nogil=True)
def _copy_rows(first, last, take, a_ptr, a_idx, a_val, b_ptr, b_idx, b_val, ptr, idx, val):
    """Rows ``first .. last - 1`` of the merged matrix: ``b``'s where ``take``, else ``a``'s."""
    for r in range(first, last):
        if take[r]:
            lo, hi, src_idx, src_val = b_ptr[r], b_ptr[r + 1], b_idx, b_val
        else:
            lo, hi, src_idx, src_val = a_ptr[r], a_ptr[r + 1], a_idx, a_val
        out = ptr[r]
        for k in range(lo, hi):
            idx[out + k - lo] = src_idx[k]
            val[out + k - lo] = src_val[k]


def select_rows(a, b, take: np.ndarray):
    """Row ``r`` of CSR ``b`` where ``take[r]``, else of ``a``, as scipy's ``(data, indices,
    indptr)`` tuple.

    Index arrays are int32 when the entries fit, int64 otherwise.
    """
    counts = np.where(take, np.diff(b.indptr), np.diff(a.indptr))
    indptr = np.zeros(take.size + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    index_dtype = np.int32 if indptr[-1] < np.iinfo(np.int32).max else np.int64
    indices = np.empty(int(indptr[-1]), np.result_type(a.indices, b.indices))
    data = np.empty(int(indptr[-1]), np.result_type(a.data, b.data))
    parts = 2 * numba.get_num_threads() if indptr[-1] >= 1 << 16 else 1
    arrays = (a.indptr, a.indices, a.data, b.indptr, b.indices, b.data, indptr, indices, data)
    run_ranges(_copy_rows, balanced_ranges(indptr, parts), take, *arrays)
    return data, indices.astype(index_dtype, copy=False), indptr.astype(index_dtype)
