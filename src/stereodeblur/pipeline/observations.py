"""Further blurred observations of a view's sharp frame: the other view, the neighbouring frames.

Each is an :class:`~stereodeblur.deconv.irls.Observation` of the view's sharp frame at the
frame's centre. The other view's operator composes a warp and a blur: the sharp frame is warped
to the other view's by the disparity (cubic), then blurred by that view's own operator. The
frames t - 1 and t + 1 gather the sharp frame along their own exposure's trajectories, the
per-segment homographies of the scene flow at instants one frame interval away (the motion
taken as constant over the three frames), occlusion-aware as the frame's own operator. A
blurred pixel whose exposure touches pixels the view does not see at the frame's centre
(occluded, outside, or another surface) gets weight 0 (:data:`UNSEEN_SHARE`).
The neighbouring frames rest on the motion being constant over three frames; beside the other
view, their weights also follow how well the view's own estimate predicts them
(:func:`weighed_neighbours`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..blur.homography import homography_blur
from ..blur.operator import SparseBlur, TiledBlur
from ..blur.trajectories import homography_positions, keys_weights
from ..blur.visibility import hidden_fraction, sceneflow_visibility
from ..deconv.irls import Observation
from ..deconv.trust import OUTSIDE_WEIGHT, leaves_view
from ..geometry.plane import move_plane
from ..geometry.rigid import se3_exp
from ..sceneflow.model import SceneFlow
from ..settings import NEIGHBOUR_TOLERANCE
from .alpha import observed_error
from .motion import FrameMotion, fill_from_nearest, splat_order
from .operator import ViewOperator, build_operator
from .window import FrameWindow, observation_kinds, occlusion_aware

if TYPE_CHECKING:
    from ..settings import DeblurSettings

UNSEEN_SHARE = 0.02
"""Share of a blurred pixel's exposure on what the frame's centre does not see (warped pixels
of the other view, instants of a neighbouring frame) above which it gets weight 0."""
NEIGHBOURS_VERSION = 3
"""Version of the neighbouring frames' data terms, part of the signature of cached benchmark
results: raise it whenever :func:`neighbour_observation` or :func:`weighed_neighbours` changes."""
NEIGHBOURS = ("previous", "next")


def neighbours_version(settings: DeblurSettings) -> int | None:
    """:data:`NEIGHBOURS_VERSION` where ``settings`` observe the neighbouring frames, else
    None."""
    return NEIGHBOURS_VERSION if "neighbours" in observation_kinds(settings) else None


@dataclass(frozen=True)
class NamedObservation:
    """An observation and what it is: ``'other-view'``, ``'previous'`` or ``'next'``."""

    name: str
    observation: Observation


def warp_operator(positions: np.ndarray, shape) -> SparseBlur:
    """Row ``y`` samples the source image at ``positions[y]`` (x, y) by Keys' cubic
    convolution, taps clamped to the image.

    Bilinear sampling would smooth what the blur keeps (across the motion), an error that on
    noiseless frames outweighs what the further observation adds
    (``docs/defaults.md#observations``).
    """
    H, W = shape
    x, y = positions[..., 0].ravel(), positions[..., 1].ravel()
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    cols = np.empty((H * W, 16), np.int64)  # each row's 16 taps in the order dy, then dx
    values = np.empty((H * W, 16), np.float32)
    for i, dy in enumerate((-1, 0, 1, 2)):
        wy, yy = keys_weights(y - (y0 + dy)), np.clip(y0 + dy, 0, H - 1)
        for j, dx in enumerate((-1, 0, 1, 2)):
            cols[:, 4 * i + j] = yy * W + np.clip(x0 + dx, 0, W - 1)
            values[:, 4 * i + j] = wy * keys_weights(x - (x0 + dx))
    indptr = np.arange(0, 16 * H * W + 1, 16, dtype=np.int64)
    matrix = sp.csr_matrix((values.ravel(), cols.ravel(), indptr), shape=(H * W, H * W))
    matrix.sum_duplicates()  # the taps clamped onto one pixel, summed in that order
    matrix.eliminate_zeros()
    return SparseBlur(matrix, (H, W))


def compose(blur: SparseBlur, warp: SparseBlur) -> SparseBlur:
    """The operator ``blur(warp(image))`` as one matrix (float32 values, int32 indices)."""
    matrix = (blur.matrix @ warp.matrix).tocsr().astype(np.float32)
    matrix.indices = matrix.indices.astype(np.int32)
    matrix.indptr = matrix.indptr.astype(np.int32)
    return SparseBlur(matrix, blur.shape)


def _unseen_weights(blur: SparseBlur, seen: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``weights`` set to 0 where the exposure puts more than :data:`UNSEEN_SHARE` on
    pixels that are not ``seen``."""
    unseen = blur.forward((~seen).astype(np.float32))
    return np.where(unseen > UNSEEN_SHARE, 0.0, weights).astype(np.float32)


def without_pixels(observation: NamedObservation, mask: np.ndarray) -> NamedObservation:
    """``observation`` with weight 0 where its exposure puts more than :data:`UNSEEN_SHARE`
    on the estimate's pixels of ``mask``."""
    o = observation.observation
    weights = _unseen_weights(o.operator, ~np.asarray(mask, dtype=bool), o.weights)
    return NamedObservation(observation.name, Observation(o.operator, o.blurred, weights))


def weighed_neighbours(
    observations, image: np.ndarray, reference: Observation, *, border: int
) -> tuple[tuple[NamedObservation, ...], dict[str, float]]:
    """``observations`` with each neighbouring frame's weights scaled by
    ``sqrt(min(1, NEIGHBOUR_TOLERANCE * e_ref / e))``, and those scales by name.

    ``e`` is the mean squared error of the neighbour's blurred frame predicted from
    ``image`` (an estimate that did not use it), ``e_ref`` the same for ``reference`` (the
    other view's observation, equally held out), both by
    :func:`~.alpha.observed_error`. A neighbour the estimate predicts far worse than the
    other view is misaligned by a motion that is not constant over three frames; on a
    noiseless frame it then sets the solution against its own frame (speckle at a small
    alpha). Its squared weight then falls as the inverse of its error, as for independent
    observations weighted by their variance.
    """
    allowed = NEIGHBOUR_TOLERANCE * observed_error(image, reference, border=border)
    out, scales = [], {}
    for item in observations:
        if item.name in NEIGHBOURS:
            error = observed_error(image, item.observation, border=border)
            scale = 1.0 if error <= allowed else float(np.sqrt(allowed / error))
            weights = (item.observation.weights * scale).astype(np.float32)
            item = NamedObservation(item.name, replace(item.observation, weights=weights))
            scales[item.name] = scale
        out.append(item)
    return tuple(out), scales


def other_view_observation(
    own: SceneFlow, other: ViewOperator, blurred: np.ndarray, weights: np.ndarray
) -> Observation:
    """The other view's blurred frame as an observation of this view's sharp frame.

    ``own``: this view's scene flow; ``other``: the other view's operator (its motion has the
    other view's scene flow); ``weights``: the other view's data weights.
    """
    theirs = other.motion.sceneflow
    H, W = theirs.shape
    y, x = np.mgrid[0:H, 0:W]
    disparity = theirs.disparity()
    sign = 1.0 if theirs.view == "right" else -1.0  # a right pixel x sees the left x + d
    source = x + sign * disparity
    positions = np.stack([source, y.astype(np.float64)], axis=-1)
    xi = np.clip(np.round(source).astype(int), 0, W - 1)
    seen = (source >= 0) & (source <= W - 1)
    seen &= np.abs(own.disparity()[y, xi] - disparity) < 1.0
    blur = other.operator
    return Observation(
        TiledBlur.of(compose(blur, warp_operator(positions, (H, W)))),
        blurred,
        _unseen_weights(blur, seen, weights),
    )


def _splat_labels(sf: SceneFlow, points: np.ndarray) -> np.ndarray:
    """Labels of the view seeing ``points`` (nearest first); holes filled from the nearest."""
    H, W = sf.shape
    q = sf.camera.project(points, sf.view)
    xr, yr = np.round(q[..., 0]).astype(int), np.round(q[..., 1]).astype(int)
    ok = (xr >= 0) & (xr < W) & (yr >= 0) & (yr < H) & (points[..., 2] > 0)
    order = splat_order(-points[..., 2], ok)
    labels = np.full((H, W), -1, np.int32)
    labels[yr.ravel()[order], xr.ravel()[order]] = sf.labels.ravel()[order]
    fill_from_nearest(labels, labels < 0)
    return labels


def neighbour_observation(
    sf: SceneFlow, step: float, blurred: np.ndarray, exposure, settings: DeblurSettings
) -> Observation:
    """The view's blurred frame ``step`` frame intervals of ``sf`` away (+1: towards the
    scene flow's neighbour, -1: the other side) as an observation of its sharp frame.

    With homography kernels each of its pixels gathers the sharp frame along its own
    trajectory (:func:`~stereodeblur.blur.homography.homography_blur` at ``offset=step``):
    one interpolation, where the blur of the warped frame interpolates twice and smooths
    what both keep (``docs/defaults.md#observations``). At every instant a
    pixel shows the segment of the frame's centre that covers it
    (:func:`~stereodeblur.blur.visibility.sceneflow_visibility` at the same offset); where
    none does for more than :data:`UNSEEN_SHARE` of the exposure it gets weight 0.
    """
    labels = _splat_labels(sf, sf.points_at(step))
    still = np.zeros(sf.shape, bool)
    num = settings.num_samples
    visible = sceneflow_visibility(sf, exposure, num, offset=step, own=labels)
    M = se3_exp(step * sf.twists)
    normals = np.stack(
        [move_plane(n, m[:3, :3], m[:3, 3]) for n, m in zip(sf.normals, M, strict=True)]
    )
    moved = SceneFlow(sf.camera, labels, normals, sf.twists, still, sf.view)
    forward, backward = moved.flow(), moved.reversed().flow()
    leaves = leaves_view(forward, backward, exposure.duty_cycle)
    weights = np.where(leaves, OUTSIDE_WEIGHT, 1.0)
    weights = np.where(hidden_fraction(visible) > UNSEEN_SHARE, 0.0, weights).astype(np.float32)
    if settings.kernels == "homography":
        shows = SceneFlow(sf.camera, labels, sf.normals, sf.twists, still, sf.view)
        operator = homography_blur(
            shows,
            exposure,
            num_samples=num,
            visible=visible if occlusion_aware(settings) else None,
            interpolation=settings.interpolation,
            offset=step,
        )
    else:
        motion = FrameMotion(0, 1, sf.view, moved, forward, backward)
        positions = homography_positions(sf.homographies(np.array([step])), labels)[:, :, 0]
        blur = build_operator(motion, exposure, settings)
        operator = compose(blur, warp_operator(positions, sf.shape))
    return Observation(TiledBlur.of(operator), blurred, weights)


def view_observations(
    window: FrameWindow,
    view: str,
    motions,
    operators,
    weights,
    settings: DeblurSettings,
    *,
    other: Observation | None = None,
) -> list[NamedObservation]:
    """The observations ``settings.observations`` asks for that ``view`` has.

    ``motions``, ``operators``, ``weights``: per view, the :class:`FrameMotion`, the
    :class:`ViewOperator` and the data weights. Nothing without a scene flow; the other
    view where its operator is given (``other``: its observation, if already made); the
    frames on either side that the window holds.
    """
    kinds = observation_kinds(settings)
    own = motions[view].sceneflow
    if own is None or not kinds:
        return []
    out = []
    theirs = next((v for v in operators if v != view), None)
    if "other-view" in kinds and theirs is not None:
        if other is None:
            blurred = window.blurred(theirs)
            other = other_view_observation(own, operators[theirs], blurred, weights[theirs])
        out.append(NamedObservation("other-view", other))
    if "neighbours" in kinds:
        direction = window.neighbour - window.index
        sides = [("next" if direction > 0 else "previous", window.neighbour)]
        if window.other is not None:
            sides.append(("previous" if direction > 0 else "next", window.other))
        for name, frame in sides:
            blurred = window.frame(view, frame)
            step = (frame - window.index) / direction
            item = neighbour_observation(own, step, blurred, window.exposure, settings)
            out.append(NamedObservation(name, item))
    return out
