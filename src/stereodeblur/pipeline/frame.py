"""Deblur one frame: window -> motion -> operator -> data terms -> solve.

:func:`deblur_stereo_frame` reads the frame window once and computes the motion once for
both views; :func:`deblur_frame` is the same for one view.
"""

from __future__ import annotations

import copy
import time
import warnings
from dataclasses import replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..deconv.irls import DeblurResult
from ..deconv.noise import alpha_from_sigma
from ..errors import FrameWarning, InputError
from ..evaluation.metrics import border_for
from ..progress import ProgressCallback, prefixed, report
from ..settings import CROSS_VIEW_ALPHAS, PAPER_ALPHA, DeblurSettings
from .alpha import (
    OtherView,
    below_floor,
    candidates,
    choose,
    held_out_error,
    local_alpha_here,
    local_terms,
    observed_error,
    other_view,
    own_error,
    prediction_error,
    searched,
    true_motion_choice,
    undominated,
)
from .deconvolve import guarded_solve
from .exposure import exposed_window
from .motion import FrameMotion, check_motion, stereo_motion
from .observations import (
    NEIGHBOURS,
    NamedObservation,
    other_view_observation,
    view_observations,
    weighed_neighbours,
)
from .operator import view_operator
from .results import FrameResult, StereoFrameResult
from .weights import DataTerms, data_terms, gate_trusts
from .window import (
    VIEWS,
    FrameWindow,
    check_gt,
    check_views,
    observation_kinds,
    predicts_other_view,
    read_window,
    uses_boundary_flow,
    views_read,
)

if TYPE_CHECKING:
    from ..io.protocol import StereoScene
    from ..sceneflow.model import SceneFlow


def build_view_operator(window: FrameWindow, motion: FrameMotion, settings: DeblurSettings):
    """:func:`~.operator.view_operator` of ``motion``, gated by the trusts measured on
    ``window`` with ``boundary_weights='gated'``."""
    trusts = None
    gated = settings.boundary_weights == "gated" and uses_boundary_flow(settings)
    if gated and motion.boundary_flow is not None:
        from ..deconv.noise import estimate_noise_sigma

        sigma = estimate_noise_sigma(window.blurred(motion.view))
        trusts = gate_trusts(window, motion.view, motion, noise_sigma=sigma)
    return view_operator(motion, window.exposure, settings, trusts=trusts)


def deblur_view(
    scene: StereoScene,
    window: FrameWindow,
    motion: FrameMotion,
    settings: DeblurSettings,
    *,
    weights: np.ndarray | None = None,
    timings: dict | None = None,
    progress: ProgressCallback | None = None,
    operator=None,
    other: OtherView | None = None,
    terms: DataTerms | None = None,
    observations: tuple[NamedObservation, ...] = (),
) -> FrameResult:
    """Deblur one view of ``window`` with its ``motion``: operator, data terms, solve.

    ``timings``: seconds of the stages before (the motion's), kept in the result's.
    ``operator``: the view's :class:`~.operator.ViewOperator`, if already built;
    ``other``: the other view, which ``alpha='cross-view'`` predicts; ``terms``: the view's
    :class:`~.weights.DataTerms`, if already computed; ``observations``: further data terms
    (:func:`~.observations.view_observations`).
    """
    view, timings = motion.view, dict(timings or {})
    check_motion(motion, window, view)
    if window.exposure.exposure == 0:
        return _passed_through(window, motion, timings)
    if operator is None:
        start = time.perf_counter()
        report(progress, f"blur operator ({settings.kernels})")
        operator = build_view_operator(window, motion, settings)
        timings["operator"] = time.perf_counter() - start
    start = time.perf_counter()  # the data terms count as part of the deconvolution
    blurred = window.blurred(view)
    if settings.alpha == "cross-view" and other is None:
        raise InputError("alpha='cross-view' needs the other view", parameter="alpha")
    if settings.alpha in ("cross-view", "held-out") and other is not None:
        terms, result, unexplained = _alpha_choice_solve(
            scene,
            window,
            view,
            blurred,
            operator,
            settings,
            other,
            weights,
            observations,
            progress,
            terms,
        )
    else:
        terms = terms or data_terms(scene, window, view, operator, settings)
        observations = _judged(blurred, operator, terms, settings, weights, observations, progress)
        result, unexplained = guarded_solve(
            blurred, operator, terms, settings, weights, observations, progress
        )
    if unexplained is not None:
        warnings.warn(
            f"frame {scene.numbering.number(window.index)} {view}: the motion cannot explain "
            f"{unexplained.mean():.0%} of the pixels (the estimate leaves [0, 1] there); "
            "deblurred with no motion there (range guard)",
            FrameWarning,
            stacklevel=2,
        )
    timings["deconvolution"] = time.perf_counter() - start
    return FrameResult(
        window.index,
        view,
        blurred,
        result,
        operator.motion,
        timings,
        terms.alpha,
        terms.steps,
        terms.trust,
        tuple(o.name for o in observations),
        unexplained,
        terms.alpha_scale,
        window.exposure.exposure,
    )


def _passed_through(window: FrameWindow, motion: FrameMotion, timings: dict) -> FrameResult:
    """The result of a sharp frame (exposure 0): the blurred frame itself."""
    blurred = window.blurred(motion.view)
    image = np.array(blurred, dtype=np.float32)
    result = DeblurResult(image, np.ones(blurred.shape[:2], np.float32), ())
    return FrameResult(window.index, motion.view, blurred, result, motion, timings, exposure=0.0)


def _judged(blurred, operator, terms, settings, weights, observations, progress):
    """``observations`` with the neighbouring frames weighed against the other view's
    observation among them (:func:`~.observations.weighed_neighbours`) by the view's own
    solution at ``terms``' alpha, solved for it; unchanged without both."""
    names = {o.name for o in observations}
    if "other-view" not in names or not names & set(NEIGHBOURS):
        return observations
    own = replace(terms, update=copy.deepcopy(terms.update))
    single, _ = guarded_solve(blurred, operator, own, settings, weights, (), progress)
    reference = next(o.observation for o in observations if o.name == "other-view")
    image = np.clip(single.image, 0.0, 1.0)
    return _weighed(observations, image, reference, border_for(blurred.shape[1]), progress)


def _weighed(observations, image, reference, border, progress):
    """:func:`~.observations.weighed_neighbours`, each scale reported."""
    observations, scales = weighed_neighbours(observations, image, reference, border=border)
    for name, scale in scales.items():
        report(progress, f"{name} frame weighed {scale:.2g}")
    return observations


def _choice_settings(settings: DeblurSettings) -> DeblurSettings:
    """``settings`` with the alpha its data terms are computed at before an alpha choice:
    ``'auto'`` for ``'held-out'`` (its floor), the first grid alpha for ``'cross-view'``."""
    if settings.alpha == "held-out":
        return replace(settings, alpha="auto")
    if settings.alpha == "cross-view":
        return replace(settings, alpha=CROSS_VIEW_ALPHAS[0])
    return settings


class _Candidate(NamedTuple):
    """One alpha of a choice: its data terms, its (range-guarded) result, the guard's region
    (or None), the result clipped to [0, 1], which the choice scores, and that image's
    :func:`.alpha.own_error` in the view's own blurred frame."""

    terms: DataTerms
    result: DeblurResult
    unexplained: np.ndarray | None
    image: np.ndarray
    own: float


def _alpha_choice_solve(
    scene, window, view, blurred, operator, settings, other, weights, observations, progress, base
):
    """Solve at the candidate alphas of ``settings.alpha`` from the view's own blurred frame
    and keep the one chosen by predicting ``other`` (:func:`.alpha.candidates`,
    :func:`.alpha.searched`, :func:`.alpha.choose`; below the floor only through the noise
    gate, :func:`.alpha.below_floor`; with the true motion from the noise rule's alpha up,
    scored by the other view's observation, :func:`.alpha.true_motion_choice`; with an
    estimated motion and the neighbouring frames observed, by :func:`.alpha.held_out_error`); with
    ``observations``, solve once more with them at that alpha (the other view is then held
    out of the choice even where it is observed), the neighbouring frames weighed by how well
    the chosen estimate predicts them (:func:`~.observations.weighed_neighbours`). Every
    solution is range-guarded (:func:`~.deconvolve.guarded_solve`) before it is scored, so
    that the choice judges what the view's result would be; with an estimated motion the
    guard's first verdict that takes the whole view, at a candidate up to the paper's alpha
    (solved for it if the floor is above), holds for every larger candidate. ``base``: the data
    terms at :func:`_choice_settings`, if already computed. Returns the data terms, the result
    and the region the guard deblurred with no motion (or None)."""
    rule = settings.alpha
    fixed = _choice_settings(settings)
    if base is None:
        base = data_terms(scene, window, view, operator, fixed)
    border = border_for(blurred.shape[1])

    solved, rejected, rejected_from = {}, None, PAPER_ALPHA  # the guard's carried verdict

    def run(alpha) -> _Candidate:
        region = rejected if alpha > rejected_from else None
        key = (alpha, region is not None)
        if key not in solved:
            report(progress, f"alpha {alpha:g}")
            terms = replace(base, alpha=alpha, update=copy.deepcopy(base.update))
            result, unexplained = guarded_solve(
                blurred, operator, terms, fixed, weights, (), progress, region
            )
            image = np.clip(result.image, 0.0, 1.0)
            own = own_error(image, operator.operator, blurred, border=border)
            solved[key] = _Candidate(terms, result, unexplained, image, own)
        return solved[key]

    observed = true_motion_choice(settings) and other.observation is not None
    floor = alpha_from_sigma(base.noise_sigma) if observed else base.alpha
    judged = settings.range_guard and not observed
    if judged and floor > PAPER_ALPHA:
        rejected = _whole_view(run(PAPER_ALPHA).unexplained)

    held = [o.observation for o in observations if o.name in NEIGHBOURS]
    if held and other.observation is not None:
        held.append(other.observation)

    def score(image) -> float:
        if observed:
            return observed_error(image, other.observation, border=border)
        if len(held) > 1:
            return held_out_error(image, held, border=border)
        return prediction_error(image, other, border=border)

    runs, errors, alphas = [], [], []
    for alpha in candidates(rule, floor):
        runs.append(run(alpha))
        if judged and alpha <= PAPER_ALPHA and rejected is None:
            rejected, rejected_from = _whole_view(runs[-1].unexplained), alpha
        errors.append(score(runs[-1].image))
        alphas.append(alpha)
        if searched(rule, errors, alphas):
            break
    kept = undominated(alphas, [r.own for r in runs]) if rule == "held-out" else range(len(runs))
    best = kept[choose([errors[k] for k in kept], rule, [alphas[k] for k in kept])]
    chosen = runs[best]
    if rule == "held-out" and best == 0 and other.observation is not None:
        gated = [observed_error(chosen.image, other.observation, border=border)]
        for alpha in below_floor(base.alpha, gated[0], base.noise_sigma):
            below = run(alpha)
            gated.append(observed_error(below.image, other.observation, border=border))
            runs.append(below)
            if gated[-1] >= gated[-2] or below.own >= chosen.own:
                break
            chosen = below
    terms, result, unexplained, image, _ = chosen
    scorers = [other.observation] if observed else held if len(held) > 1 else []
    if local_alpha_here(settings, base.noise_sigma) and scorers:
        terms = local_terms(terms, runs, run, scorers, base.noise_sigma, border=border)
    if observations or terms.alpha_scale is not None:
        if observations and other.observation is not None:
            observations = _weighed(observations, image, other.observation, border, progress)
        varying = " varying over the view" if terms.alpha_scale is not None else ""
        further = " with the further observations" if observations else ""
        report(progress, f"alpha {terms.alpha:g}{varying}{further}")
        terms = replace(terms, update=copy.deepcopy(base.update))
        result, unexplained = guarded_solve(
            blurred,
            operator,
            terms,
            fixed,
            weights,
            observations,
            progress,
            rejected if terms.alpha > rejected_from else None,
        )
    return terms, result, unexplained


def _whole_view(unexplained: np.ndarray | None) -> np.ndarray | None:
    """``unexplained`` if the range guard took the whole view from the motion, else None."""
    return unexplained if unexplained is not None and unexplained.all() else None


def needs_stereo_pass(settings: DeblurSettings) -> bool:
    """Whether a view's deblurring computes the motion itself (:func:`deblur_frame` then
    refuses a given motion, or with ``alpha='held-out'`` takes ``'auto'``): an alpha that
    predicts the other view or further observations."""
    return predicts_other_view(settings) or bool(observation_kinds(settings))


def deblur_frame(
    scene: StereoScene,
    index: int,
    *,
    view: str = "left",
    settings: DeblurSettings | None = None,
    weights: np.ndarray | None = None,
    motion: FrameMotion | None = None,
    progress: ProgressCallback | None = None,
) -> FrameResult:
    """Deblur frame ``index`` of ``view`` of an open scene.

    ``weights`` replaces the initial data weights chosen by ``settings``; ``motion``
    (from :func:`~.motion.frame_motion` with the same settings) skips the motion
    estimation; with either, ``alpha='held-out'`` is ``'auto'`` and the view has its single
    observation (the other view and the neighbours' motion are not known).
    Reports progress as ``"frame {number} {view}: ..."`` (the source's number of frame
    ``index``, :mod:`stereodeblur.io.numbering`).
    """
    settings = settings or DeblurSettings()
    (view,) = check_views((view,))
    if motion is not None or weights is not None:  # one view's: the other view is not known
        alpha = "auto" if settings.alpha == "held-out" else settings.alpha
        settings = replace(settings, alpha=alpha, observations="single")
    if needs_stereo_pass(settings):
        if motion is not None or weights is not None:  # it needs both views' motion
            raise InputError(
                "alpha='cross-view' computes the motion of both views itself: "
                "leave motion and weights unset (or use deblur_stereo_frame)",
                parameter="alpha",
            )
        stereo = deblur_stereo_frame(
            scene, index, views=(view,), settings=settings, progress=progress
        )
        return stereo.frames[view]
    if motion is not None and settings.exposure == "auto":
        raise InputError("exposure='auto' estimates the motion itself: leave motion unset")
    number = scene.numbering.number(index)
    progress = prefixed(progress, f"frame {number} {view}: ")
    start = time.perf_counter()
    check_gt(scene, index, settings, (view,), motion=motion is None)
    window = read_window(scene, index, (view,), settings, motion=motion is None)
    timings = {}
    if motion is None:
        window, _, dense = exposed_window(window, (view,), settings, progress, f"frame {number}")
        timings["exposure"] = time.perf_counter() - start
        report(progress, f"motion ({settings.motion_source})")
        stereo = stereo_motion(scene, window, (view,), settings, dense=dense, progress=progress)
        motion = stereo.views[view]
    timings["motion"] = time.perf_counter() - start - timings.get("exposure", 0.0)
    return deblur_view(
        scene, window, motion, settings, weights=weights, timings=timings, progress=progress
    )


def deblur_stereo_frame(
    scene: StereoScene,
    index: int,
    *,
    views=VIEWS,
    settings: DeblurSettings | None = None,
    sceneflow: SceneFlow | None = None,
    progress: ProgressCallback | None = None,
) -> StereoFrameResult:
    """Deblur frame ``index`` of every view in ``views``, reading each frame and computing
    the motion once.

    Each view's image equals :func:`deblur_frame`'s. ``sceneflow``: the left view's scene
    flow towards the frame's neighbour (e.g. saved by ``stereodeblur sceneflow``), used
    instead of an estimate (``motion_source='sceneflow'``). Reports progress as
    ``"frame {number}: motion ..."`` and ``"frame {number} {view}: ..."`` (the source's number
    of frame ``index``, :mod:`stereodeblur.io.numbering`).
    """
    settings = settings or DeblurSettings()
    views = check_views(views)
    cross_view = predicts_other_view(settings)
    kinds = observation_kinds(settings)
    needed = views_read(settings, views)
    timings = {}
    label = f"frame {scene.numbering.number(index)}"
    start = time.perf_counter()
    check_gt(scene, index, settings, needed)
    window = read_window(scene, index, needed, settings, estimate=sceneflow is None)
    timings["read"] = time.perf_counter() - start
    start = time.perf_counter()
    progress_of = prefixed(progress, f"{label}: ")
    window, exposure, dense = exposed_window(window, needed, settings, progress_of, label)
    timings["exposure"] = time.perf_counter() - start
    start = time.perf_counter()
    report(progress, f"{label}: motion ({settings.motion_source})")
    motion = stereo_motion(
        scene,
        window,
        needed,
        settings,
        sceneflow=sceneflow,
        dense=dense,
        progress=prefixed(progress, f"{label}: "),
    )
    timings["motion"] = time.perf_counter() - start
    share = {
        "exposure": timings["exposure"] / len(views),
        "motion": (timings["read"] + timings["motion"]) / len(views),
    }
    if window.exposure.exposure == 0:  # sharp frames pass through
        frames = {v: _passed_through(window, motion.views[v], share) for v in views}
        return StereoFrameResult(index, frames, motion, timings, exposure)
    operators, seconds, terms = {}, {}, {}
    if cross_view or kinds:  # every operator first: the views use each other's
        for view in needed:
            start = time.perf_counter()
            report(progress, f"{label} {view}: blur operator ({settings.kernels})")
            operators[view] = build_view_operator(window, motion.views[view], settings)
            seconds[view] = {"operator": time.perf_counter() - start}
    if cross_view or "other-view" in kinds:  # a view's data weights weigh it as the other's
        fixed = _choice_settings(settings)  # observation
        terms = {v: data_terms(scene, window, v, operators[v], fixed) for v in needed}
    weights = {v: t.weights for v, t in terms.items()}
    frames = {}
    for view in views:
        start = time.perf_counter()
        seen = other = None  # this view's observation by the other view; what its choice predicts
        if cross_view or "other-view" in kinds:
            theirs = next(v for v in VIEWS if v != view)
            own, blurred = motion.views[view].sceneflow, window.blurred(theirs)
            if own is not None and motion.views[theirs].sceneflow is not None:
                seen = other_view_observation(own, operators[theirs], blurred, weights[theirs])
            if cross_view:
                other = other_view(operators[theirs], motion.views[theirs], blurred, theirs, seen)
        observations = view_observations(
            window, view, motion.views, operators, weights, settings, other=seen
        )
        if kinds:
            seconds[view]["observations"] = time.perf_counter() - start
        frames[view] = deblur_view(
            scene,
            window,
            motion.views[view],
            settings,
            timings=share | seconds.get(view, {}),
            progress=prefixed(progress, f"{label} {view}: "),
            operator=operators.get(view),
            other=other,
            terms=terms.get(view),
            observations=tuple(observations),
        )
        del seen, other, observations  # freed before the next view's are built (peak memory)
    return StereoFrameResult(index, frames, motion, timings, exposure)
