"""The noise level of a blurred frame, and the prior weight ``alpha`` set from it.

Conventions
-----------
Images are float, ``(H, W)`` grey or ``(H, W, C)`` colour, intensities in [0, 1]. The
noise is taken to be additive, white and Gaussian, independent over pixels and
channels, with one standard deviation ``sigma`` in intensity units for all channels.

The paper fixes ``alpha = 0.001`` (Eq. 6). That is far too strong for clean input;
:func:`auto_alpha` (``--alpha auto``) sets ``alpha = clip(2 * sigma_hat^1.9, 2e-5, 3e-3)``
from the noise estimate instead (close to ``alpha ~ sigma^2``, the MAP scaling of a prior
weight with the noise variance). The rule does not know about model errors (an estimated
scene flow), which act like extra noise. Why these constants:
``docs/defaults.md#noise-rule``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..errors import InputError

# Immerkaer's mask: the difference of two discrete Laplacians, which is zero on any
# locally quadratic image; white noise of deviation sigma gives responses of deviation
# 6 sigma (the mask's coefficients have a squared sum of 36).
_MASK = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
_MASK_NORM = 6.0
_HALF_NORMAL_MEDIAN = 0.6744897501960817  # median of |z|, z ~ N(0, 1)

# The calibrated rule.
# Why: docs/defaults.md#noise-rule
ALPHA_SCALE = 2.0
"""``c`` of ``alpha = c * sigma^p``."""
ALPHA_POWER = 1.9
"""``p`` of ``alpha = c * sigma^p``."""
ALPHA_MIN = 2e-5
"""Smallest ``alpha`` the rule returns (clean input)."""
ALPHA_MAX = 3e-3
"""Largest ``alpha`` the rule returns (very noisy input)."""


def _check_image(image) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim not in (2, 3) or image.shape[0] < 3 or image.shape[1] < 3:
        raise InputError(f"image must have shape (H, W) or (H, W, C), H, W >= 3, got {image.shape}")
    if not np.issubdtype(image.dtype, np.number):
        raise InputError(f"image must be numeric, got dtype {image.dtype}")
    image = np.asarray(image, dtype=np.float64)
    if not np.all(np.isfinite(image)):
        raise InputError("image contains NaN or infinite values")
    return image if image.ndim == 3 else image[..., None]


def estimate_noise_sigma(image: np.ndarray) -> float:
    """Robust estimate of the standard deviation of additive white noise in ``image``.

    Immerkaer's estimator (Immerkaer 1996, "Fast noise variance estimation") made robust:
    the image is filtered with the mask ``[[1, -2, 1], [-2, 4, -2], [1, -2, 1]]``, which
    removes locally quadratic content, and ``sigma = median |response| / (6 * 0.6745)``
    over the interior pixels of all channels (the median instead of the mean keeps edges
    and texture, which give large responses on few pixels, from inflating the estimate).
    Content that survives the mask still adds to it: a noiseless blurred natural image
    reads 0.0001-0.002, a finely textured one (grass, gravel) up to 0.005 at 320 x 240, and
    sharp texture (a static background) reads as noise too.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, C)
        Intensities in [0, 1]; ``H, W >= 3``.

    Returns
    -------
    float
        ``sigma`` in intensity units, >= 0.
    """
    image = _check_image(image)
    responses = [
        ndimage.correlate(image[..., c], _MASK, mode="reflect")[1:-1, 1:-1]
        for c in range(image.shape[2])
    ]
    median = float(np.median(np.abs(np.stack(responses))))
    return median / (_MASK_NORM * _HALF_NORMAL_MEDIAN)


def alpha_from_sigma(
    sigma: float,
    *,
    scale: float = ALPHA_SCALE,
    power: float = ALPHA_POWER,
    alpha_min: float = ALPHA_MIN,
    alpha_max: float = ALPHA_MAX,
) -> float:
    """The prior weight for noise deviation ``sigma``: ``clip(scale * sigma^power, min, max)``.

    Parameters
    ----------
    sigma : float
        Noise standard deviation in intensity units (e.g. :func:`estimate_noise_sigma`).
    scale, power : float
        ``c`` and ``p`` of the rule; the defaults are calibrated (``docs/defaults.md#noise-rule``).
    alpha_min, alpha_max : float
        The clamp, ``0 < alpha_min <= alpha_max``.

    Returns
    -------
    float
        ``alpha``, non-decreasing in ``sigma``.
    """
    if not (np.isfinite(sigma) and sigma >= 0):
        raise InputError(f"sigma must be a non-negative number, got {sigma!r}")
    if not (np.isfinite(scale) and scale > 0 and np.isfinite(power) and power > 0):
        raise InputError(f"scale and power must be positive, got {scale!r}, {power!r}")
    if not (0 < alpha_min <= alpha_max < np.inf):
        raise InputError(
            f"need 0 < alpha_min <= alpha_max, got alpha_min={alpha_min!r}, alpha_max={alpha_max!r}"
        )
    return float(np.clip(scale * float(sigma) ** power, alpha_min, alpha_max))


def auto_alpha(
    blurred: np.ndarray,
    *,
    scale: float = ALPHA_SCALE,
    power: float = ALPHA_POWER,
    alpha_min: float = ALPHA_MIN,
    alpha_max: float = ALPHA_MAX,
) -> float:
    """``alpha`` of Eq. 6 from the noise level of the blurred frame (``--alpha auto``).

    ``alpha_from_sigma(estimate_noise_sigma(blurred), ...)``; see those two functions.
    """
    return alpha_from_sigma(
        estimate_noise_sigma(blurred),
        scale=scale,
        power=power,
        alpha_min=alpha_min,
        alpha_max=alpha_max,
    )
