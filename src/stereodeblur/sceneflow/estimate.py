"""Piecewise-rigid scene flow from two blurred stereo frames, in the spirit of PRSF.

Vogel, Schindler & Roth (IJCV 2015) model the scene as planar segments moving
rigidly; the paper (Sec. 3) takes its planes, motions and occlusions from it.
This estimator follows the same model in stages:

1. census descriptors of the four images (:mod:`preparation`, :mod:`census`), robust
   to blur and gain,
   with "similar" bands relative to the brightness (dark texture counts) and
   above the estimated sensor noise (noise does not pass for texture);
2. initial disparity at t and t + 1 by semi-global matching and initial optical
   flow (left view, t -> t + 1, and back) by DIS (:mod:`initial`);
3. SLIC superpixels of the left view at t, about 1200 at 640x480
   (:mod:`superpixels`);
4. proposals (:mod:`candidates`): per segment a robust plane fit to the
   disparities and a robust rigid-motion fit to the correspondences; the
   dominant motion (the camera's own motion) with every segment's plane; and
   global proposals (sequential RANSAC over the segments' proposals: a plane
   with its motion that explains a large part of the image, refitted on all its
   pixels);
5. fusion (:mod:`selection`, :mod:`data_term`, :mod:`fusion`): each segment picks its own, a
   neighbour's or a global proposal by the 4-view census cost plus a truncated
   smoothness term (weaker across contrast edges), by alpha-expansion over the
   segment adjacency graph; regions of segments that picked the same proposal are
   then refitted as one and offered again to their neighbours (twice);
6. continuous refinement of every chosen plane and motion (9 parameters, shared
   by the segments that chose it) on the images (:mod:`refine`); if the exposure
   is given and the blur's length changes strongly between the frames (a fast
   approach), once more on images whose blur has been balanced (each frame
   blurred by the other frame's predicted motion, :func:`blur_balance.cross_blur`);
7. occlusion, out-of-view and motion-boundary masks (:mod:`occlusion`).

Every tuning constant is a field of :class:`~stereodeblur.sceneflow.settings.SceneFlowSettings`
(fits and the data term use pixels on a 2-pixel grid from 200,000 pixels on).
Matching blurred frames directly has a limit: under strong blur that changes
between the frames (a near plane approaching fast), the estimate is biased;
balancing the blur (needs ``exposure``) reduces the bias
(``docs/defaults.md#blur-balancing``).

Conventions are the package's: left reference view at frame t, pixel centres at
integer coordinates, planes ``P^T n = 1`` in left-camera coordinates at t,
twists from t to t + 1. Input images are float in [0, 1], grey or RGB.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure, StereoCamera
from ..geometry.plane import plane_from_disparity_coefficients
from ..progress import ProgressCallback, report
from .blur_balance import blur_length_change, cross_blur
from .candidates import fit_pixels, keep_in_front, segment_proposals
from .census import census_cost
from .fusion import ProposalSet
from .initial import InitialMatches, initial_matches
from .model import SceneFlow
from .occlusion import OcclusionMasks, occlusion_masks
from .prediction import predict
from .preparation import PreparedFrames, prepare_frames
from .refine import refine_proposals
from .selection import Selection, select_proposals
from .settings import SceneFlowSettings
from .superpixels import SegmentGraph, default_num_segments, segment_graph, slic_segments

__all__ = ["SceneFlowEstimate", "SceneFlowWarning", "estimate_scene_flow"]

STAGES = (
    "census",
    "initial",
    "superpixels",
    "proposals",
    "fusion",
    "regions",
    "refine",
    "occlusion",
)


class SceneFlowWarning(UserWarning):
    """The input gives the scene flow little to work with (textureless, no overlap, ...)."""


@dataclass(frozen=True)
class SceneFlowEstimate:
    """Estimated scene flow and the initial correspondences it started from.

    Parameters
    ----------
    sceneflow : SceneFlow
        Segments of the left view at t with planes, motions and occlusion.
    initial_flow : ndarray, shape (H, W, 2), float32
        DIS optical flow of the left view, t -> t + 1 (the paper's "initial optical flow").
    initial_disparity : ndarray, shape (H, W), float32
        Semi-global matching disparity at t, NaN in holes.
    initial_disparity_next : ndarray, shape (H, W), float32
        Semi-global matching disparity at t + 1 (in frame t + 1's pixels), NaN in holes.
    warnings : tuple of str
        Messages about degenerate input (also issued as :class:`SceneFlowWarning`).
    timings : dict
        Seconds per stage (:data:`STAGES`).
    diagnostics : dict
        ``matched_right_t``, ``matched_left_t1``, ``matched_right_t1``: share of the
        pixels whose census cost at the predicted position is below
        ``settings.match_cost``; ``dominant_inliers``: share of the pixels the dominant
        motion explains; ``num_proposals``: distinct plane+motion proposals in the
        result; ``num_global``: global proposals found; ``census_gamma``: the census's
        encoding (1 linear, 0.5 the square root: shot noise that would flatten the dark parts).
    """

    sceneflow: SceneFlow
    initial_flow: np.ndarray
    initial_disparity: np.ndarray
    initial_disparity_next: np.ndarray
    warnings: tuple[str, ...] = ()
    timings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ChosenMotion:
    """Stage 6's result: the refined proposals, each segment's among them, and per segment
    its plane (disparity coefficients, in front of the camera), normal and twist."""

    proposals: ProposalSet
    segment_proposal: np.ndarray
    abc: np.ndarray
    normals: np.ndarray
    twists: np.ndarray


class _Stages:
    """Seconds per stage, and a progress report after each."""

    def __init__(self, progress: ProgressCallback | None):
        self.progress = progress
        self.timings: dict[str, float] = {}
        self._t = time.perf_counter()

    def done(self, stage: str) -> None:
        now = time.perf_counter()
        self.timings[stage] = self.timings.get(stage, 0.0) + now - self._t
        self._t = now
        report(self.progress, f"scene flow: {stage}", STAGES.index(stage) + 1, len(STAGES))


def estimate_scene_flow(
    left_t: np.ndarray,
    right_t: np.ndarray,
    left_next: np.ndarray,
    right_next: np.ndarray,
    camera: StereoCamera,
    *,
    settings: SceneFlowSettings = SceneFlowSettings(),  # noqa: B008 (frozen)
    seed: int = 0,
    exposure: Exposure | None = None,
    progress: ProgressCallback | None = None,
    num_segments: int | None = None,
    debug_dir: str | Path | None = None,
    other_side: tuple[np.ndarray, np.ndarray] | None = None,
) -> SceneFlowEstimate:
    """Estimate a piecewise-rigid scene flow of the left view from frame t to t + 1.

    Parameters
    ----------
    left_t, right_t, left_next, right_next : ndarray, shape (H, W) or (H, W, 3)
        Rectified (possibly motion-blurred) frames t and t + 1, float in [0, 1].
    camera : StereoCamera
    settings : SceneFlowSettings
        Tuning constants (:mod:`stereodeblur.sceneflow.settings`).
    seed : int
        Seed of the random choices (RANSAC samples, expansion order).
    exposure : Exposure, optional
        Frame rate and exposure time. If given and the estimated blur changes
        between the frames (a fast approach), the refinement is repeated on
        images whose blur has been balanced (:func:`blur_balance.cross_blur`).
    progress : callable, optional
        Receives a :class:`~stereodeblur.progress.Progress` after every stage
        (``"scene flow: <stage>"``, stages done, number of stages).
    num_segments : int, optional
        Overrides ``settings.num_segments`` where given.
    debug_dir : path, optional
        Folder for debug pictures (segments, disparity, flow, occlusion).
    other_side : tuple of 2 ndarray, optional
        Left and right frames on the other side of t (t - 1), as the four frames; used where
        ``settings.other_side`` (what leaves the view at t + 1 is matched there).

    Returns
    -------
    SceneFlowEstimate
        Degenerate input (textureless, black, identical or unrelated frames)
        still gives a finite result; each problem is listed in ``warnings`` and
        issued as a :class:`SceneFlowWarning`.
    """
    images = (left_t, right_t, left_next, right_next)
    height, width = _check_images(images if other_side is None else (*images, *other_side))
    settings = _check_settings(camera, settings, num_segments)
    rng = np.random.default_rng(seed)
    stages = _Stages(progress)
    prepared = prepare_frames(images, settings, other_side if settings.other_side else None)
    stages.done("census")
    matches = initial_matches(prepared.u8)
    stages.done("initial")
    count = settings.num_segments or default_num_segments((height, width))
    graph = segment_graph(slic_segments(prepared.segment_image, count))
    stages.done("superpixels")
    pixels = fit_pixels(camera, graph, matches, settings)
    start = segment_proposals(camera, graph, pixels, settings, rng)
    stages.done("proposals")
    selection = select_proposals(
        camera,
        prepared.codes,
        prepared.normed[0],
        graph,
        pixels,
        start,
        settings,
        seed=seed,
        rng=rng,
        after_round=lambda k: stages.done("fusion") if k == 0 else None,
        other_side=prepared.other_side_codes,
    )
    stages.done("regions")
    chosen = refine_selection(camera, prepared, graph, selection, settings, exposure=exposure)
    stages.done("refine")
    matched = _matched_fractions(camera, prepared.codes, graph, chosen, pixels.step, settings)
    sceneflow, masks = _with_occlusion(camera, graph.labels, chosen, matches, settings)
    stages.done("occlusion")
    messages = _messages(prepared, matches, start, matched, settings)
    for message in messages:
        warnings.warn(message, SceneFlowWarning, stacklevel=2)
    if debug_dir is not None:
        _write_debug(Path(debug_dir), prepared.segment_image, sceneflow, matches, masks)
    return SceneFlowEstimate(
        sceneflow=sceneflow,
        initial_flow=matches.flow,
        initial_disparity=matches.disparity,
        initial_disparity_next=matches.disparity_next,
        warnings=tuple(messages),
        timings=dict(stages.timings),
        diagnostics={
            **{f"matched_{k}": v for k, v in matched.items()},
            **_counts(start, chosen),
            "census_gamma": prepared.census_gamma,
        },
    )


def refine_selection(
    camera: StereoCamera,
    prepared: PreparedFrames,
    graph: SegmentGraph,
    selection: Selection,
    settings: SceneFlowSettings,
    *,
    exposure: Exposure | None,
) -> ChosenMotion:
    """Stage 6: refine the chosen proposals on the images; if the exposure is given and the
    blur's length changes strongly from t to t + 1, once more on blur-balanced images."""
    used, chosen_local = np.unique(selection.chosen, return_inverse=True)
    props = selection.proposals
    final = ProposalSet(props.abc[used], props.R[used], props.T[used])
    groups = chosen_local[graph.labels]
    final = refine_proposals(
        camera,
        list(prepared.normed),
        groups,
        final,
        num_iterations=settings.refine_iterations,
        scale=settings.refine_scale,
        plane_prior=settings.plane_prior,
        motion_prior=settings.motion_prior,
        prior_share=settings.motion_prior_share,
    )
    if exposure is not None and exposure.duty_cycle > 0:
        duty = exposure.duty_cycle
        change = blur_length_change(camera, groups, final, duty_cycle=duty, relative=True)
        if np.mean(np.abs(change) > settings.blur_change) >= settings.blur_change_share:
            # Differently blurred frames bias the match: give all four the same blur and
            # refine again, now led by the images alone. (Unclipped: blurring commutes
            # with a gain, not with clipping.)
            gained = [g * np.float32(prepared.gain) for g in prepared.grays]
            balanced, valid = cross_blur(camera, gained, groups, final, duty_cycle=duty)
            final = refine_proposals(
                camera,
                balanced,
                groups,
                final,
                num_iterations=settings.refine_iterations,
                scale=settings.refine_scale,
                plane_prior=settings.balanced_prior,
                motion_prior=settings.balanced_prior,
                valid=valid,
            )
    abc = keep_in_front(final.abc[chosen_local], graph, settings.min_disparity)
    return ChosenMotion(
        proposals=final,
        segment_proposal=chosen_local,
        abc=abc,
        normals=plane_from_disparity_coefficients(camera, abc),
        twists=final.twists()[chosen_local],
    )


def _with_occlusion(camera, labels, chosen: ChosenMotion, matches: InitialMatches, settings):
    """Stage 7: the scene flow with its occlusion mask, and all the masks."""
    height, width = labels.shape
    provisional = SceneFlow(
        camera, labels, chosen.normals, chosen.twists, np.zeros((height, width), bool)
    )
    masks = occlusion_masks(
        provisional.disparity(),
        provisional.flow(),
        provisional.disparity_next(),
        labels,
        backward_flow=matches.flow_back,
        initial_flow=matches.flow,
        depth_margin=settings.depth_margin,
        boundary_jump=settings.boundary_jump,
    )
    return provisional.with_occlusion(masks.combined), masks


def _counts(start, chosen: ChosenMotion) -> dict:
    return {
        "dominant_inliers": start.dominant_inliers,
        "num_proposals": len(chosen.proposals),
        "num_global": len(start.global_ids),
    }


def _check_settings(camera, settings, num_segments) -> SceneFlowSettings:
    """``settings`` checked, with ``num_segments`` in it where given."""
    import dataclasses

    if not isinstance(camera, StereoCamera):
        raise InputError(f"camera must be a StereoCamera, got {type(camera).__name__}")
    if not isinstance(settings, SceneFlowSettings):
        raise InputError(f"settings must be a SceneFlowSettings, got {type(settings).__name__}")
    if num_segments is None:
        return settings
    if isinstance(num_segments, bool) or not isinstance(num_segments, (int, np.integer)):
        raise InputError(f"num_segments must be a whole number >= 1, got {num_segments!r}")
    if num_segments < 1:
        raise InputError(f"num_segments must be >= 1, got {num_segments}")
    return dataclasses.replace(settings, num_segments=int(num_segments))


def _check_images(images) -> tuple[int, int]:
    names = ("left_t", "right_t", "left_next", "right_next", "other_side[0]", "other_side[1]")
    shape = None
    for name, image in zip(names[: len(images)], images, strict=True):
        a = np.asarray(image)
        if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 3)):
            raise InputError(f"{name} must have shape (H, W) or (H, W, 3), got {a.shape}")
        if a.shape[0] < 8 or a.shape[1] < 8:
            raise InputError(f"{name} is too small for scene flow: {a.shape[:2]} (need >= 8x8)")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise InputError(f"{name} has shape {a.shape}, left_t has {shape}")
        if a.dtype.kind not in "fui" or not np.all(np.isfinite(a)):
            raise InputError(f"{name} must hold finite numbers, got dtype {a.dtype}")
    return int(shape[0]), int(shape[1])


def _matched_fractions(camera, codes, graph, chosen: ChosenMotion, step, settings):
    """Share of (grid) pixels whose census cost in each other view is below match_cost."""
    labels = graph.labels
    height, width = labels.shape
    yy, xx = np.mgrid[0:height:step, 0:width:step]
    x, y = xx.ravel(), yy.ravel()
    seg = labels[y, x]
    k = chosen.segment_proposal[seg]
    final = chosen.proposals
    d0, x1, y1, d1 = predict(camera, chosen.abc[seg], final.R[k], final.T[k], x, y)
    lt, rt, lt1, rt1 = codes
    out = {}
    for name, target, xt, yt in (
        ("right_t", rt, x - d0, y),
        ("left_t1", lt1, x1, y1),
        ("right_t1", rt1, x1 - d1, y1),
    ):
        cost = census_cost(lt, target, x, y, np.nan_to_num(xt, nan=-1.0), yt)
        inside = np.isfinite(cost)
        out[name] = float(np.mean(cost[inside] < settings.match_cost)) if inside.any() else 0.0
    return out


def _messages(prepared: PreparedFrames, matches, start, matched, settings) -> list[str]:
    """The stages' problems, and warnings where few pixels match (only meaningful with some
    texture)."""
    messages = [*prepared.messages, *matches.messages, *start.messages]
    contrast_ok = prepared.contrast_ok
    if contrast_ok and matched["right_t"] < settings.min_matched:
        messages.append(
            f"only {100 * matched['right_t']:.0f}% of the pixels match between the left and "
            "right views at frame t: the views may not overlap or not be rectified"
        )
    if contrast_ok and matched["left_t1"] < settings.min_matched:
        messages.append(
            f"only {100 * matched['left_t1']:.0f}% of the pixels match between frames t and "
            "t+1: the frames may not overlap"
        )
    return messages


def _write_debug(folder, image, sceneflow, matches: InitialMatches, masks: OcclusionMasks):
    """Pictures of the estimate, each under a caption saying what it shows and its colours."""
    from ..io.formats import write_png
    from ..viz import (
        disparity_key,
        disparity_to_color,
        flow_key,
        flow_to_color,
        mask_to_image,
        segment_overlay,
        with_caption,
    )

    disparity, flow = sceneflow.disparity(), sceneflow.flow()
    initial_disp = matches.disparity
    folder.mkdir(parents=True, exist_ok=True)
    finite = np.concatenate(
        [disparity[np.isfinite(disparity)], initial_disp[np.isfinite(initial_disp)]]
    )
    top = float(np.percentile(finite, 99)) if finite.size else 1.0
    max_flow = float(max(np.percentile(np.linalg.norm(flow, axis=-1), 99), 1e-3))
    width = sceneflow.labels.shape[1]
    turbo = (
        f"Colour: turbo scale from dark blue, 0 px (far), to red, {top:.3g} px (near); "
        "black: unknown."
    )
    wheel = (
        "Colour: direction as hue (right red, down yellow, left cyan-blue, up blue-violet), "
        f"length as saturation: white 0 px, full colour {max_flow:.3g} px, darker beyond; "
        "black: unknown."
    )
    segments = len(np.unique(sceneflow.labels))
    pictures = {
        "segments.png": with_caption(
            segment_overlay(image, sceneflow.labels),
            [f"Segments: {segments} superpixels (yellow borders) over the left frame t."],
        ),
        "disparity.png": with_caption(
            disparity_to_color(disparity, max_disparity=top),
            ["Disparity of the scene flow, left view, frame t.", turbo],
            key=disparity_key(top, width),
        ),
        "initial_disparity.png": with_caption(
            disparity_to_color(initial_disp, max_disparity=top),
            ["Initial disparity (semi-global matching), left view, frame t.", turbo],
            key=disparity_key(top, width),
        ),
        "flow.png": with_caption(
            flow_to_color(flow, max_flow=max_flow),
            ["Optical flow of the scene flow, left view, frame t to t + 1.", wheel],
            key=flow_key(max_flow),
        ),
        "initial_flow.png": with_caption(
            flow_to_color(matches.flow, max_flow=max_flow),
            ["Initial optical flow (DIS), left view, frame t to t + 1.", wheel],
            key=flow_key(max_flow),
        ),
        "occlusion.png": with_caption(
            mask_to_image(masks.combined),
            [
                "Occlusion, left view, frame t. White: the pixel leaves the view, is occluded "
                "or fails the forward-backward check at t + 1, or lies in a "
                "motion-boundary band; black: followed by one plane's motion."
            ],
        ),
    }
    for name, rgb in pictures.items():
        write_png(folder / name, rgb.astype(np.float32) / 255.0, bit_depth=8)
