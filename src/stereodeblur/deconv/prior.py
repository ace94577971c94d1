"""The sparse gradient prior of Eq. 6-8: forward differences and their IRLS weights.

Conventions
-----------
Gradients are forward differences, ``dx I (y, x) = I (y, x + 1) - I (y, x)`` and
``dy I (y, x) = I (y + 1, x) - I (y, x)``, set to 0 in the last column (``dx``) and the last
row (``dy``) (Neumann boundary), per channel. The IRLS weights of Eq. 7 are
``alpha * max(|d I|, epsilon)^(p - 2)`` per pixel, channel and direction; they include
``alpha`` (times the pixel's ``scale`` where alpha varies over the image; a difference
counts at its first pixel) and are 0 where the differences are identically zero.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import uint64 as U

from stereodeblur.deconv.cg import LANES, _as_3d, by_rows, fold_lanes, lane_sum
from stereodeblur.errors import InputError

# --- gradients ---------------------------------------------------------------------------


@numba.njit(parallel=True, cache=True)
def _differences(image, dx, dy):  # pragma: no cover - compiled
    rows, cols, channels = image.shape
    for i in numba.prange(rows):
        for j in range(cols):
            for c in range(channels):
                v = image[i, j, c]
                dx[i, j, c] = image[i, j + 1, c] - v if j < cols - 1 else 0.0
                dy[i, j, c] = image[i + 1, j, c] - v if i < rows - 1 else 0.0


@numba.njit(parallel=True, cache=True)
def _differences_adjoint(dx, dy, out):  # pragma: no cover - compiled
    rows, cols, channels = out.shape
    for i in numba.prange(rows):
        for j in range(cols):
            for c in range(channels):
                acc = 0.0
                if j < cols - 1:
                    acc -= dx[i, j, c]
                if j > 0:
                    acc += dx[i, j - 1, c]
                if i < rows - 1:
                    acc -= dy[i, j, c]
                if i > 0:
                    acc += dy[i - 1, j, c]
                out[i, j, c] = acc


def gradient(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward differences ``D I = (dx I, dy I)``, zero in the last column / row.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)

    Returns
    -------
    dx, dy : ndarray
        Same shape as ``image``; float64 for float64 input, float32 otherwise.
    """
    image = np.asarray(image)
    if image.ndim not in (2, 3):
        raise InputError(f"image must have shape (H, W) or (H, W, C), got {image.shape}")
    dtype = np.float64 if image.dtype == np.float64 else np.float32
    image = np.ascontiguousarray(image, dtype=dtype)
    dx = np.empty_like(image)
    dy = np.empty_like(image)
    _differences(_as_3d(image), _as_3d(dx), _as_3d(dy))
    return dx, dy


def gradient_adjoint(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """Adjoint ``D^T (gx, gy) = dx^T gx + dy^T gy`` of :func:`gradient`.

    Entries of ``dx`` in the last column and of ``dy`` in the last row are ignored (the
    forward differences there are identically zero).
    """
    dx = np.asarray(dx)
    dy = np.asarray(dy)
    if dx.shape != dy.shape or dx.ndim not in (2, 3):
        raise InputError(f"dx and dy must share shape (H, W[, C]), got {dx.shape}, {dy.shape}")
    dtype = np.float64 if np.float64 in (dx.dtype, dy.dtype) else np.float32
    dx = np.ascontiguousarray(dx, dtype=dtype)
    dy = np.ascontiguousarray(dy, dtype=dtype)
    out = np.empty_like(dx)
    _differences_adjoint(_as_3d(dx), _as_3d(dy), _as_3d(out))
    return out


# --- IRLS weights (Eq. 7) and the weighted Laplacian of Eq. 8 ---------------------------


def smoothness_weights(image, alpha, exponent, epsilon, wx, wy, partial, scale=None) -> None:
    """Eq. 7 weights of ``image`` into ``wx``, ``wy``; row sums of ``h_eps(d I)`` to ``partial``
    (of ``scale * h_eps(d I)`` with a per-pixel ``scale`` of alpha, float32 ``(H, W)``)."""
    if scale is None:
        scale = _unit_scale(image.shape[:2])
    by_rows(_smoothness_range, image, image, alpha, exponent, epsilon, wx, wy, partial, scale)


def _unit_scale(plane) -> np.ndarray:
    """Ones of shape ``plane``, float32: alpha the same at every pixel (exactly)."""
    return np.ones(plane, np.float32)


def add_weighted_laplacian(x, wx, wy, out, partial) -> None:
    """``out += D^T diag(wx, wy) D x``; the row sums of ``x * out`` per channel to ``partial``."""
    by_rows(_laplacian_rows, x, x, wx, wy, out, partial)


def _smoothness_range(first, last, image, alpha, exponent, epsilon, wx, wy, partial, scale):
    """:func:`smoothness_weights` on rows ``first .. last - 1``.

    ``max(|d I|, eps)`` by numba, its power by numpy (whose ``power`` is vectorised, unlike
    the scalar one numba calls), then the scale and ``h_eps`` by numba. Each step releases
    the GIL.
    """
    floor = np.float32(epsilon)
    _floored_sizes_rows(first, last, image, floor, wx, wy)
    power = np.float32(exponent - 2.0)
    for weights in (wx, wy):
        rows = weights[first:last]
        np.power(rows, power, out=rows)
    small = (
        0.5 * exponent * epsilon ** (exponent - 2.0),
        (1.0 - 0.5 * exponent) * epsilon**exponent,
    )
    _smoothness_rows(first, last, image, floor, np.float32(alpha), scale, small, wx, wy, partial)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _floored_sizes_rows(first, last, image, floor, wx, wy):  # pragma: no cover - compiled
    """``max(|d I|, floor)`` into ``wx``, ``wy`` (``floor`` also where ``d`` is undefined)."""
    rows, cols, channels = image.shape
    x2 = image.reshape(rows, cols * channels)
    wx2 = wx.reshape(rows, cols * channels)
    wy2 = wy.reshape(rows, cols * channels)
    size = U(cols * channels)
    c = U(channels)
    inner = size - c if cols > 1 else U(0)
    for i in range(first, last):
        x_row, wx_row, wy_row = x2[i], wx2[i], wy2[i]
        for k in range(inner):  # x direction: right neighbour k + channels
            wx_row[k] = max(abs(x_row[k + c] - x_row[k]), floor)
        for k in range(inner, size):
            wx_row[k] = floor
        x_down = x2[min(i + 1, rows - 1)]  # the last row: d = 0
        for k in range(size):
            wy_row[k] = max(abs(x_down[k] - x_row[k]), floor)


@numba.njit(cache=True, nogil=True, inline="always")
def _smoothed_power(difference, rho, floor, small):  # pragma: no cover - compiled
    """``h_eps(c)`` of one difference ``c`` given ``rho = max(|c|, eps)^(p - 2)`` (``small``:
    the quadratic's scale and offset below ``eps``)."""
    g = abs(difference)
    g64 = np.float64(g)
    if g >= floor:
        return np.float64(rho) * g64 * g64
    return small[0] * g64 * g64 + small[1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _smoothness_rows(
    first, last, image, floor, alpha, scale, small, wx, wy, partial
):  # pragma: no cover - compiled
    """Scale ``rho`` in ``wx``, ``wy`` to the weights ``alpha s rho`` (``s``: the pixel's
    ``scale``); row sums of ``s h_eps(d I)``.

    ``h_eps(c) = |c|^p`` for ``|c| >= eps`` and ``(p/2) eps^(p-2) c^2 + (1 - p/2) eps^p``
    below: the function whose IRLS majoriser the weights are. The weights are 0 in the
    last column (``wx``) and row (``wy``), where the differences are identically zero.
    Row sums add ``h`` per entry (x then y term) in :data:`LANES` fixed-order lanes.
    """
    rows, cols, channels = image.shape
    x2 = image.reshape(rows, cols * channels)
    wx2 = wx.reshape(rows, cols * channels)
    wy2 = wy.reshape(rows, cols * channels)
    size = U(cols * channels)
    c = U(channels)
    inner = size - c if cols > 1 else U(0)
    h = np.empty(cols * channels)
    for i in range(first, last):
        x_row, wx_row, wy_row, s_row = x2[i], wx2[i], wy2[i], scale[i]
        for k in range(inner):
            h[k] = _smoothed_power(x_row[k + c] - x_row[k], wx_row[k], floor, small)
            wx_row[k] = (alpha * s_row[k // c]) * wx_row[k]
        for k in range(inner, size):
            h[k] = 0.0
            wx_row[k] = 0.0
        if i < rows - 1:
            x_down = x2[i + 1]
            for k in range(size):
                h[k] += _smoothed_power(x_down[k] - x_row[k], wy_row[k], floor, small)
                wy_row[k] = (alpha * s_row[k // c]) * wy_row[k]
        else:
            for k in range(size):
                wy_row[k] = 0.0
        for k in range(size):
            h[k] *= s_row[k // c]
        partial[i, 0] = lane_sum(h)


@numba.njit(cache=True, nogil=True, inline="always")
def _laplacian_entry(o, x_row, x_up, x_down, wy_up, wy_row, wx_row, k, c):  # pragma: no cover
    """Entry ``k`` of ``out + L x`` with both x neighbours: the y terms, then the flux from
    the left neighbour ``k - c``, minus the flux to the right one ``k + c``."""
    v = x_row[k]
    y_terms = wy_up[k] * (v - x_up[k]) - wy_row[k] * (x_down[k] - v)
    left = wx_row[k - c] * (v - x_row[k - c])
    return ((o[k] + y_terms) + left) - wx_row[k] * (x_row[k + c] - v)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _laplacian_rows(first, last, x, wx, wy, out, partial):  # pragma: no cover - compiled
    """``out += dx^T (wx * dx x) + dy^T (wy * dy x)`` (``wx``, ``wy`` include alpha).

    One sweep per row (channel stride ``C``), which also adds ``x * out`` into the lanes of
    :func:`~stereodeblur.deconv.cg.lane_dots` (entry ``k`` to lane ``k % (LANES C)``, in
    blocks of whole lanes so that it vectorises) and writes their row sums per channel into
    ``partial`` (for CG). The first and last columns lack the left and right flux.
    """
    rows, cols, channels = x.shape
    x2 = x.reshape(rows, cols * channels)
    wx2 = wx.reshape(rows, cols * channels)
    wy2 = wy.reshape(rows, cols * channels)
    out2 = out.reshape(rows, cols * channels)
    size = U(cols * channels)
    c = U(channels)
    lanes = U(LANES * channels)
    inner_end = size - c if cols > 1 else c  # [c, inner_end): both x neighbours exist
    head_end = min(lanes, inner_end)  # then whole blocks of lanes from lane 0
    blocks = (inner_end - head_end) // lanes
    tail = head_end + blocks * lanes
    acc = np.zeros(LANES * channels)
    for i in range(first, last):
        up = max(i - 1, 0)  # at the borders the neighbour is the pixel itself: d = 0
        down = min(i + 1, rows - 1)
        x_row, x_up, x_down = x2[i], x2[up], x2[down]
        wy_up, wy_row, wx_row = wy2[up], wy2[i], wx2[i]
        o = out2[i]
        for k in range(U(0), min(c, size)):  # first column: no left neighbour
            v = x_row[k]
            value = o[k] + (wy_up[k] * (v - x_up[k]) - wy_row[k] * (x_down[k] - v))
            if cols > 1:
                value -= wx_row[k] * (x_row[k + c] - v)
            o[k] = value
            acc[k] += np.float64(v) * np.float64(value)
        for k in range(c, head_end):
            value = _laplacian_entry(o, x_row, x_up, x_down, wy_up, wy_row, wx_row, k, c)
            o[k] = value
            acc[k] += np.float64(x_row[k]) * np.float64(value)
        for block in range(blocks):
            base = head_end + block * lanes
            for lane in range(lanes):
                k = base + lane
                value = _laplacian_entry(o, x_row, x_up, x_down, wy_up, wy_row, wx_row, k, c)
                o[k] = value
                acc[lane] += np.float64(x_row[k]) * np.float64(value)
        for k in range(tail, inner_end):
            value = _laplacian_entry(o, x_row, x_up, x_down, wy_up, wy_row, wx_row, k, c)
            o[k] = value
            acc[k - tail] += np.float64(x_row[k]) * np.float64(value)
        if cols > 1:
            for k in range(inner_end, size):  # last column: no right neighbour
                v = x_row[k]
                y_terms = wy_up[k] * (v - x_up[k]) - wy_row[k] * (x_down[k] - v)
                value = (o[k] + y_terms) + wx_row[k - c] * (v - x_row[k - c])
                o[k] = value
                acc[k % lanes] += np.float64(v) * np.float64(value)
        fold_lanes(acc, channels, partial, i)
