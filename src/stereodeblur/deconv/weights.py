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

A *motion boundary* of a scene flow is a pair of 4-neighbouring pixels of different
segments whose flows (frame t to t + 1) differ by more than ``flow_threshold`` pixels.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from ..errors import InputError
from .noise import estimate_noise_sigma

PAPER_K_SIGMA = 4000.0 / 3.0
"""``k_sigma`` of Eq. 5 for intensities in [0, 1]."""


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
        The residual scale the update measured against (:class:`AdaptiveWeights`: the
        threshold ``c * sigma``; :class:`PaperWeights`: ``1 / sqrt(k_sigma)``).
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
        E.g. :attr:`SceneFlow.occlusion`, or :func:`motion_boundary_band`.
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
        channels), are down-weighted too: see :class:`AdaptiveWeights`.
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


@dataclass(eq=False)
class AdaptiveWeights:
    """Residual weights that down-weight only what the blur model cannot explain.

    Eq. 5 compares residuals with a fixed scale; these compare them with their own spread,
    so that noise and the prior's small misfit on texture leave ``w ~ 1``, while motion
    boundaries and scene-flow errors, whose residuals are several times larger, get
    ``w ~ 0``. At the update for iteration ``n``:

    1. ``e(x)^2``: the mean over channels of ``r(x)^2``, averaged over a Gaussian window of
       deviation ``smoothing`` px (one noisy pixel is not an outlier; a boundary is a
       region);
    2. ``sigma = max(median_x e(x), noise_sigma, min_sigma)``: a robust spread of the
       residual (the median ignores up to half the pixels being outliers), never below the
       noise level of the input, nor below ``min_sigma``;
    3. ``v(x) = 1 / (1 + (e(x) / (threshold * sigma))^4)``: a Geman-McClure-type kernel in
       ``e^2``: flat near 0 (``v > 0.975`` for ``e < sigma`` at ``threshold = 2.5``), 0.5
       at ``e = threshold * sigma``, and ``~ (threshold sigma / e)^4`` beyond;
    4. ``w_n = (1 - s_n) w_{n-1} + s_n v`` with ``s_n = first_step * step_decay^(n - 1)``:
       the weights follow the residual at first and settle later (with the defaults no
       weight moves by more than 0.058 in the tenth iteration).

    Works with ``alpha`` set from the noise (:func:`stereodeblur.deconv.noise.auto_alpha`);
    with a much larger ``alpha`` than the noise calls for (e.g. 0.001 on clean input) the
    prior's misfit at strong edges becomes the largest residual and is down-weighted too.
    Start from :func:`adaptive_initial_weights`.

    Parameters
    ----------
    noise_sigma : float, optional
        Noise deviation of the blurred input; when None it is estimated from the blurred
        frame at the first call (:func:`stereodeblur.deconv.noise.estimate_noise_sigma`)
        and kept in ``estimated_noise_sigma``.
    threshold : float
        ``c``: a smoothed residual ``c`` times its spread gets ``v = 0.5``.
    smoothing : float
        Deviation in pixels of the Gaussian window of step 1 (0: no smoothing).
    min_sigma : float
        Floor of the residual scale (intensity units).
    first_step : float
        ``s_1`` in (0, 1]; 1 replaces the initial weights by the first residual weights.
    step_decay : float
        Ratio of successive steps, in (0, 1]; 1 keeps the step constant.
    """

    noise_sigma: float | None = None
    threshold: float = 2.5
    smoothing: float = 1.0
    min_sigma: float = 0.003
    first_step: float = 1.0
    step_decay: float = 0.7
    history: list[WeightsStep] = field(default_factory=list, init=False, repr=False)
    estimated_noise_sigma: float | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        if self.noise_sigma is not None and not (
            np.isfinite(self.noise_sigma) and self.noise_sigma >= 0
        ):
            raise InputError(f"noise_sigma must be a non-negative number, got {self.noise_sigma!r}")
        for name in ("threshold", "min_sigma"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be a positive number, got {value!r}")
        if not (np.isfinite(self.smoothing) and self.smoothing >= 0):
            raise InputError(f"smoothing must be a non-negative number, got {self.smoothing!r}")
        for name in ("first_step", "step_decay"):
            value = getattr(self, name)
            if not (0 < value <= 1):
                raise InputError(f"{name} must be in (0, 1], got {value!r}")

    def robust_weights(self, residual: np.ndarray, noise_sigma: float) -> tuple:
        """Steps 1-3 alone: ``(v, e, threshold * sigma)`` for one residual ``(H, W[, C])``."""
        residual = _check_residual(residual)
        squared = np.mean(residual**2, axis=2)
        if self.smoothing > 0:
            squared = ndimage.gaussian_filter(squared, self.smoothing, mode="nearest")
        spread = np.sqrt(np.maximum(squared, 0.0))
        sigma = max(float(np.median(spread)), float(noise_sigma), self.min_sigma)
        scale = self.threshold * sigma
        v = 1.0 / (1.0 + (spread / scale) ** 4)
        return v.astype(np.float32), spread.astype(np.float32), scale

    def step(self, n: int) -> float:
        """``s_n``, the weight of the new residual weights in the update for iteration n."""
        return self.first_step * self.step_decay ** max(int(n) - 1, 0)

    def __call__(self, n, blurred, residual, estimate, weights) -> np.ndarray:
        noise_sigma = self.noise_sigma
        if noise_sigma is None:
            if self.estimated_noise_sigma is None:
                self.estimated_noise_sigma = estimate_noise_sigma(blurred)
            noise_sigma = self.estimated_noise_sigma
        residual = _check_residual(residual, weights)
        v, _, scale = self.robust_weights(residual, noise_sigma)
        previous = np.asarray(weights, dtype=np.float32)
        step = self.step(n)
        w = np.clip((1.0 - step) * previous + step * v, 0.0, 1.0).astype(np.float32)
        self.history.append(WeightsStep(int(n), w, residual_norm(residual), scale))
        return w


# --- motion boundaries of a scene flow ------------------------------------------------------


def _boundary_pairs(sceneflow, flow_threshold: float):
    """Boundary pairs ``(mask_a, mask_b, difference)`` along x and along y."""
    if not (np.isfinite(flow_threshold) and flow_threshold >= 0):
        raise InputError(f"flow_threshold must be a non-negative number, got {flow_threshold!r}")
    labels = sceneflow.labels
    flow = sceneflow.flow()
    pairs = []
    for axis in (1, 0):  # neighbours along x, then along y
        first = [slice(None), slice(None)]
        second = [slice(None), slice(None)]
        first[axis], second[axis] = slice(None, -1), slice(1, None)
        first, second = tuple(first), tuple(second)
        difference = np.hypot(*np.moveaxis(flow[first] - flow[second], -1, 0))
        boundary = (labels[first] != labels[second]) & (difference > flow_threshold)
        pairs.append((first, second, boundary, difference))
    return pairs


def motion_boundaries(sceneflow, *, flow_threshold: float = 0.5) -> np.ndarray:
    """Pixels on either side of a motion boundary of ``sceneflow``, bool ``(H, W)``.

    Parameters
    ----------
    sceneflow : SceneFlow
    flow_threshold : float
        Least flow difference (pixels per frame interval) between neighbouring segments for
        their border to count; adjacent planes of one rigid object move alike and do not.
    """
    mask = np.zeros(sceneflow.shape, bool)
    for first, second, boundary, _ in _boundary_pairs(sceneflow, flow_threshold):
        mask[first] |= boundary
        mask[second] |= boundary
    return mask


def motion_boundary_band(
    sceneflow,
    width: float,
    *,
    flow_threshold: float = 0.5,
    include_occlusion: bool = True,
) -> np.ndarray:
    """Pixels within ``width`` px of a motion boundary (or of an occluded pixel), bool (H, W).

    Parameters
    ----------
    sceneflow : SceneFlow
    width : float
        Distance in pixels (Euclidean, from the boundary pixels); 0 gives the boundary
        pixels themselves. :func:`boundary_band_width` scales it with the blur.
    flow_threshold : float
        See :func:`motion_boundaries`.
    include_occlusion : bool
        Also mark pixels within ``width`` of ``sceneflow.occlusion``.
    """
    if not (np.isfinite(width) and width >= 0):
        raise InputError(f"width must be a non-negative number, got {width!r}")
    seeds = motion_boundaries(sceneflow, flow_threshold=flow_threshold)
    if include_occlusion:
        seeds = seeds | sceneflow.occlusion
    if not seeds.any():
        return seeds
    return ndimage.distance_transform_edt(~seeds) <= width


def boundary_band_width(
    sceneflow,
    exposure,
    *,
    flow_threshold: float = 0.5,
    margin: float = 1.0,
    fraction: float = 0.125,
    quantile: float = 0.9,
) -> float:
    """Band width for :func:`motion_boundary_band` that grows with the blur at the boundaries.

    ``width = margin + fraction * tau * q``: ``tau`` the duty cycle, ``q`` the ``quantile``
    of the flow differences over the boundary pairs, so ``tau * q`` is the relative
    displacement of the two sides during the exposure (mixing reaches half of it on either
    side). ``margin`` alone when there is no boundary.

    The defaults keep the band narrow (2-4 px for 8-25 px of relative blur): on two-layer
    test problems (a moving textured disc or box over a static or moving background, the
    model assigning every pixel its layer's blur) a soft, narrow band did better than one
    covering all mixed pixels, see :func:`adaptive_initial_weights`.

    Parameters
    ----------
    sceneflow : SceneFlow
    exposure : Exposure
        Provides the duty cycle ``tau`` (exposure time over frame interval).
    flow_threshold : float
        See :func:`motion_boundaries`.
    margin : float
        Pixels, >= 0.
    fraction : float
        Of the relative displacement during the exposure, >= 0.
    quantile : float
        In [0, 1]; below 1 so that a few wild flow differences do not widen the band.
    """
    for name, value in (("margin", margin), ("fraction", fraction)):
        if not (np.isfinite(value) and value >= 0):
            raise InputError(f"{name} must be a non-negative number, got {value!r}")
    if not (0 <= quantile <= 1):
        raise InputError(f"quantile must be in [0, 1], got {quantile!r}")
    differences = np.concatenate(
        [d[b] for _, _, b, d in _boundary_pairs(sceneflow, flow_threshold)]
    )
    if differences.size == 0:
        return float(margin)
    return float(margin + fraction * exposure.duty_cycle * np.quantile(differences, quantile))


def adaptive_initial_weights(
    sceneflow,
    exposure,
    *,
    band_value: float = 0.3,
    width: float | None = None,
    flow_threshold: float = 0.5,
    include_occlusion: bool = True,
) -> np.ndarray:
    """``w_0`` for :class:`AdaptiveWeights`: ``band_value`` in the motion-boundary band, else 1.

    The band is :func:`motion_boundary_band` with :func:`boundary_band_width` unless
    ``width`` is given. The band is down-weighted, not cut out: a pixel of weight 0 does
    not constrain the first estimate, so its residual is large whether or not the model
    explains it, and the residual weights keep it out for good (on the two-layer test
    problems a zero band 2 px wide lost up to 2.2 dB against no band, one covering the mixed
    pixels up to 7 dB; a 2 px band at 0.3 gained 0.1-6.4 dB).

    Returns
    -------
    ndarray, float32, shape (H, W)
    """
    if width is None:
        width = boundary_band_width(sceneflow, exposure, flow_threshold=flow_threshold)
    band = motion_boundary_band(
        sceneflow, width, flow_threshold=flow_threshold, include_occlusion=include_occlusion
    )
    return initial_weights_from_occlusion(band, value=band_value)


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
        E.g. ``AdaptiveWeights.history``.
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
