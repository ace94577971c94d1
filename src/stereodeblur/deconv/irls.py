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

import numpy as np

from stereodeblur.deconv._normal_equations import IrlsIterate, _Extra, _NormalEquations
from stereodeblur.deconv.cg import _as_3d, solve, threads_for
from stereodeblur.deconv.prior import gradient, gradient_adjoint
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


def _check_map(values, plane, name: str) -> np.ndarray | None:
    """``values`` of shape ``plane`` as C-contiguous float32, finite and >= 0; None if None."""
    if values is None:
        return None
    array = np.asarray(values, dtype=np.float32)
    if array.shape != plane or not np.all(np.isfinite(array) & (array >= 0)):
        raise InputError(f"{name} must be finite, >= 0 and of shape {plane}")
    return np.ascontiguousarray(array)


def _check_anchor(anchor, plane) -> np.ndarray | None:
    beta = _check_map(anchor, plane, "anchor")
    return beta if beta is not None and beta.any() else None


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


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
    alpha_scale: np.ndarray | None = None,
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
    alpha, alpha_scale : float, ndarray (H, W) optional
        Prior weight, the paper's 0.001 (Eq. 6), times ``alpha_scale >= 0`` at each
        difference's first pixel (1 everywhere by default).
    exponent, epsilon : float
        ``p`` of the robust norm ``|c|^p``, in (0, 2], and the floor of ``|c|`` in the IRLS
        weights; the paper's 0.8 and 0.01 (Eq. 6-7).
    num_irls, num_cg : int
        IRLS iterations and CG steps per iteration; the paper's 10 and 25.
    update_weights : callable, optional
        ``update_weights(n, blurred, residual, estimate, weights) -> new weights``, called at
        the start of every IRLS iteration ``n >= 1`` with the residual ``B - A I`` of the
        current ``estimate`` (for the residual weights of Eq. 5). Arguments are read-only
        views in the shape of ``blurred`` (weights ``(H, W)``), valid during the call only
        (copy what you keep); the result must be ``(H, W)`` in [0, 1].
    anchor : ndarray, shape (H, W), optional
        ``beta(x) >= 0``: adds ``sum_x beta(x) || I(x) - B(x) ||^2`` to the energy, keeping
        the estimate near the blurred frame where the blur model is not trusted.
    initial : ndarray, shape of ``blurred``, optional
        Starting estimate ``I^0`` (a warm start), in place of the blurred frame; only the
        starting point changes.
    observations : sequence of Observation
        Further data terms ``sum_x || w_k(x) (B_k(x) - A_k I(x)) ||^2`` (e.g. the other
        view or the neighbouring frames warped to this one).
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
            scale=alpha_scale,
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
    scale,
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
    extras = [
        _Extra(
            o.operator,
            _check_image(o.blurred, shape, "observation blurred"),
            _check_weights(o.weights, plane, "observation weights"),
            shape,
        )
        for o in observations
    ]
    beta = _check_anchor(anchor, plane)
    scale = _check_map(scale, plane, "alpha_scale")
    system = _NormalEquations(b3, shape, operator, *settings, beta, extras, scale)
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
