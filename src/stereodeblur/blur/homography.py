"""The homography-induced blur operator of piecewise-rigid scene flow (paper Sec. 3).

Row ``x`` of the operator is the discretised exposure integral of Eq. 3-4:
the mean over the ``N`` instants ``t`` of the sharp reference image, interpolated
(bilinear as in the paper, or cubic) at ``H_ref_from_t[label(x), t] @ x``; with
per-instant segments (:mod:`.visibility`), ``label(x)`` is the segment the pixel shows at
``t``. Sample instants, positions, interpolation weights and the border rule (clamp to the
image, i.e. replicate edge content) are those of :mod:`.trajectories`; duplicate taps are
summed.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..geometry.camera import Exposure
from ..sceneflow.model import SceneFlow
from ..settings import DEFAULT_INTERPOLATION, NUM_SAMPLES
from . import _kernels
from .operator import SparseBlur
from .trajectories import bilinear_taps, cubic_taps, homography_positions, is_cubic


def _check_num_samples(num_samples) -> int:
    if isinstance(num_samples, bool) or not isinstance(num_samples, int | np.integer):
        raise ValueError(f"num_samples must be an integer >= 1, got {num_samples!r}")
    if num_samples < 1:
        raise ValueError(f"num_samples must be an integer >= 1, got {num_samples}")
    return int(num_samples)


def _check_visible(visible, num_samples: int, shape, num_segments: int) -> np.ndarray:
    """``visible`` as a contiguous int16 / int32 array, after checking shape and labels."""
    visible = np.asarray(visible)
    if visible.shape != (num_samples,) + tuple(shape):
        raise ValueError(f"visible has shape {visible.shape}, expected {(num_samples,) + shape}")
    if not np.issubdtype(visible.dtype, np.integer) or (
        visible.size and (visible.min() < -1 or visible.max() >= num_segments)
    ):
        raise ValueError(f"visible must hold segment labels in [-1, {num_segments})")
    dtype = np.int16 if num_segments <= np.iinfo(np.int16).max else np.int32
    return np.ascontiguousarray(visible, dtype=dtype)


def _check_substitute(substitute, shape) -> tuple:
    """``(mask, indptr, indices, values)`` of ``(operator, mask)`` after checking shapes."""
    other, mask = substitute
    mask = np.asarray(mask)
    if not isinstance(other, SparseBlur) or other.shape != tuple(shape):
        raise ValueError(f"substitute must hold a SparseBlur of shape {tuple(shape)}")
    if mask.shape != tuple(shape) or mask.dtype != bool:
        raise ValueError(f"the substitute's mask must be bool of shape {tuple(shape)}")
    matrix = other.matrix
    return mask, matrix.indptr, matrix.indices, matrix.data.astype(np.float32, copy=False)


def csr_from_arrays(indptr, indices, data, size: int) -> sp.csr_matrix:
    """A ``size x size`` CSR matrix, with int32 index arrays when they fit."""
    if indptr[-1] < np.iinfo(np.int32).max:
        indptr = indptr.astype(np.int32)
    else:
        indices = indices.astype(np.int64)
    matrix = sp.csr_matrix((data, indices, indptr), shape=(size, size))
    matrix.has_sorted_indices = True
    return matrix


def _inputs(sceneflow: SceneFlow, exposure: Exposure, num_samples, offset: float) -> tuple:
    num_samples = _check_num_samples(num_samples)
    fractions = offset + exposure.sample_fractions(num_samples)
    homographies = np.ascontiguousarray(sceneflow.homographies(fractions), dtype=np.float64)
    labels = np.ascontiguousarray(sceneflow.labels, dtype=np.int32)
    return homographies, labels, num_samples


def homography_blur(
    sceneflow: SceneFlow,
    exposure: Exposure,
    *,
    num_samples: int = NUM_SAMPLES,
    visible=None,
    substitute: tuple[SparseBlur, np.ndarray] | None = None,
    interpolation: str = DEFAULT_INTERPOLATION,
    offset: float = 0.0,
) -> SparseBlur:
    """Blur operator of the reference view of ``sceneflow`` (paper Eq. 3-4).

    Parameters
    ----------
    sceneflow : SceneFlow
        Labels, planes and motions over the reference view (``sceneflow.view``).
    exposure : Exposure
        Frame rate and exposure time; the instants are ``exposure.sample_fractions``.
    num_samples : int, optional
        Number ``N`` of instants in the exposure integral (paper: ``N = 70``).
    visible : ndarray of int, shape (N, H, W), optional
        The segment each pixel shows at each instant
        (:func:`~stereodeblur.blur.visibility.sceneflow_visibility`); where it is
        :data:`~stereodeblur.blur.visibility.HIDDEN`, the pixel's own segment stands in.
        None (the paper's Eq. 3-4): every pixel shows its own segment throughout.
    substitute : (SparseBlur, ndarray of bool (H, W)), optional
        Another operator over the view and a mask: the pixels of the mask take that
        operator's rows, which are not computed here
        (:func:`~stereodeblur.blur.operator.merge_rows` of the two, built once).
    interpolation : {'bilinear', 'cubic'}, optional
        How the sharp image is sampled at the positions: bilinear (the paper) or Keys'
        cubic convolution (:mod:`.trajectories`; about 2.5x the entries). Default:
        ``settings.DEFAULT_INTERPOLATION`` (``'cubic'``), as
        :class:`~stereodeblur.settings.DeblurSettings` and the command line.
    offset : float, optional
        Frame intervals between the reference instant and the exposure's centre: with
        ``offset = 1`` the rows are the next frame's blurred pixels, gathered from the
        reference frame's sharp image (``sceneflow.labels`` then the segments the next frame
        shows, its planes and motions the reference frame's).

    Returns
    -------
    SparseBlur
        Rows: blurred pixels; columns: pixels of the sharp reference image.
        Every row sums to one.
    """
    cubic = is_cubic(interpolation)
    homographies, labels, num_samples = _inputs(sceneflow, exposure, num_samples, offset)
    if visible is not None:
        visible = _check_visible(visible, num_samples, labels.shape, homographies.shape[0])
    if substitute is not None:
        substitute = _check_substitute(substitute, labels.shape)
    indptr, indices, data = _kernels.assemble_homography(
        homographies, labels, num_samples, visible, substitute, cubic=cubic
    )
    matrix = csr_from_arrays(indptr, indices, data, labels.size)
    return SparseBlur(matrix, tuple(labels.shape))


def homography_blur_reference(
    sceneflow: SceneFlow,
    exposure: Exposure,
    *,
    num_samples: int = NUM_SAMPLES,
    visible=None,
    interpolation: str = DEFAULT_INTERPOLATION,
    offset: float = 0.0,
) -> SparseBlur:
    """Pure-numpy, slow construction of the same operator as :func:`homography_blur`.

    Used by the tests to check the fast assembly; it takes its positions and
    weights from the vectorised forms in :mod:`.trajectories`.
    """
    homographies, labels, num_samples = _inputs(sceneflow, exposure, num_samples, offset)
    size = labels.size
    if visible is not None:
        labels = np.moveaxis(np.where(visible >= 0, visible, labels), 0, -1)
    positions = homography_positions(homographies, labels).reshape(size, num_samples, 2)
    if is_cubic(interpolation):
        index, weight, valid = cubic_taps(positions, sceneflow.shape, border="clamp")
    else:
        index, weight, valid = bilinear_taps(positions, sceneflow.shape, border="clamp")
    rows = np.broadcast_to(np.arange(size)[:, None, None], index.shape)
    matrix = sp.coo_matrix((weight[valid], (rows[valid], index[valid])), shape=(size, size)).tocsr()
    matrix.sum_duplicates()
    matrix.eliminate_zeros()
    matrix.data = (matrix.data / num_samples).astype(np.float32)
    matrix.sort_indices()
    return SparseBlur(matrix, tuple(sceneflow.shape))
