"""Prior weight chosen per view by cross-view prediction (``alpha='held-out'``, the
default, and ``alpha='cross-view'``).

The view is deblurred at several alphas: ``'held-out'`` at the noise rule's (``'auto'``)
and at every alpha of :data:`~stereodeblur.settings.CROSS_VIEW_ALPHAS` above it,
``'cross-view'`` at every alpha of the grid.
Each solution predicts the other view's blurred frame through the other view's
observation of this view (:func:`~.observations.other_view_observation`: warped by the
disparity, blurred with the other view's operator), a held-out observation with its own
noise and its own model error. The pixels that observation cannot see (occlusions, the image
edge) have weight 0 there and do not count. The prediction is made in the blurred domain,
where the blur hides part of the estimate's error (the noise it averages away, the detail it
removes), so on its own it often picks too little regularisation for noisy frames.
``'held-out'`` therefore keeps the best predictor among alphas no smaller than the noise
rule's, raised by the motion's trust; only where the best prediction is within
:data:`~stereodeblur.settings.HELD_OUT_NOISE_RATIO` of the noise (the motion explains the
other view) does it go below the trust's raise, down to the noise alone
(:func:`below_floor`). ``'cross-view'`` takes :data:`~stereodeblur.settings.CROSS_VIEW_STEP`
grid steps above the best predictor of the whole grid (``benchmarks/study_alpha_choice.py``).
"""

from __future__ import annotations

import numpy as np

from ..deconv.irls import Observation
from ..deconv.noise import alpha_from_sigma
from ..errors import InputError
from ..settings import CROSS_VIEW_ALPHAS, CROSS_VIEW_STEP, HELD_OUT_NOISE_RATIO
from .observations import other_view_observation

RULES_VERSION = 2
"""Version of the choice of ``'held-out'`` and ``'cross-view'``, part of the signature of
cached benchmark results: 2 since stop 28 (the other view's observation predicted, its unseen
pixels left out; ``'held-out'`` below the trust's raise where the prediction is within the
noise), 1 the 90 % best-predicted pixels through a bilinear warp."""


def other_view(own_motion, other_operator, blurred: np.ndarray, weights: np.ndarray, view: str):
    """The other view's :class:`~stereodeblur.deconv.irls.Observation` of the view whose
    motion is ``own_motion``, made of view ``view``'s operator, blurred frame and data
    weights: what that view's alpha choice predicts."""
    if own_motion.sceneflow is None or other_operator.motion.sceneflow is None:
        raise InputError(
            f"alpha='cross-view' needs the {view} view's disparity, which its motion lacks",
            parameter="alpha",
        )
    return other_view_observation(own_motion.sceneflow, other_operator, blurred, weights)


def prediction_error(image: np.ndarray, other: Observation, *, border: int) -> float:
    """Mean squared error per pixel (over channels) of ``other``'s blurred frame predicted
    from ``image``, over the pixels it sees (weight > 0), ``border`` px excluded."""
    predicted = np.asarray(other.operator.forward(image), np.float64)
    error = (predicted - np.asarray(other.blurred, np.float64)) ** 2
    if error.ndim == 3:
        error = error.mean(axis=-1)
    inner = (slice(border, error.shape[0] - border), slice(border, error.shape[1] - border))
    seen = np.asarray(other.weights)[inner] > 0
    return float(error[inner][seen].mean()) if seen.any() else float("inf")


def candidates(rule: str, floor: float) -> tuple[float, ...]:
    """The alphas ``rule`` solves at, in this order: for ``'cross-view'`` the grid
    :data:`~stereodeblur.settings.CROSS_VIEW_ALPHAS`; for ``'held-out'`` ``floor`` (the
    ``'auto'`` alpha) and the grid alphas above it."""
    if rule == "held-out":
        return (floor, *(a for a in CROSS_VIEW_ALPHAS if a > floor))
    return CROSS_VIEW_ALPHAS


def searched(rule: str, errors) -> bool:
    """Whether ``rule`` needs no further candidate after these prediction errors:
    ``'held-out'`` stops once the error rises (on the 40 training scenes every error curve
    had one minimum)."""
    return rule == "held-out" and len(errors) > 1 and errors[-1] >= errors[-2]


def choose(errors, rule: str = "cross-view") -> int:
    """Index of the chosen alpha among the candidates solved: for ``'held-out'`` the best
    predictor, for ``'cross-view'`` :data:`CROSS_VIEW_STEP` above it, within the grid."""
    best = int(np.argmin(errors))
    return best if rule == "held-out" else min(best + CROSS_VIEW_STEP, len(errors) - 1)


def below_floor(floor: float, error: float, sigma: float) -> tuple[float, ...]:
    """The alphas ``'held-out'`` tries below its ``floor`` (the noise rule's alpha raised by
    the motion's trust) when the floor predicts best, with prediction ``error``, in this
    order: the grid alphas between the noise rule's alpha (from ``sigma``) and the floor,
    and the noise rule's, from the top, while the error falls. Nothing unless ``error`` is
    within :data:`HELD_OUT_NOISE_RATIO` of the two views' noise ``2 sigma^2``: only where the
    motion explains the other view to about its noise is its trust not needed."""
    noise = alpha_from_sigma(sigma)
    if noise >= floor or error >= HELD_OUT_NOISE_RATIO * 2.0 * sigma**2:
        return ()
    return (*(a for a in reversed(CROSS_VIEW_ALPHAS) if noise < a < floor), noise)
