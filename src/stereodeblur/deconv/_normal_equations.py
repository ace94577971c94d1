"""The IRLS normal equations of Eq. 8: data terms, prior and their products.

:class:`_NormalEquations` holds the view's weighted data term, any further observations
(:class:`_Extra`, each with its robust weights), the prior's IRLS weights and an optional
anchor, and applies ``A^T W^2 A + sum_k A_k^T W_k^2 A_k + D^T rho D + beta`` for the CG solve
of :func:`stereodeblur.deconv.irls.deblur_irls` (whose module gives the conventions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import uint64 as U

from stereodeblur.deconv.cg import _as_3d, by_rows, lane_sum
from stereodeblur.deconv.prior import add_weighted_laplacian, smoothness_weights


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


class _DataTerm:
    """One data term ``sum_x || w(x) (B(x) - A_x I) ||^2``: its operator, checked ``(H * W, C)``
    image ``b3``, squared weights and the residual ``B - A I`` of the last :meth:`data_term`."""

    def __init__(self, operator, b3, weights, shape):
        self.operator, self.shape, self.b3 = operator, shape, b3
        self.residual = np.empty_like(b3)
        self.partial = np.empty((shape[0], 1), np.float64)
        self.set_squared(weights * weights)

    def set_squared(self, squared) -> None:
        self.squared = np.ascontiguousarray(squared, dtype=np.float32)
        self.unit = bool(np.all(self.squared == 1))

    def rhs(self):
        """``A^T W^2 B``."""
        weighted = self.b3.copy()
        _scale_pixels(weighted, self.squared)
        return _adjoint(self.operator, weighted, self.shape)

    def gram(self, p3):
        """``A^T W^2 A p``."""
        return _as_3d(np.asarray(_gram(self.operator, p3, self.squared, self.unit, self.shape)))

    def data_term(self, estimate3d) -> float:
        """``sum w^2 |B - A I|^2``; keeps ``B - A I`` in ``residual``."""
        reblurred = np.ascontiguousarray(_forward(self.operator, estimate3d, self.shape))
        _residual(self.b3, reblurred, self.squared, self.residual, self.partial)
        return float(self.partial.sum())

    def start_residual(self):
        """``A^T W^2 (B - A I)`` from ``residual``, which it overwrites (scaled by ``W^2``)."""
        if not self.unit:
            _scale_pixels(self.residual, self.squared)
        return _adjoint(self.operator, self.residual, self.shape)


class _Extra(_DataTerm):
    """A further observation's data term, with its robust weights: ``squared`` is
    ``w^2 / (1 + (r / scale)^2)`` after :meth:`reweight` (``r``: the RMS over channels of
    ``B_k - A_k I``), ``w^2`` before."""

    def __init__(self, operator, b3, weights, shape):
        super().__init__(operator, b3, weights, shape)
        self.base = self.squared.copy()

    def reweight(self, scale: float) -> None:
        r2 = np.mean(self.residual.astype(np.float64) ** 2, axis=2)
        self.set_squared(self.base / (1.0 + r2 / scale**2))


class _NormalEquations:
    """The data and prior terms of Eq. 6 and the IRLS normal equations of Eq. 8.

    Holds the view's data term (``own``, on the blurred frame ``B``, float32 ``(H, W, C)``),
    the further observations' (``extras``), the current data weights (:meth:`set_weights`)
    and prior weights (:meth:`prior_term`); ``residual`` is ``B - A I`` of the last
    :meth:`data_term` call.
    """

    def __init__(
        self, blurred3, shape, operator, alpha, exponent, epsilon, beta, extras=(), scale=None
    ):
        self.b3, self.shape = blurred3, shape
        self.scale = np.ones(shape[:2], np.float32) if scale is None else scale
        self.own = _DataTerm(operator, blurred3, np.ones(shape[:2], np.float32), shape)
        self.extras = list(extras)
        self.alpha, self.exponent, self.epsilon = float(alpha), float(exponent), float(epsilon)
        self.beta3 = None
        if beta is not None:
            self.beta3 = np.ascontiguousarray(np.broadcast_to(beta[..., None], blurred3.shape))
            self.anchored = np.empty_like(blurred3)  # beta * p, reused by every CG step
        self.wx = np.empty_like(blurred3)
        self.wy = np.empty_like(blurred3)
        rows, channels = blurred3.shape[0], blurred3.shape[2]
        self.partial = np.empty((rows, 1), np.float64)
        self.channel_partial = np.empty((rows, channels), np.float64)

    @property
    def residual(self):
        return self.own.residual

    def set_weights(self, w) -> None:
        """Data weights ``w``: ``W^2``, the right-hand side ``A^T W^2 B (+ sum_k A_k^T W_k^2 B_k
        + beta B)`` with the observations' current weights, and its norm."""
        self.w = w
        self.own.set_squared(w * w)
        self.rhs = np.array(self.own.rhs(), dtype=np.float32, order="C")
        for extra in self.extras:
            self.rhs += extra.rhs()
        if self.beta3 is not None:
            self.rhs += self.beta3 * self.b3
        norm = np.sqrt(np.einsum("ijc,ijc->c", self.rhs, self.rhs, dtype=np.float64))
        self.rhs_norm = np.where(norm > 0, norm, 1.0)

    def apply(self, p3, row_dots):
        """``(A^T W^2 A + sum_k A_k^T W_k^2 A_k + D^T rho D + beta) p``; the row sums of
        ``p * (that)`` to ``row_dots``."""
        q = _owned(self.own.gram(p3), p3)
        for extra in self.extras:
            q += extra.gram(p3)
        if self.beta3 is not None:
            np.multiply(self.beta3, p3, out=self.anchored)
            q += self.anchored
        add_weighted_laplacian(p3, self.wx, self.wy, q, row_dots)
        return q

    def data_term(self, estimate3d) -> float:
        """``sum w^2 |B - A I|^2`` over the data terms (``+ sum beta |I - B|^2``)."""
        data = self.own.data_term(estimate3d)
        data += sum(extra.data_term(estimate3d) for extra in self.extras)
        if self.beta3 is not None:
            difference = (estimate3d - self.b3) ** 2
            data += float(np.einsum("ijc,ijc->", self.beta3, difference, dtype=np.float64))
        return data

    def prior_term(self, estimate3d) -> float:
        """``(2 / p) alpha sum s h_eps(d I)`` (``s``: the per-pixel ``scale`` of alpha);
        sets the prior weights of Eq. 7 at ``I``."""
        smoothness_weights(
            estimate3d,
            self.alpha,
            self.exponent,
            self.epsilon,
            self.wx,
            self.wy,
            self.partial,
            self.scale,
        )
        return 2.0 * self.alpha / self.exponent * float(self.partial.sum())

    def start_residual(self, estimate3d):
        """``b - M I = sum A^T W^2 (B - A I) - D^T rho D I (+ beta (B - I))``, from the data
        terms' residuals (which it overwrites)."""
        start = np.array(self.own.start_residual(), dtype=np.float32, order="C")
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
