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
from numba import uint64 as U

from stereodeblur.deconv.cg import _as_3d, by_rows, lane_sum, solve, threads_for
from stereodeblur.deconv.prior import (
    add_weighted_laplacian,
    gradient,
    gradient_adjoint,
    smoothness_weights,
)
from stereodeblur.errors import InputError
from stereodeblur.progress import ProgressCallback, report

__all__ = [
    "DeblurResult",
    "IrlsIterate",
    "Observation",
    "deblur_irls",
    "gradient",
    "gradient_adjoint",
]


@dataclass(frozen=True, eq=False)
class Observation:
    """A further blurred observation of the estimate: ``blurred ~ operator(I)``.

    Adds ``sum_x || w(x) (B_k(x) - (A_k I)(x)) ||^2`` to the data term of
    :func:`deblur_irls`. ``operator`` has ``forward`` and ``adjoint`` (and optionally
    ``gram``) on images of the estimate's shape, e.g. a blur composed with a warp;
    ``blurred`` has the estimate's shape; ``weights`` ``(H, W)`` in [0, 1] (0 where the
    observation does not see the estimate).
    """

    operator: object
    blurred: np.ndarray
    weights: np.ndarray


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
        ``num_irls + 1`` entries: the starting point (``initial`` or the blurred frame), then
        one per iteration.
    weights_history : tuple of ndarray or None
        With ``update_weights``: the weights used in each of the ``num_irls`` iterations.
    """

    image: np.ndarray
    weights: np.ndarray
    history: tuple[IrlsIterate, ...]
    weights_history: tuple[np.ndarray, ...] | None = None


def _scale_pixels(image, scale) -> None:
    """``image[y, x, :] *= scale[y, x]`` in place."""
    by_rows(_scale_rows, image, image, scale)


def _residual(blurred, reblurred, squared_weights, residual, partial) -> None:
    """``residual = B - A I``; row sums of ``w^2 |residual|^2`` into ``partial``."""
    by_rows(_residual_rows, blurred, blurred, reblurred, squared_weights, residual, partial)


@numba.njit(cache=True, nogil=True)
def _scale_rows(first, last, image, scale):  # pragma: no cover - compiled
    rows, cols, channels = image.shape
    for i in range(first, last):
        for j in range(cols):
            s = scale[i, j]
            for c in range(channels):
                image[i, j, c] *= s


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _residual_rows(
    first, last, blurred, reblurred, squared_weights, residual, partial
):  # pragma: no cover - compiled
    """``residual = B - A I``; ``partial[i] = sum_j w_j^2 sum_c residual_jc^2`` in fixed order."""
    rows, cols, channels = blurred.shape
    size = U(cols * channels)
    b2 = blurred.reshape(rows, cols * channels)
    a2 = reblurred.reshape(rows, cols * channels)
    r2 = residual.reshape(rows, cols * channels)
    squares = np.empty(cols * channels)
    weighted = np.empty(cols)
    for i in range(first, last):
        b_row, a_row, r_row = b2[i], a2[i], r2[i]
        for k in range(size):
            value = b_row[k] - a_row[k]
            r_row[k] = value
            squares[k] = np.float64(value) * np.float64(value)
        for j in range(cols):
            total = 0.0
            for c in range(channels):
                total += squares[j * channels + c]
            weighted[j] = np.float64(squared_weights[i, j]) * total
        partial[i, 0] = lane_sum(weighted)


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


def _check_image(image, shape, name: str) -> np.ndarray:
    """``image`` as a private float32 ``(H, W, C)`` copy, after checking shape and values."""
    image = np.asarray(image)
    if image.shape != shape or not np.issubdtype(image.dtype, np.number):
        raise InputError(f"{name} must be a numeric array of shape {shape}, got {image.shape}")
    image = _as_3d(np.array(image, dtype=np.float32, order="C"))
    if not np.all(np.isfinite(image)):
        raise InputError(f"{name} contains NaN or infinite values")
    return image


def _check_anchor(anchor, plane) -> np.ndarray | None:
    if anchor is None:
        return None
    beta = np.asarray(anchor, dtype=np.float32)
    if beta.shape != plane or not np.all(np.isfinite(beta) & (beta >= 0)):
        raise InputError(f"anchor must be finite, >= 0 and of shape {plane}")
    return np.ascontiguousarray(beta) if beta.any() else None


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def _owned(array: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``array`` as a writeable C-contiguous float32 array not sharing memory with ``other``."""
    if (
        array.dtype != np.float32
        or np.may_share_memory(array, other)
        or not array.flags.writeable
        or not array.flags.c_contiguous
    ):
        return np.array(array, dtype=np.float32, order="C")
    return array


def _forward(operator, image3d, shape):
    return _as_3d(np.asarray(operator.forward(image3d.reshape(shape)), dtype=np.float32))


def _adjoint(operator, image3d, shape):
    return _as_3d(np.asarray(operator.adjoint(image3d.reshape(shape)), dtype=np.float32))


def _gram(operator, p3, squared, unit, shape):
    """``A^T W^2 A p`` (in one pass if ``operator`` offers ``gram``)."""
    gram = getattr(operator, "gram", None)
    if gram is not None:
        return gram(p3.reshape(shape), None if unit else squared.reshape(shape[:2]))
    ap = _forward(operator, p3, shape)
    if not unit:
        ap = _owned(ap, p3)
        _scale_pixels(ap, squared)
    return _adjoint(operator, ap, shape)


class _Extra:
    """An :class:`Observation` in the normal equations, with its robust weights.

    ``squared`` is ``w^2 / (1 + (r / scale)^2)`` after :meth:`reweight` (``r``: the RMS over
    channels of ``B_k - A_k I``), ``w^2`` before.
    """

    def __init__(self, observation: Observation, shape):
        self.operator, self.shape = observation.operator, shape
        self.b3 = _check_image(observation.blurred, shape, "observation blurred")
        base = _check_weights(observation.weights, shape[:2], "observation weights")
        self.base = base * base
        self.squared = self.base.copy()
        self.residual = np.empty_like(self.b3)
        self.partial = np.empty((shape[0], 1), np.float64)

    def rhs(self):
        weighted = self.b3.copy()
        _scale_pixels(weighted, self.squared)
        return _adjoint(self.operator, weighted, self.shape)

    def data_term(self, estimate3d) -> float:
        reblurred = np.ascontiguousarray(_forward(self.operator, estimate3d, self.shape))
        _residual(self.b3, reblurred, self.squared, self.residual, self.partial)
        return float(self.partial.sum())

    def start_residual(self):
        weighted = self.residual.copy()
        _scale_pixels(weighted, self.squared)
        return _adjoint(self.operator, weighted, self.shape)

    def reweight(self, scale: float) -> None:
        r2 = np.mean(self.residual.astype(np.float64) ** 2, axis=2)
        self.squared = (self.base / (1.0 + r2 / scale**2)).astype(np.float32)


class _NormalEquations:
    """The data and prior terms of Eq. 6 and the IRLS normal equations of Eq. 8.

    Holds the blurred frame ``B`` (float32, ``(H, W, C)``), the operator, the current data
    weights (:meth:`set_weights`) and prior weights (:meth:`prior_term`), and the residual
    ``B - A I`` of the last :meth:`data_term` call.
    """

    def __init__(self, blurred3, shape, operator, alpha, exponent, epsilon, beta, extras=()):
        self.b3, self.shape, self.operator = blurred3, shape, operator
        self.extras = list(extras)
        self.alpha, self.exponent, self.epsilon = float(alpha), float(exponent), float(epsilon)
        self.beta3 = None
        if beta is not None:
            self.beta3 = np.ascontiguousarray(np.broadcast_to(beta[..., None], blurred3.shape))
            self.anchored = np.empty_like(blurred3)  # beta * p, reused by every CG step
        self.wx = np.empty_like(blurred3)
        self.wy = np.empty_like(blurred3)
        self.residual = np.empty_like(blurred3)
        rows, channels = blurred3.shape[0], blurred3.shape[2]
        self.partial = np.empty((rows, 1), np.float64)
        self.channel_partial = np.empty((rows, channels), np.float64)

    def forward(self, image3d):
        return _forward(self.operator, image3d, self.shape)

    def adjoint(self, image3d):
        return _adjoint(self.operator, image3d, self.shape)

    def set_weights(self, w) -> None:
        """Data weights ``w``: ``W^2``, the right-hand side ``A^T W^2 B (+ sum_k A_k^T W_k^2 B_k
        + beta B)`` with the observations' current weights, and its norm."""
        self.w = w
        self.squared = np.ascontiguousarray(w * w, dtype=np.float32)
        self.unit_weights = bool(np.all(self.squared == 1))
        weighted_b = self.b3.copy()
        _scale_pixels(weighted_b, self.squared)
        self.rhs = np.array(self.adjoint(weighted_b), dtype=np.float32, order="C")
        for extra in self.extras:
            self.rhs += extra.rhs()
        if self.beta3 is not None:
            self.rhs += self.beta3 * self.b3
        norm = np.sqrt(np.einsum("ijc,ijc->c", self.rhs, self.rhs, dtype=np.float64))
        self.rhs_norm = np.where(norm > 0, norm, 1.0)

    def apply(self, p3, row_dots):
        """``(A^T W^2 A + sum_k A_k^T W_k^2 A_k + D^T rho D + beta) p``; the row sums of
        ``p * (that)`` to ``row_dots``."""
        q = _gram(self.operator, p3, self.squared, self.unit_weights, self.shape)
        q = _owned(_as_3d(np.asarray(q)), p3)
        for extra in self.extras:
            q += _as_3d(np.asarray(_gram(extra.operator, p3, extra.squared, False, self.shape)))
        if self.beta3 is not None:
            np.multiply(self.beta3, p3, out=self.anchored)
            q += self.anchored
        add_weighted_laplacian(p3, self.wx, self.wy, q, row_dots)
        return q

    def data_term(self, estimate3d) -> float:
        """``sum w^2 |B - A I|^2 (+ sum beta |I - B|^2)``; keeps ``B - A I`` in ``residual``."""
        reblurred = np.ascontiguousarray(self.forward(estimate3d))
        _residual(self.b3, reblurred, self.squared, self.residual, self.partial)
        data = float(self.partial.sum())
        data += sum(extra.data_term(estimate3d) for extra in self.extras)
        if self.beta3 is not None:
            difference = (estimate3d - self.b3) ** 2
            data += float(np.einsum("ijc,ijc->", self.beta3, difference, dtype=np.float64))
        return data

    def prior_term(self, estimate3d) -> float:
        """``(2 / p) alpha sum h_eps(d I)``; sets the prior weights of Eq. 7 at ``I``."""
        smoothness_weights(
            estimate3d, self.alpha, self.exponent, self.epsilon, self.wx, self.wy, self.partial
        )
        return 2.0 * self.alpha / self.exponent * float(self.partial.sum())

    def start_residual(self, estimate3d):
        """``b - M I = A^T W^2 (B - A I) - D^T rho D I (+ beta (B - I))``, from ``residual``.

        Overwrites ``residual`` (scaled by ``W^2``).
        """
        if not self.unit_weights:
            _scale_pixels(self.residual, self.squared)
        start = np.array(self.adjoint(self.residual), dtype=np.float32, order="C")
        for extra in self.extras:
            start += extra.start_residual()
        correction = np.zeros_like(start)
        add_weighted_laplacian(estimate3d, self.wx, self.wy, correction, self.channel_partial)
        start -= correction
        if self.beta3 is not None:
            start += self.beta3 * (self.b3 - estimate3d)
        return start

    def energy(self, iteration, estimate3d, relative) -> IrlsIterate:
        """Both terms at ``estimate3d`` (which also sets the next iteration's prior weights)."""
        data = self.data_term(estimate3d)
        prior = self.prior_term(estimate3d)
        mean = float(self.w.mean())
        return IrlsIterate(iteration, data + prior, data, prior, mean, relative)


def _check_arguments(
    blurred, operator, alpha, exponent, epsilon, num_irls, num_cg, robust_scale=None
) -> None:
    """Raise an :class:`InputError` naming the first bad argument of :func:`deblur_irls`."""
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
    if robust_scale is not None and not (np.isfinite(robust_scale) and robust_scale > 0):
        raise InputError(f"robust_scale must be a positive number, got {robust_scale!r}")


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
    initial: np.ndarray | None = None,
    observations=(),
    robust_scale: float | None = None,
    progress: ProgressCallback | None = None,
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
        (e.g. :class:`stereodeblur.blur.operator.SparseBlur`). If it also has
        ``gram(image, squared_weights)`` (``A^T W^2 A`` in one pass, as ``SparseBlur``), the
        CG steps use that instead of ``forward`` then ``adjoint``.
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
    initial : ndarray, shape of ``blurred``, optional
        Starting estimate ``I^0`` (a warm start, e.g. the other view's result warped into
        this one); the blurred frame by default. Only the starting point changes: the
        energy, the weights' first evaluation and every iteration use it in place of ``B``.
    observations : sequence of Observation
        Further data terms ``sum_x || w_k(x) (B_k(x) - A_k I(x)) ||^2`` (e.g. the other
        view or the neighbouring frames warped to this one), summed into the energy and the
        normal equations.
    robust_scale : float, optional
        With ``observations``: from iteration 1 on, each observation's squared weights are
        ``w_k^2 / (1 + (r / robust_scale)^2)`` with ``r`` its residual's RMS over channels at
        the current estimate (Cauchy IRLS weights), so that what the warp does not explain
        drops out; with ``initial``, from iteration 0 on.
    progress : ProgressCallback, optional
        Receives ``Progress("IRLS", completed, num_irls)`` after each IRLS iteration.

    Returns
    -------
    DeblurResult
        The estimate is float32 and not clipped.
    """
    blurred = np.asarray(blurred)
    _check_arguments(blurred, operator, alpha, exponent, epsilon, num_irls, num_cg, robust_scale)
    with threads_for(blurred.size):
        return _deblur(
            blurred,
            operator,
            weights=weights,
            settings=(alpha, exponent, epsilon),
            num_irls=int(num_irls),
            num_cg=int(num_cg),
            update_weights=update_weights,
            anchor=anchor,
            initial=initial,
            observations=tuple(observations),
            robust_scale=robust_scale,
            progress=progress,
        )


def _deblur(
    blurred,
    operator,
    *,
    weights,
    settings,
    num_irls,
    num_cg,
    update_weights,
    anchor,
    initial,
    observations,
    robust_scale,
    progress,
) -> DeblurResult:
    """The body of :func:`deblur_irls` on validated arguments (``settings``: alpha, p, eps)."""
    shape = blurred.shape
    plane = shape[:2]
    b3 = _check_image(blurred, shape, "blurred")
    w = np.ones(plane, np.float32) if weights is None else _check_weights(weights, plane, "weights")
    extras = [_Extra(o, shape) for o in observations]
    beta = _check_anchor(anchor, plane)
    system = _NormalEquations(b3, shape, operator, *settings, beta, extras)
    system.set_weights(w)
    estimate = b3.copy() if initial is None else _check_image(initial, shape, "initial")
    history = [system.energy(0, estimate, None)]
    weights_history = [] if update_weights is not None else None
    for n in range(num_irls):
        if n >= 1 and update_weights is not None:
            new = update_weights(
                n,
                _read_only(b3.reshape(shape)),
                _read_only(system.residual.reshape(shape)),
                _read_only(estimate.reshape(shape)),
                _read_only(w),
            )
            w = _check_weights(new, plane, "update_weights result")
        started = n >= 1 or initial is not None  # the residual is an estimate's
        reweight = started and robust_scale is not None and bool(extras)
        for extra in extras if reweight else ():
            extra.reweight(robust_scale)
        if n >= 1 and (update_weights is not None or reweight):
            system.set_weights(w)
        if weights_history is not None:
            weights_history.append(w)
        # Warm start from I^{n-1}: the residual b - M I from B - A I at hand (no extra A I).
        start = system.start_residual(estimate)
        estimate, norms, _ = solve(
            system.apply, system.rhs, estimate, num_iterations=num_cg, rtol=None, residual=start
        )
        relative = float((norms[-1] / system.rhs_norm).max())
        history.append(system.energy(n + 1, estimate, relative))
        report(progress, "IRLS", n + 1, num_irls)
    return DeblurResult(
        image=estimate.reshape(shape),
        weights=w,
        history=tuple(history),
        weights_history=None if weights_history is None else tuple(weights_history),
    )
