"""Solve one view: Eq. 6 by IRLS with its data terms, and the range guard after it."""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..deconv.irls import DeblurResult, deblur_irls
from ..progress import ProgressCallback, report
from ..settings import OBSERVATION_ROBUST_SCALE
from .observations import without_pixels

if TYPE_CHECKING:
    from ..settings import DeblurSettings
    from .weights import DataTerms


def solve(
    blurred: np.ndarray,
    operator,
    terms: DataTerms,
    settings: DeblurSettings,
    *,
    weights: np.ndarray | None = None,
    observations=(),
    progress: ProgressCallback | None = None,
) -> DeblurResult:
    """Eq. 6 by IRLS (:func:`~stereodeblur.deconv.irls.deblur_irls`) with ``terms``.

    ``weights`` replaces ``terms.weights`` as the initial data weights; ``observations``
    (:class:`~.observations.NamedObservation`) are further data terms, weighted by their
    residual and summed with the view's own at the same alpha; ``progress`` gets
    ``Progress('IRLS', done, total)`` after every IRLS iteration.
    """
    return deblur_irls(
        blurred,
        operator,
        weights=terms.weights if weights is None else weights,
        alpha=terms.alpha,
        alpha_scale=terms.alpha_scale,
        num_irls=settings.num_irls,
        num_cg=settings.num_cg,
        update_weights=terms.update,
        anchor=terms.anchor,
        observations=[o.observation for o in observations],
        robust_scale=OBSERVATION_ROBUST_SCALE if observations else None,
        progress=progress,
    )


def guarded_solve(
    blurred, operator, terms, settings, weights, observations, progress, rejected=None
):
    """``(result, unexplained)``: :func:`solve` with ``operator``'s operator; with
    ``settings.range_guard``, where that result leaves [0, 1] over a whole region
    (:func:`unexplained`), solved once more with no motion there, data weight 1 and the
    further observations that see it dropped (``unexplained`` None where the guard did not
    act). ``rejected``: a region the guard has already taken from the motion (at another
    alpha), solved with no motion at once."""
    if rejected is None:
        result = solve(
            blurred,
            operator.operator,
            terms,
            settings,
            weights=weights,
            observations=observations,
            progress=progress,
        )
        rejected = unexplained(result.image) if settings.range_guard else None
        if rejected is None:
            return result, None
    result = _without_motion_solve(
        blurred, operator, terms, settings, weights, observations, rejected, progress
    )
    return result, rejected


def unexplained(image: np.ndarray) -> np.ndarray | None:
    """The range guard's region of the estimate ``image``
    (:func:`~stereodeblur.deconv.intensity_range.unexplained_regions` with the settings'
    ``RANGE_*`` constants), or None if it is empty."""
    from .. import settings as constants  # read at call time, so that a study can vary them
    from ..deconv.intensity_range import unexplained_regions

    region = unexplained_regions(
        image,
        excess=constants.RANGE_EXCESS,
        window=constants.RANGE_WINDOW,
        share=constants.RANGE_SHARE,
        area=constants.RANGE_AREA,
        whole=constants.RANGE_WHOLE,
    )
    return region if region.any() else None


def _without_motion_solve(
    blurred, operator, terms, settings, weights, observations, region, progress
):
    """:func:`solve` with no motion in ``region`` (the guard's), data weight 1 and the further
    observations that see it dropped there."""
    from ..blur.operator import without_motion

    report(progress, f"range guard: {region.mean():.1%} of the pixels with no motion")
    update = copy.deepcopy(terms.update)  # may have been used by a solve: start afresh
    if update is not None:
        update.history.clear()
    start = terms.weights if weights is None else weights
    return solve(
        blurred,
        without_motion(operator.operator, region),
        replace(terms, update=update),
        settings,
        weights=np.where(region, 1.0, start).astype(np.float32),
        observations=tuple(without_pixels(o, region) for o in observations),
        progress=progress,
    )
