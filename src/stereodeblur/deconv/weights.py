"""Data weights that keep motion boundaries out of the deblurring data term (Sec. 3, Eq. 5).

Conventions
-----------
A weight ``w(x)`` in [0, 1] belongs to pixel ``x``, is shared by the colour channels and
multiplies the residual inside the square of Eq. 6 (see :mod:`stereodeblur.deconv.irls`).
The residual is ``r(x) = B(x) - A_x I``, shape ``(H, W)`` or ``(H, W, C)``; ``||r(x)||`` is
its Euclidean norm over the channels.

A *weight update* is a callable ``update(n, blurred, residual, estimate, weights) -> (H, W)``
for ``deblur_irls(update_weights=...)``: it is called at the start of IRLS iteration
``n >= 1`` with the residual of the current estimate ``I^{n-1}`` and returns ``w_n``; the
first iteration uses the initial weights passed as ``deblur_irls(weights=...)``. The
updates here are small stateful objects: every call appends a :class:`WeightsStep` (the
weights it returned, the residual norm they came from, the residual scale it used) to the
object's ``history``; use a fresh object for every deblurring.

The default handling of motion boundaries is not a residual weight but the dense optical
flow's kernels there (:func:`stereodeblur.pipeline.boundary_motion`), or without those
the occlusion-aware operator (:mod:`stereodeblur.blur.visibility`) with
:func:`hidden_weights` and an anchor to the blurred frame where the motion is not trusted
(:mod:`stereodeblur.deconv.trust`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

PAPER_K_SIGMA = 4000.0 / 3.0
"""``k_sigma`` of Eq. 5 for intensities in [0, 1]."""

# Why: docs/defaults.md#hidden-surface-weights
HIDDEN_SLOPE = 2.0
"""``slope`` of :func:`hidden_weights`: weight 0 from half the exposure on."""


@dataclass(frozen=True, eq=False)
class WeightsStep:
    """One weight update.

    Attributes
    ----------
    iteration : int
        The IRLS iteration ``n`` the weights are for.
    weights : ndarray, float32, shape (H, W)
        ``w_n``.
    residual_norm : ndarray, float32, shape (H, W)
        ``||B(x) - A_x I^{n-1}||`` over the channels, the input of the update.
    scale : float
        The residual scale of the update (:class:`PaperWeights`: ``1 / sqrt(k_sigma)``).
    """

    iteration: int
    weights: np.ndarray
    residual_norm: np.ndarray
    scale: float


def _check_residual(residual, weights=None) -> np.ndarray:
    residual = np.asarray(residual)
    if residual.ndim not in (2, 3) or residual.size == 0:
        raise InputError(f"residual must have shape (H, W) or (H, W, C), got {residual.shape}")
    if not np.issubdtype(residual.dtype, np.number):
        raise InputError(f"residual must be numeric, got dtype {residual.dtype}")
    residual = np.asarray(residual, dtype=np.float64)
    residual = residual if residual.ndim == 3 else residual[..., None]
    if weights is not None and np.shape(weights) != residual.shape[:2]:
        raise InputError(f"weights must have shape {residual.shape[:2]}, got {np.shape(weights)}")
    return residual


def residual_norm(residual: np.ndarray) -> np.ndarray:
    """``||r(x)||`` over the channels, float32 ``(H, W)``."""
    residual = _check_residual(residual)
    return np.sqrt(np.einsum("ijc,ijc->ij", residual, residual)).astype(np.float32)


def initial_weights_from_occlusion(occlusion: np.ndarray, *, value: float = 0.0) -> np.ndarray:
    """``w_0`` of Eq. 5: ``value`` (the paper: 0) where ``occlusion`` is True, 1 elsewhere.

    Parameters
    ----------
    occlusion : ndarray of bool, shape (H, W)
        E.g. :attr:`SceneFlow.occlusion`.
    value : float
        The weight of the masked pixels, in [0, 1].

    Returns
    -------
    ndarray, float32, shape (H, W)
    """
    occlusion = np.asarray(occlusion)
    if occlusion.ndim != 2:
        raise InputError(f"occlusion must have shape (H, W), got {occlusion.shape}")
    if not (0 <= value <= 1):
        raise InputError(f"value must be in [0, 1], got {value!r}")
    return np.where(occlusion.astype(bool), value, 1.0).astype(np.float32)


def hidden_weights(hidden_share: np.ndarray, *, slope: float = HIDDEN_SLOPE) -> np.ndarray:
    """Data weights ``max(0, 1 - slope h)`` of pixels that show a hidden surface.

    ``h`` is the share of the exposure during which the pixel shows a surface that the
    reference instant hides (:func:`stereodeblur.blur.visibility.hidden_fraction`): no blur
    model of the reference image explains that part of the pixel.

    Returns
    -------
    ndarray, float32, shape of ``hidden_share``
    """
    share = np.asarray(hidden_share, dtype=np.float64)
    return np.clip(1.0 - slope * share, 0.0, 1.0).astype(np.float32)


@dataclass(eq=False)
class PaperWeights:
    """Eq. 5 as published: ``w_n(x) = exp(-k_sigma ||B(x) - A_x I^{n-1}||^2)``.

    A weight update for ``deblur_irls(update_weights=...)``; start it from
    :func:`initial_weights_from_occlusion` of the scene flow's occlusion mask.

    Parameters
    ----------
    k_sigma : float
        The paper's 4000 / 3 for intensities in [0, 1]. With it a residual norm of 0.009
        already gives ``w = 0.9`` and 0.023 gives 0.5, so textured pixels whose residual the
        prior keeps at about 0.01, or noise of ``sigma = 0.01`` (norm about 0.017 over three
        channels), are down-weighted too, and a pixel of weight 0 is left to the prior
        alone: see :mod:`stereodeblur.deconv.trust` for the default.
    """

    k_sigma: float = PAPER_K_SIGMA
    history: list[WeightsStep] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self):
        if not (np.isfinite(self.k_sigma) and self.k_sigma > 0):
            raise InputError(f"k_sigma must be a positive number, got {self.k_sigma!r}")

    def __call__(self, n, blurred, residual, estimate, weights) -> np.ndarray:
        norm = residual_norm(residual)
        w = np.exp(-self.k_sigma * norm.astype(np.float64) ** 2).astype(np.float32)
        self.history.append(WeightsStep(int(n), w, norm, 1.0 / math.sqrt(self.k_sigma)))
        return w


# --- pictures ---------------------------------------------------------------------------------


def weights_image(weights: np.ndarray) -> np.ndarray:
    """Weights in [0, 1] as a uint8 grey image (0 black, 1 white)."""
    weights = np.asarray(weights, dtype=np.float64)
    if weights.ndim != 2:
        raise InputError(f"weights must have shape (H, W), got {weights.shape}")
    return np.rint(np.clip(np.nan_to_num(weights), 0.0, 1.0) * 255).astype(np.uint8)


def residual_image(residual: np.ndarray, *, full_scale: float = 0.1) -> np.ndarray:
    """``||r(x)||`` (or a residual ``(H, W, C)``) as uint8 grey, white at ``full_scale``."""
    if not (np.isfinite(full_scale) and full_scale > 0):
        raise InputError(f"full_scale must be a positive number, got {full_scale!r}")
    residual = np.asarray(residual)
    norm = residual_norm(residual) if residual.ndim == 3 else np.abs(residual)
    return weights_image(np.asarray(norm, dtype=np.float64) / full_scale)


def write_weights_history(
    directory: str | os.PathLike,
    history,
    *,
    full_scale: float = 0.1,
) -> list[Path]:
    """Write ``weights_NN.png`` and ``residual_NN.png`` (8-bit grey) for every step.

    Parameters
    ----------
    directory : path
        Created if missing.
    history : sequence of WeightsStep
        E.g. ``PaperWeights.history``.
    full_scale : float
        Residual norm shown white.

    Returns
    -------
    list of Path
        The files written.
    """
    from ..io.formats import write_png

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for step in history:
        n = step.iteration
        written.append(write_png(directory / f"weights_{n:02d}.png", step.weights, bit_depth=8))
        picture = residual_image(step.residual_norm, full_scale=full_scale) / 255.0
        written.append(write_png(directory / f"residual_{n:02d}.png", picture, bit_depth=8))
    return written
