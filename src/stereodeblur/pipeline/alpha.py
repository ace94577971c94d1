"""Prior weight chosen per view by cross-view prediction (``alpha='held-out'``, the
default, and ``alpha='cross-view'``).

The view is deblurred at several alphas: ``'held-out'`` at the noise rule's (``'auto'``)
and at every alpha of :data:`~stereodeblur.settings.CROSS_VIEW_ALPHAS` above it,
``'cross-view'`` at every alpha of the grid.
Each solution is carried to the other view through that view's disparity, blurred with
the other view's operator and compared with the other view's blurred frame, a held-out
observation with its own noise and its own model error. Pixels the other view cannot
see (occlusions, the image edge) give the largest errors, so only the smallest
:data:`~stereodeblur.settings.CROSS_VIEW_KEEP` of the per-pixel errors count. The
prediction is made in the blurred domain, where the blur hides part of the estimate's error
(the noise it averages away, the detail it removes), so on its own it often picks too little
regularisation for noisy frames. ``'held-out'`` therefore keeps the best predictor among
alphas no smaller than the noise rule's, raised by the motion's trust, and among predictors
within :data:`~stereodeblur.settings.HELD_OUT_TIE` of the best (a flat error curve, which cannot
tell them apart) the alpha nearest the paper's. It solves them from the smallest up and stops
once an error is more than :data:`~stereodeblur.settings.HELD_OUT_STOP` above the least, a
decade (:data:`~stereodeblur.settings.HELD_OUT_SPAN`) or more above the least's alpha. An
estimated motion that the range guard rejects over the whole view at a candidate up to the
paper's alpha (the floor first) is rejected at every larger candidate too, where a strong prior
can hide the failure (the pipeline's ``_alpha_choice_solve``). ``'cross-view'`` takes
:data:`~stereodeblur.settings.CROSS_VIEW_STEP` grid steps above the best predictor of the
whole grid.

With the neighbouring frames observed (``observations='neighbours'``/``'all'``) an estimated
motion's candidates are scored instead by the untrimmed errors of the other view's and the
neighbouring frames' observations of the view, summed (:func:`held_out_error`; the data
weights leave out what they cannot see): a motion error that both views share, which the
other view's prediction cannot see, shows in the neighbouring frames, and the trimmed error
drops exactly the pixels it spoils.

``'held-out'`` drops every candidate that a larger candidate fits as well in the view's own
blurred frame (:func:`undominated`): the exact solution's residual only grows with alpha, so a
smaller alpha that fits worse has not reached what it is for (its solve rings, or the range
guard or the clipping to [0, 1] took it back) and its smaller prediction error is no reason to
take it.

Where the floor predicts best, ``'held-out'`` asks whether the trust's raise was needed: it
predicts the other view once more, through the other view's observation of this view (the
data term of ``observations='other-view'``), over every pixel that observation sees with a
data weight of at least :data:`~stereodeblur.settings.HELD_OUT_MIN_WEIGHT`, untrimmed (a
trimmed mean of squared errors lies below the noise it is compared with). Only if that error
is within :data:`~stereodeblur.settings.HELD_OUT_NOISE_RATIO` of the two views' noise (the
motion explains the other view) does it go below the floor, down to the noise rule's alpha,
while the same error falls (:func:`below_floor`).

With the true motion (``motion_source='gt'``) there is no motion error for the trust to
guard against: the floor is the noise rule's alpha, and every candidate is scored by that
untrimmed prediction through the other view's observation (:func:`true_motion_choice`).

With ``local_alpha`` the chosen alpha is then scaled per pixel (:func:`local_scale`): the
candidates' held-out errors are taken around each pixel (:func:`local_error`, a Gaussian window
of :data:`~stereodeblur.settings.LOCAL_ALPHA_WINDOW` of the width) and each pixel takes the
locally best candidate's alpha, smoothed in log alpha. One alpha cannot suit a frame whose
content or blur varies: fine stripes that the blur nearly erases want less regularisation than
a sharp, noisy region. Never below the chosen alpha unless the frame is noisy
(:data:`~stereodeblur.settings.LOCAL_ALPHA_NOISE`), then down to
:data:`~stereodeblur.settings.LOCAL_ALPHA_DOWN` times less: on a quiet frame a locally smaller
alpha predicts the held-out frames better where the blur hides what it gets wrong. By default
(``'noisy'``) only on a noisy frame (:func:`local_alpha_here`).

Why the rule and each of its constants: ``docs/defaults.md``, from its section ``#alpha-rule``
on.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import gaussian_filter, map_coordinates

from ..deconv.noise import alpha_from_sigma
from ..errors import InputError
from ..settings import (
    CROSS_VIEW_ALPHAS,
    CROSS_VIEW_KEEP,
    CROSS_VIEW_STEP,
    HELD_OUT_MIN_WEIGHT,
    HELD_OUT_NOISE_RATIO,
    HELD_OUT_SPAN,
    HELD_OUT_STOP,
    HELD_OUT_TIE,
    LOCAL_ALPHA_DOWN,
    LOCAL_ALPHA_NOISE,
    LOCAL_ALPHA_WINDOW,
    PAPER_ALPHA,
)

if TYPE_CHECKING:
    from ..deconv.irls import Observation

RULES_VERSION = 15
"""Version of the choice of ``'held-out'`` and ``'cross-view'``, part of the signature of cached
benchmark results: raise it whenever a change of the rule can change a choice."""
TRUE_MOTION_RULES_VERSION = 11
"""The same for the choice with the true motion (:func:`true_motion_choice`)."""


def rules_version(settings) -> int | None:
    """:data:`RULES_VERSION` (:data:`TRUE_MOTION_RULES_VERSION` with the true motion) if
    ``settings``' alpha is chosen by predicting the other view, else None (a fixed alpha,
    ``'auto'``, or no scene flow: then the rules are ``'auto'``)."""
    predicts = settings.alpha in ("held-out", "cross-view")
    if not predicts or settings.motion_source == "initial-flow":
        return None
    return TRUE_MOTION_RULES_VERSION if true_motion_choice(settings) else RULES_VERSION


def local_alpha_acts(settings) -> bool:
    """Whether ``settings.local_alpha`` can vary the prior weight over the view: not ``'off'``,
    with ``'held-out'`` and a scene flow or the true motion (:func:`local_scale`)."""
    held_out = settings.alpha == "held-out" and rules_version(settings) is not None
    return settings.local_alpha != "off" and held_out


def local_alpha_here(settings, noise_sigma: float) -> bool:
    """Whether the prior weight varies over a view of noise estimate ``noise_sigma``: where
    :func:`local_alpha_acts`, and with ``'noisy'`` only from :data:`LOCAL_ALPHA_NOISE` up."""
    noisy = settings.local_alpha == "always" or noise_sigma >= LOCAL_ALPHA_NOISE
    return local_alpha_acts(settings) and noisy


LOCAL_ALPHA_VERSION = 3
"""Version of the local alpha's rule in result caches: raise it whenever the rule changes."""


def local_alpha_signature(settings) -> str:
    """The local alpha's constants where ``settings`` use it, else '' (for result caches)."""
    if not local_alpha_acts(settings):
        return ""
    where = " on noisy frames" if settings.local_alpha == "noisy" else ""
    return (
        f" local alpha {LOCAL_ALPHA_VERSION}{where}: {LOCAL_ALPHA_WINDOW:g}"
        f" down {LOCAL_ALPHA_DOWN:g}"
        f" above noise {LOCAL_ALPHA_NOISE:g} share {LOCAL_MIN_SHARE:g}"
    )


def true_motion_choice(settings) -> bool:
    """Whether ``'held-out'`` starts at the noise rule's alpha and scores by the other view's
    observation: with the true motion, where no motion error needs the trust's raise (why:
    ``docs/defaults.md#true-motion-choice``)."""
    return settings.alpha == "held-out" and settings.motion_source == "gt"


@dataclass(frozen=True)
class OtherView:
    """What a view's alpha choice predicts: the other view's blurred frame.

    Parameters
    ----------
    operator : SparseBlur
        The other view's blur operator.
    blurred : ndarray, shape (H, W) or (H, W, C)
        The other view's blurred frame.
    disparity : ndarray, float, shape (H, W)
        The other view's disparity at the frame's centre (px, positive).
    direction : int
        +1 if the other view is the right one (its pixel ``u`` sees the left view's
        ``u + d``), -1 if it is the left one.
    observation : Observation or None
        The other view's observation of this view with its data weights
        (:func:`~.observations.other_view_observation`), for the noise gate.
    """

    operator: object
    blurred: np.ndarray
    disparity: np.ndarray
    direction: int
    observation: Observation | None = None


def other_view(
    view_operator, motion, blurred: np.ndarray, view: str, observation=None
) -> OtherView:
    """The :class:`OtherView` made of view ``view``'s operator, motion and blurred frame
    (and its ``observation`` of the opposite view), for the choice of the view opposite to
    it."""
    if motion.sceneflow is None:
        raise InputError(
            f"alpha='cross-view' needs the {view} view's disparity, which its motion lacks",
            parameter="alpha",
        )
    direction = 1 if view == "right" else -1
    disparity = motion.sceneflow.disparity()
    return OtherView(view_operator.operator, blurred, disparity, direction, observation)


def warp_to_other(image: np.ndarray, disparity: np.ndarray, direction: int) -> np.ndarray:
    """``image`` resampled on the other view's grid at ``u + direction * d(u)`` (``d``: the
    other view's disparity; +1 takes a left image to the right view), bilinear, edge pixels
    repeated, float64."""
    height, width = disparity.shape
    rows, cols = np.mgrid[0:height, 0:width].astype(np.float64)
    cols += direction * disparity
    planes = image[..., None] if image.ndim == 2 else image
    out = np.empty(planes.shape, np.float64)
    for c in range(planes.shape[-1]):
        out[..., c] = map_coordinates(
            planes[..., c].astype(np.float64), [rows, cols], order=1, mode="nearest"
        )
    return out.reshape(image.shape)


def prediction_error(image: np.ndarray, other: OtherView, *, border: int) -> float:
    """:func:`trimmed_error` of the other view's blurred frame predicted from ``image``."""
    predicted = other.operator.forward(warp_to_other(image, other.disparity, other.direction))
    return trimmed_error(predicted, other.blurred, border=border)


def inner(array, border: int) -> np.ndarray:
    """``array`` without ``border`` px on every side."""
    array = np.asarray(array)
    return array[border : array.shape[0] - border, border : array.shape[1] - border]


def pixel_errors(predicted, observed, *, border: int) -> np.ndarray:
    """Squared error per pixel (mean over channels), float64, ``border`` px excluded."""
    error = (np.asarray(predicted, np.float64) - np.asarray(observed, np.float64)) ** 2
    return inner(error.mean(axis=-1) if error.ndim == 3 else error, border)


def trimmed_error(predicted, observed, *, border: int, keep: float = CROSS_VIEW_KEEP) -> float:
    """Mean of the ``keep`` smallest :func:`pixel_errors`."""
    error = np.sort(pixel_errors(predicted, observed, border=border), axis=None)
    return float(error[: max(1, int(keep * error.size))].mean())


def candidates(rule: str, floor: float) -> tuple[float, ...]:
    """The alphas ``rule`` solves at, in this order: for ``'cross-view'`` the grid
    :data:`~stereodeblur.settings.CROSS_VIEW_ALPHAS`; for ``'held-out'`` ``floor`` (the
    ``'auto'`` alpha) and the grid alphas above it."""
    if rule == "held-out":
        return (floor, *(a for a in CROSS_VIEW_ALPHAS if a > floor))
    return CROSS_VIEW_ALPHAS


def tied(errors) -> list[int]:
    """Indices of the prediction errors within :data:`HELD_OUT_TIE` of the least."""
    least = min(errors)
    return [k for k, error in enumerate(errors) if error <= (1.0 + HELD_OUT_TIE) * least]


def searched(rule: str, errors, alphas) -> bool:
    """Whether ``rule`` needs no further candidate after these prediction errors of the
    candidates ``alphas``: ``'held-out'`` stops once the last error is more than
    :data:`HELD_OUT_STOP` above the least (it searches past a smaller bump) and the last alpha
    is at least :data:`HELD_OUT_SPAN` times the least's (a larger alpha that fits the view's
    own frame better shows the least's solve ringing, :func:`undominated`)."""
    if rule != "held-out":
        return False
    least = int(np.argmin(errors))
    risen = errors[-1] > (1.0 + HELD_OUT_STOP) * errors[least]
    return risen and alphas[-1] >= HELD_OUT_SPAN * alphas[least] * (1 - 1e-9)


def choose(errors, rule: str = "cross-view", alphas=()) -> int:
    """Index of the chosen alpha among the candidates solved (``alphas``): for
    ``'held-out'`` the one nearest the paper's alpha (in log alpha; the larger on a tie)
    among the predictors :func:`tied` with the best, for ``'cross-view'``
    :data:`CROSS_VIEW_STEP` above the best predictor, within the grid."""
    if rule == "held-out":
        return min(tied(errors), key=lambda k: (abs(np.log(alphas[k] / PAPER_ALPHA)), -k))
    return min(int(np.argmin(errors)) + CROSS_VIEW_STEP, len(errors) - 1)


def own_error(image: np.ndarray, operator, blurred: np.ndarray, *, border: int) -> float:
    """Mean squared error per pixel (over channels) of the view's own blurred frame
    ``blurred`` predicted from ``image`` by its ``operator``, ``border`` px excluded."""
    return float(pixel_errors(operator.forward(image), blurred, border=border).mean())


def undominated(alphas, own) -> list[int]:
    """Indices of the candidates that no larger alpha dominates: candidate ``k`` is dropped if
    a larger alpha's solution fits the view's own blurred frame at least as well (its
    :func:`own_error` in ``own`` no larger). Such a ``k`` buys neither fit nor regularity; its
    solve did not reach what the smaller alpha is for (ringing, the range guard, clipping)."""
    return [
        k
        for k, (alpha, error) in enumerate(zip(alphas, own, strict=True))
        if not any(a > alpha and e <= error for a, e in zip(alphas, own, strict=True))
    ]


def observed_error(image: np.ndarray, observation: Observation, *, border: int) -> float:
    """Mean squared error per pixel (over channels) of ``observation``'s blurred frame
    predicted from ``image``, over the pixels it sees with a data weight of at least
    :data:`HELD_OUT_MIN_WEIGHT`, ``border`` px excluded; inf if there are none."""
    predicted = observation.operator.forward(image)
    error = pixel_errors(predicted, observation.blurred, border=border)
    counted = inner(observation.weights, border) >= HELD_OUT_MIN_WEIGHT
    return float(error[counted].mean()) if counted.any() else float("inf")


def held_out_error(image: np.ndarray, observations, *, border: int) -> float:
    """Sum of the :func:`observed_error` of every observation in ``observations`` (the other
    view's and the neighbouring frames' observations of this view): what ``'held-out'``
    scores an estimated motion's candidates by where the neighbouring frames are observed."""
    return sum(observed_error(image, o, border=border) for o in observations)


def below_floor(floor: float, error: float, sigma: float) -> tuple[float, ...]:
    """The alphas ``'held-out'`` tries below its ``floor`` (the noise rule's alpha raised by
    the motion's trust) when the floor predicts best with :func:`observed_error` ``error``,
    from the top: the grid alphas between the noise rule's alpha (from ``sigma``) and the
    floor, then the noise rule's; none unless ``error`` is within
    :data:`HELD_OUT_NOISE_RATIO` of the two views' noise ``2 sigma^2``."""
    noise = alpha_from_sigma(sigma)
    if noise >= floor or error >= HELD_OUT_NOISE_RATIO * 2.0 * sigma**2:
        return ()
    return (*(a for a in reversed(CROSS_VIEW_ALPHAS) if noise < a < floor), noise)


LOCAL_MIN_SHARE = 0.1
"""Least share of a window an observation must count for :func:`local_error` to score it."""


def local_error(image: np.ndarray, observations, *, window: float, border: int) -> np.ndarray:
    """Per pixel, the sum over ``observations`` of the mean squared error of its blurred frame
    predicted from ``image`` around the pixel (Gaussian window of ``window`` px over the
    pixels it sees with a data weight of at least :data:`HELD_OUT_MIN_WEIGHT`, ``border`` px
    excluded): :func:`held_out_error` made local. NaN where an observation counts less than
    :data:`LOCAL_MIN_SHARE` of the window."""
    total = np.zeros(image.shape[:2])
    for o in observations:
        error = np.zeros(total.shape)
        inner(error, border)[...] = pixel_errors(
            o.operator.forward(image), o.blurred, border=border
        )
        counted = np.zeros(total.shape)
        inner(counted, border)[...] = inner(o.weights, border) >= HELD_OUT_MIN_WEIGHT
        share = gaussian_filter(counted, window)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = gaussian_filter(error * counted, window) / share
        total += np.where(share >= LOCAL_MIN_SHARE, mean, np.nan)
    return total


def local_scale(alphas, errors, chosen: float, *, window: float) -> np.ndarray:
    """Per-pixel factor of the ``chosen`` alpha, float32: at each pixel the candidate of
    ``alphas`` whose :func:`local_error` (``errors``, one map per candidate; inf where a
    candidate is not allowed) is least, its log smoothed by the same Gaussian ``window``; 1
    where no candidate is scored (NaN)."""
    errors = np.asarray(errors)
    scored = ~np.isnan(errors).any(axis=0)
    best = np.argmin(np.where(np.isnan(errors), np.inf, errors), axis=0)
    logs = np.where(scored, np.log(np.asarray(alphas, np.float64))[best], np.log(chosen))
    return np.exp(gaussian_filter(logs, window) - np.log(chosen)).astype(np.float32)


def local_terms(terms, runs, run, scorers, noise_sigma: float, *, border: int):
    """The chosen candidate's data ``terms`` with the per-pixel factor of their alpha
    (``local_alpha``): from the solved candidates ``runs`` (each with ``.terms`` and ``.image``)
    no smaller than the chosen alpha, on a frame of noise ``noise_sigma`` of at least
    :data:`LOCAL_ALPHA_NOISE` down to :data:`LOCAL_ALPHA_DOWN` times less (the grid alphas
    missing there solved by ``run(alpha)``), scored by the held-out observations ``scorers``
    around each pixel (:func:`local_error`, :func:`local_scale`). Below the chosen alpha only
    where the motion explains them: where the chosen solution predicts each within
    :data:`HELD_OUT_NOISE_RATIO` times 2 ``noise_sigma`` squared (the noise gate of
    :func:`below_floor`, made local)."""
    window = LOCAL_ALPHA_WINDOW * terms.weights.shape[1]
    noisy = noise_sigma >= LOCAL_ALPHA_NOISE
    least = (terms.alpha / LOCAL_ALPHA_DOWN if noisy else terms.alpha) * (1 - 1e-9)
    lowest = min(r.terms.alpha for r in runs)
    runs = [r for r in runs if r.terms.alpha >= least]
    runs += [run(a) for a in CROSS_VIEW_ALPHAS if least <= a < lowest]
    errors = [local_error(r.image, scorers, window=window, border=border) for r in runs]
    alphas = [r.terms.alpha for r in runs]
    explained = errors[alphas.index(terms.alpha)] <= (
        HELD_OUT_NOISE_RATIO * 2.0 * noise_sigma**2 * len(scorers)
    )
    errors = [
        e if a >= terms.alpha else np.where(explained, e, np.inf)
        for a, e in zip(alphas, errors, strict=True)
    ]
    return replace(terms, alpha_scale=local_scale(alphas, errors, terms.alpha, window=window))
