"""The 2D-displacement blur operator, the baseline after Kim & Lee (CVPR 2015).

As the paper describes it (supplement Fig. 11): the content of every source
pixel ``y`` moves on a straight line with constant velocity during the
exposure, ``y + s * flow_forward(y)`` for instants ``s >= 0`` and
``y + |s| * flow_backward(y)`` for ``s < 0``. Kernels are formed by forward
warping: at every instant the content of ``y`` is splatted bilinearly onto the
four pixels around its position (or by Keys' cubic weights onto sixteen), so the
kernel of blurred pixel ``z`` collects the pixels whose trajectories pass through
``z``. Every row is then normalised to sum to one.

Instants, positions, bilinear weights and the border rule (source pixels of an
extended grid carry the flow and content of the nearest in-image pixel) are
those of :mod:`.trajectories`, shared with :mod:`.homography`.

Coverage rule: a blurred pixel whose total splatted weight is below
``MIN_COVERAGE * num_samples`` (where a locally translating flow gives exactly
``num_samples``) receives essentially no content: its row is the identity.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..geometry.camera import Exposure
from ..settings import DEFAULT_INTERPOLATION, NUM_SAMPLES
from . import _kernels
from .homography import _check_num_samples, csr_from_arrays
from .operator import SparseBlur
from .trajectories import (
    bilinear_taps,
    cubic_taps,
    displacement_margin,
    displacement_positions,
    extended_grid,
    is_cubic,
)

MIN_COVERAGE = 1e-3
"""Rows receiving less than this fraction of one full sample set become the identity."""


def _check_flow(flow, name: str) -> np.ndarray:
    flow = np.asarray(flow)
    if flow.ndim != 3 or flow.shape[2] != 2 or not np.issubdtype(flow.dtype, np.number):
        raise InputError(f"{name} must be a numeric (H, W, 2) array, got shape {flow.shape}")
    if not np.all(np.isfinite(flow)):
        raise InputError(
            f"{name} must be finite, got {np.count_nonzero(~np.isfinite(flow))} non-finite values"
        )
    return flow.astype(np.float64)


def _inputs(flow_forward, flow_backward, exposure: Exposure, num_samples, cubic):
    forward = _check_flow(flow_forward, "flow_forward")
    backward = _check_flow(flow_backward, "flow_backward")
    if forward.shape != backward.shape:
        raise InputError(
            f"flow_forward has shape {forward.shape} but flow_backward {backward.shape}"
        )
    num_samples = _check_num_samples(num_samples)
    fractions = exposure.sample_fractions(num_samples).astype(np.float64)
    margin = displacement_margin(forward, backward, fractions, cubic=cubic)
    return forward, backward, fractions, margin


def displacement_blur(
    flow_forward: np.ndarray,
    flow_backward: np.ndarray,
    exposure: Exposure,
    *,
    num_samples: int = NUM_SAMPLES,
    rows: np.ndarray | None = None,
    interpolation: str = DEFAULT_INTERPOLATION,
) -> SparseBlur:
    """Blur operator from 2D displacements by forward warping (Kim & Lee 2015).

    Parameters
    ----------
    flow_forward : ndarray, shape (H, W, 2)
        Flow ``(u, v)`` from the centre of this frame to the next one, pixels.
    flow_backward : ndarray, shape (H, W, 2)
        Flow from this frame to the previous one; pass ``-flow_forward`` when
        only two frames exist.
    exposure : Exposure
        Frame rate and exposure time; the instants are ``exposure.sample_fractions``.
    num_samples : int, optional
        Number ``N`` of instants (paper: ``N = 70``).
    rows : ndarray of bool, shape (H, W), optional
        Build only the rows of these blurred pixels (equal to the full operator's); the
        other rows are empty. Default: all rows.
    interpolation : {'bilinear', 'cubic'}, optional
        How the content is splatted: bilinearly onto four pixels or by Keys' cubic weights
        onto sixteen (:mod:`.trajectories`). Default:
        ``settings.DEFAULT_INTERPOLATION`` (``'cubic'``), as
        :class:`~stereodeblur.settings.DeblurSettings` and the command line.

    Returns
    -------
    SparseBlur
        Rows: blurred pixels; columns: pixels of the sharp image. Every row (of ``rows``)
        sums to one.
    """
    cubic = is_cubic(interpolation)
    forward, backward, fractions, margin = _inputs(
        flow_forward, flow_backward, exposure, num_samples, cubic
    )
    shape = forward.shape[:2]
    if rows is not None:
        rows = np.asarray(rows)
        if rows.shape != shape or rows.dtype != bool:
            raise InputError(f"rows must be a bool array of shape {shape}, got {rows.shape}")
    item_x, item_y, item_src = extended_grid(shape, margin)
    flows = np.ascontiguousarray(np.stack([forward, backward]))
    splats = _kernels.assemble_splats(
        shape, item_x, item_y, item_src, flows, fractions, rows, cubic=cubic
    )
    size = shape[0] * shape[1]
    # Source-major splats -> rows of blurred pixels; columns come out sorted since
    # the extended pixels are ordered by the in-image pixel they stand for.
    by_row = _kernels.transpose(*splats, size, row_label=item_src)
    del splats
    indptr, indices, data = _kernels.normalise_rows(*by_row, MIN_COVERAGE * fractions.size, rows)
    del by_row
    return SparseBlur(csr_from_arrays(indptr, indices, data, size), shape)


def displacement_blur_reference(
    flow_forward: np.ndarray,
    flow_backward: np.ndarray,
    exposure: Exposure,
    *,
    num_samples: int = NUM_SAMPLES,
    interpolation: str = DEFAULT_INTERPOLATION,
) -> SparseBlur:
    """Pure-numpy, slow construction of the same operator as :func:`displacement_blur`.

    Used by the tests to check the fast assembly.
    """
    cubic = is_cubic(interpolation)
    forward, backward, fractions, margin = _inputs(
        flow_forward, flow_backward, exposure, num_samples, cubic
    )
    shape = forward.shape[:2]
    size = shape[0] * shape[1]
    x, y, source = extended_grid(shape, margin)
    sy, sx = np.divmod(source, shape[1])
    positions = displacement_positions(x, y, forward[sy, sx], backward[sy, sx], fractions)
    taps = cubic_taps if cubic else bilinear_taps
    dest, weight, valid = taps(positions, shape, border="drop")
    cols = np.broadcast_to(source[:, None, None], dest.shape)
    splat = sp.coo_matrix((weight[valid], (dest[valid], cols[valid])), shape=(size, size)).tocsr()
    splat.sum_duplicates()
    totals = np.asarray(splat.sum(axis=1)).ravel()
    covered = totals >= MIN_COVERAGE * fractions.size
    scale = sp.diags(np.where(covered, 1.0 / np.where(covered, totals, 1.0), 0.0))
    identity = sp.diags((~covered).astype(np.float64))
    matrix = (scale @ splat + identity).tocsr()
    matrix.eliminate_zeros()
    matrix.sort_indices()
    matrix.data = matrix.data.astype(np.float32)
    return SparseBlur(matrix, shape)
