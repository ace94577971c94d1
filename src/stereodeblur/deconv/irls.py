"""Non-blind deconvolution with a sparse gradient prior by IRLS (Sec. 3, Eq. 6-8).

Conventions
-----------
Images are float32, ``(H, W)`` grey or ``(H, W, C)`` colour; the blur operator applies the
same matrix to every channel. Gradients are forward differences,
``dx I (y, x) = I (y, x + 1) - I (y, x)`` and ``dy I (y, x) = I (y + 1, x) - I (y, x)``,
set to 0 in the last column (``dx``) and the last row (``dy``) (Neumann boundary), per
channel. The data weights ``w`` are per pixel, shared by all channels, and multiply the
residual inside the square: ``sum_x || w(x) (B(x) - A_x I) ||^2``, so ``W^2`` appears in
the normal equations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from stereodeblur.deconv.cg import _as_3d, row_channel_dots, solve, threads_for
from stereodeblur.errors import InputError


@dataclass(frozen=True)
class IrlsIterate:
    """Energy bookkeeping after one IRLS iteration (``iteration = 0``: the starting point).

    Attributes
    ----------
    iteration : int
        Completed IRLS iterations.
    energy : float
        ``data_term + prior_term``, the objective IRLS decreases (see :func:`deblur_irls`).
    data_term : float
        ``sum_x || w(x) (B(x) - A_x I) ||^2`` with the weights used in this iteration, plus
        the anchor term ``sum_x beta(x) || I(x) - B(x) ||^2`` if any.
    prior_term : float
        ``(2 / exponent) * alpha * sum h_eps(d I)`` over channels and both directions.
    weights_mean : float
        Mean of the data weights used in this iteration.
    cg_relative_residual : float or None
        Largest over channels of ``||b - M I|| / ||b||`` at the end of the CG solve (the
        recursively updated residual); None for ``iteration = 0``.
    """

    iteration: int
    energy: float
    data_term: float
    prior_term: float
    weights_mean: float
    cg_relative_residual: float | None


@dataclass(frozen=True, eq=False)
class DeblurResult:
    """Outcome of :func:`deblur_irls`.

    Attributes
    ----------
    image : ndarray, float32, shape of the blurred input
        The sharp estimate, not clipped to [0, 1] (clip for display or saving).
    weights : ndarray, float32, shape (H, W)
        The data weights used in the last IRLS iteration.
    history : tuple of IrlsIterate
        ``num_irls + 1`` entries: the starting point (the blurred frame), then one per iteration.
    weights_history : tuple of ndarray or None
        With ``update_weights``: the weights used in each of the ``num_irls`` iterations.
    """

    image: np.ndarray
    weights: np.ndarray
    history: tuple[IrlsIterate, ...]
    weights_history: tuple[np.ndarray, ...] | None = None


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


# --- fused kernels of the IRLS loop -------------------------------------------------------


@numba.njit(parallel=True, cache=True)
def _smoothness_weights(image, alpha, exponent, epsilon, wx, wy, partial):  # pragma: no cover
    """Eq. 7 weights ``alpha * max(|d I|, eps)^(p - 2)`` and row sums of ``h_eps(d I)``.

    ``h_eps(c) = |c|^p`` for ``|c| >= eps`` and ``(p/2) eps^(p-2) c^2 + (1 - p/2) eps^p``
    below: the function whose IRLS majoriser the weights are. The weights are 0 in the
    last column (``wx``) and row (``wy``), where the differences are identically zero.
    """
    rows, cols, channels = image.shape
    size = cols * channels
    x2 = image.reshape(rows, size)
    wx2 = wx.reshape(rows, size)
    wy2 = wy.reshape(rows, size)
    power = np.float32(exponent - 2.0)
    floor = np.float32(epsilon)
    scale = np.float32(alpha)
    rho_floor = floor**power
    small_scale = 0.5 * exponent * epsilon ** (exponent - 2.0)
    small_offset = (1.0 - 0.5 * exponent) * epsilon**exponent
    for i in numba.prange(rows):
        acc = 0.0
        for k in range(size - channels):  # x direction: right neighbour k + channels
            g = abs(x2[i, k + channels] - x2[i, k])
            g64 = np.float64(g)
            if g >= floor:
                rho = g**power
                acc += np.float64(rho) * g64 * g64
            else:
                rho = rho_floor
                acc += small_scale * g64 * g64 + small_offset
            wx2[i, k] = scale * rho
        for k in range(size - channels, size):
            wx2[i, k] = 0.0
        if i < rows - 1:
            for k in range(size):  # y direction: the next row
                g = abs(x2[i + 1, k] - x2[i, k])
                g64 = np.float64(g)
                if g >= floor:
                    rho = g**power
                    acc += np.float64(rho) * g64 * g64
                else:
                    rho = rho_floor
                    acc += small_scale * g64 * g64 + small_offset
                wy2[i, k] = scale * rho
        else:
            for k in range(size):
                wy2[i, k] = 0.0
        partial[i, 0] = acc


@numba.njit(parallel=True, cache=True)
def _add_weighted_laplacian(x, wx, wy, out, partial):  # pragma: no cover - compiled
    """``out += dx^T (wx * dx x) + dy^T (wy * dy x)`` (``wx``, ``wy`` include alpha).

    Also writes the row sums of ``x * out`` per channel into ``partial`` (for CG).
    """
    rows, cols, channels = x.shape
    size = cols * channels
    x2 = x.reshape(rows, size)
    wx2 = wx.reshape(rows, size)
    wy2 = wy.reshape(rows, size)
    out2 = out.reshape(rows, size)
    for i in numba.prange(rows):
        row = np.int64(i)
        up = max(row - 1, 0)  # at the borders the neighbour is the pixel itself: d = 0
        down = min(row + 1, rows - 1)
        x_row = x2[row]
        x_up = x2[up]
        x_down = x2[down]
        wy_up = wy2[up]
        wy_row = wy2[row]
        wx_row = wx2[row]
        o = out2[row]
        for k in range(size):
            v = x_row[k]
            o[k] += wy_up[k] * (v - x_up[k]) - wy_row[k] * (x_down[k] - v)
        for k in range(channels, size):
            flux = wx_row[k - channels] * (x_row[k] - x_row[k - channels])
            o[k] += flux
            o[k - channels] -= flux
        row_channel_dots(x_row, o, channels, partial, row)


@numba.njit(parallel=True, cache=True)
def _scale_pixels(image, scale):  # pragma: no cover - compiled
    """``image[y, x, :] *= scale[y, x]`` in place."""
    rows, cols, channels = image.shape
    for i in numba.prange(rows):
        for j in range(cols):
            s = scale[i, j]
            for c in range(channels):
                image[i, j, c] *= s


@numba.njit(parallel=True, cache=True)
def _residual(blurred, reblurred, squared_weights, residual, partial):  # pragma: no cover
    """``residual = B - A I``; row sums of ``w^2 |residual|^2`` into ``partial``."""
    rows, cols, channels = blurred.shape
    for i in numba.prange(rows):
        acc = 0.0
        for j in range(cols):
            s = 0.0
            for c in range(channels):
                value = blurred[i, j, c] - reblurred[i, j, c]
                residual[i, j, c] = value
                s += np.float64(value) * np.float64(value)
            acc += np.float64(squared_weights[i, j]) * s
        partial[i, 0] = acc


# --- the solver ---------------------------------------------------------------------------


def _check_weights(weights, shape, name: str) -> np.ndarray:
    weights = np.asarray(weights)
    if weights.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {weights.shape}")
    if not np.issubdtype(weights.dtype, np.number) and weights.dtype != bool:
        raise InputError(f"{name} must be numeric, got dtype {weights.dtype}")
    weights = np.array(weights, dtype=np.float32, order="C")  # a private copy
    if not np.all(np.isfinite(weights)) or weights.min() < 0 or weights.max() > 1:
        raise InputError(f"{name} must be finite and in [0, 1]")
    return weights


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def deblur_irls(
    blurred: np.ndarray,
    operator,
    *,
    weights: np.ndarray | None = None,
    alpha: float = 1e-3,
    exponent: float = 0.8,
    epsilon: float = 0.01,
    num_irls: int = 10,
    num_cg: int = 25,
    update_weights: Callable | None = None,
    anchor: np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> DeblurResult:
    """Deblur ``blurred`` by IRLS on a weighted least-squares data term and ``|d I|^p`` prior.

    The energy of Eq. 6 is ``sum_x || w(x) (B(x) - A_x I) ||^2 + alpha sum |d I|^p`` with the
    sum over channels and both directions. Each IRLS iteration (Eq. 7-8) computes
    ``rho = max(|d I^{n-1}|, epsilon)^(p - 2)`` per channel and direction and takes
    ``num_cg`` conjugate-gradient steps, warm-started from ``I^{n-1}``, on the normal equations

        ``(A^T W^2 A + alpha (dx^T rho_x dx + dy^T rho_y dy)) I = A^T W^2 B``,

    ``W = diag(w)``: the weights multiply the residual inside the square, hence ``W^2``.
    These are Eq. 8 as the paper writes it (``alpha || rho_n grad I ||^2``, no factor
    ``p / 2``, as in Levin et al.'s reference code). With them IRLS is an exact
    majorise-minimise scheme for ``E(I) = sum_x || w (B - A_x I) ||^2 + (2 / p) alpha sum
    h_eps(d I)``, where ``h_eps(c) = |c|^p`` for ``|c| >= epsilon`` and is the quadratic
    ``(p/2) eps^(p-2) c^2 + (1 - p/2) eps^p`` below; that is, Eq. 6 with an effective prior
    weight ``2 alpha / p``. ``E`` is what ``history`` reports, and it does not increase
    from one iteration to the next while the weights stay fixed (any number of CG steps
    from the warm start lowers the majoriser), up to float32 rounding.

    Parameters
    ----------
    blurred : ndarray, shape (H, W) or (H, W, C)
        ``B``, the blurred frame (normalised intensities); also the starting estimate.
    operator : object
        Blur ``A`` with ``forward(image)`` and ``adjoint(image)`` on ``(H, W[, C])`` arrays
        (e.g. :class:`stereodeblur.blur.operator.SparseBlur`).
    weights : ndarray, shape (H, W), optional
        Per-pixel data weights ``w`` in [0, 1], all ones by default. Zeros are allowed
        (masked deblurring): such pixels are filled in by the prior.
    alpha : float
        Prior weight; the paper's 0.001 (Eq. 6).
    exponent : float
        ``p`` of the robust norm ``|c|^p``, in (0, 2]; the paper's 0.8 (Eq. 6-7).
    epsilon : float
        Floor of ``|c|`` in the IRLS weights; the paper's 0.01 (Eq. 7).
    num_irls : int
        IRLS iterations; the paper's 10.
    num_cg : int
        CG steps per IRLS iteration; the paper's 25.
    update_weights : callable, optional
        ``update_weights(n, blurred, residual, estimate, weights) -> new weights``, called at
        the start of every IRLS iteration ``n >= 1`` with the residual ``B - A I`` of the
        current ``estimate`` (for the residual weights of Eq. 5). Arguments are read-only
        views in the shape of ``blurred`` (weights ``(H, W)``), valid during the call only
        (copy what you keep); the result must be ``(H, W)`` in [0, 1].
    anchor : ndarray, shape (H, W), optional
        ``beta(x) >= 0``: adds ``sum_x beta(x) || I(x) - B(x) ||^2`` to the energy (and
        ``diag(beta)`` to the normal equations), which keeps the estimate near the blurred
        frame where the blur model is not trusted; none by default.
    progress : callable, optional
        ``progress(completed, num_irls)`` after each IRLS iteration.

    Returns
    -------
    DeblurResult
        The estimate is float32 and not clipped.
    """
    blurred = np.asarray(blurred)
    if blurred.ndim not in (2, 3) or min(blurred.shape[:2], default=0) < 1:
        raise InputError(f"blurred must have shape (H, W) or (H, W, C), got {blurred.shape}")
    if not np.issubdtype(blurred.dtype, np.number):
        raise InputError(f"blurred must be numeric, got dtype {blurred.dtype}")
    if not (hasattr(operator, "forward") and hasattr(operator, "adjoint")):
        raise InputError(f"operator must have forward and adjoint methods, got {operator!r}")
    op_shape = getattr(operator, "shape", None)
    if op_shape is not None and tuple(op_shape) != blurred.shape[:2]:
        raise InputError(f"operator shape {tuple(op_shape)} does not match image {blurred.shape}")
    if not (np.isfinite(alpha) and alpha >= 0):
        raise InputError(f"alpha must be a non-negative number, got {alpha!r}")
    if not (np.isfinite(exponent) and 0 < exponent <= 2):
        raise InputError(f"exponent must be in (0, 2], got {exponent!r}")
    if not (np.isfinite(epsilon) and epsilon > 0):
        raise InputError(f"epsilon must be positive, got {epsilon!r}")
    for name, value in (("num_irls", num_irls), ("num_cg", num_cg)):
        if int(value) != value or value < 0:
            raise InputError(f"{name} must be a non-negative integer, got {value!r}")

    with threads_for(blurred.size):
        return _deblur(
            blurred,
            operator,
            weights,
            alpha,
            exponent,
            epsilon,
            num_irls,
            num_cg,
            update_weights,
            anchor,
            progress,
        )


def _deblur(
    blurred,
    operator,
    weights,
    alpha,
    exponent,
    epsilon,
    num_irls,
    num_cg,
    update_weights,
    anchor,
    progress,
) -> DeblurResult:
    """The body of :func:`deblur_irls` on validated arguments."""
    shape = blurred.shape
    plane = shape[:2]
    b3 = _as_3d(np.array(blurred, dtype=np.float32, order="C"))
    if not np.all(np.isfinite(b3)):
        raise InputError("blurred contains NaN or infinite values")
    w = np.ones(plane, np.float32) if weights is None else _check_weights(weights, plane, "weights")
    beta = None
    if anchor is not None:
        beta = np.asarray(anchor, dtype=np.float32)
        if beta.shape != plane or not np.all(np.isfinite(beta) & (beta >= 0)):
            raise InputError(f"anchor must be finite, >= 0 and of shape {plane}")
        beta = np.ascontiguousarray(beta) if beta.any() else None
    if beta is not None:
        beta3 = np.ascontiguousarray(np.broadcast_to(beta[..., None], b3.shape))
        anchored = np.empty_like(b3)  # beta * p, reused by every CG step

    def forward(image3d):
        return _as_3d(np.asarray(operator.forward(image3d.reshape(shape)), dtype=np.float32))

    def adjoint(image3d):
        return _as_3d(np.asarray(operator.adjoint(image3d.reshape(shape)), dtype=np.float32))

    # Buffers reused across IRLS iterations.
    rows = plane[0]
    wx = np.empty_like(b3)
    wy = np.empty_like(b3)
    residual = np.empty_like(b3)
    partial = np.empty((rows, 1), np.float64)
    channel_partial = np.empty((rows, b3.shape[2]), np.float64)
    prior_scale = 2.0 * alpha / exponent

    def weights_state(w):
        squared = np.ascontiguousarray(w * w, dtype=np.float32)
        weighted_b = b3.copy()
        _scale_pixels(weighted_b, squared)
        rhs = np.array(adjoint(weighted_b), dtype=np.float32, order="C")
        if beta is not None:
            rhs += beta3 * b3
        rhs_norm = np.sqrt(np.einsum("ijc,ijc->c", rhs, rhs, dtype=np.float64))
        return squared, bool(np.all(squared == 1)), rhs, np.where(rhs_norm > 0, rhs_norm, 1.0)

    def normal(p3, row_dots):  # (A^T W^2 A + alpha D^T rho D + beta) p, and p . (that) per row
        ap = forward(p3)
        if not unit_weights:
            if np.may_share_memory(ap, p3) or not ap.flags.writeable or not ap.flags.c_contiguous:
                ap = np.array(ap, order="C")
            _scale_pixels(ap, squared)
        q = adjoint(ap)
        if np.may_share_memory(q, p3) or not q.flags.writeable or not q.flags.c_contiguous:
            q = np.array(q, order="C")
        if beta is not None:
            np.multiply(beta3, p3, out=anchored)
            q += anchored
        _add_weighted_laplacian(p3, wx, wy, q, row_dots)
        return q

    def data_term(estimate3d):
        reblurred = forward(estimate3d)
        _residual(b3, np.ascontiguousarray(reblurred), squared, residual, partial)
        data = float(partial.sum())
        if beta is not None:
            data += float(np.einsum("ijc,ijc->", beta3, (estimate3d - b3) ** 2, dtype=np.float64))
        return data

    def prior_term_and_weights(estimate3d):
        _smoothness_weights(
            estimate3d, float(alpha), float(exponent), float(epsilon), wx, wy, partial
        )
        return prior_scale * float(partial.sum())

    squared, unit_weights, rhs, rhs_norm = weights_state(w)
    estimate = b3.copy()
    data = data_term(estimate)
    prior = prior_term_and_weights(estimate)
    history = [IrlsIterate(0, data + prior, data, prior, float(w.mean()), None)]
    weights_history = [] if update_weights is not None else None

    for n in range(int(num_irls)):
        if n >= 1 and update_weights is not None:
            new = update_weights(
                n,
                _read_only(b3.reshape(shape)),
                _read_only(residual.reshape(shape)),
                _read_only(estimate.reshape(shape)),
                _read_only(w),
            )
            w = _check_weights(new, plane, "update_weights result")
            squared, unit_weights, rhs, rhs_norm = weights_state(w)
        if weights_history is not None:
            weights_history.append(w)
        # Warm start: b - M I = A^T W^2 (B - A I) - alpha D^T rho D I, with B - A I at hand.
        if not unit_weights:
            _scale_pixels(residual, squared)
        start = np.array(adjoint(residual), dtype=np.float32, order="C")
        correction = np.zeros_like(start)
        _add_weighted_laplacian(estimate, wx, wy, correction, channel_partial)
        start -= correction
        if beta is not None:
            start += beta3 * (b3 - estimate)
        estimate, norms, _ = solve(
            normal, rhs, estimate, num_iterations=int(num_cg), rtol=None, residual=start
        )
        relative = norms[-1] / rhs_norm
        data = data_term(estimate)
        prior = prior_term_and_weights(estimate)
        history.append(
            IrlsIterate(n + 1, data + prior, data, prior, float(w.mean()), float(relative.max()))
        )
        if progress is not None:
            progress(n + 1, int(num_irls))

    return DeblurResult(
        image=estimate.reshape(shape),
        weights=w,
        history=tuple(history),
        weights_history=None if weights_history is None else tuple(weights_history),
    )
