"""The motion of a stereo frame, computed once and shared by its views.

Convention: a frame's motion leads to its *neighbour* (:func:`~.window.neighbour_of`:
the next frame, the previous one for the last frame of a clip). ``FrameMotion.sceneflow``
moves the view's pixels towards the neighbour, ``flow_forward`` is the 2D flow to it and
``flow_backward`` the 2D flow to the frame on the other side (None where it is not
known; the blur operators then mirror the forward flow). The blur of a frame is centred
on it, so a motion towards the previous frame blurs like the same motion forwards.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from ..errors import InputError
from ..progress import ProgressCallback
from ..sceneflow.model import SceneFlow
from .window import FrameWindow, check_gt, read_window, relabels, uses_dense_flow

if TYPE_CHECKING:
    from ..io.protocol import StereoScene
    from ..sceneflow.estimate import SceneFlowEstimate
    from ..settings import DeblurSettings


@dataclass(frozen=True)
class FrameMotion:
    """The motion a frame's blur operator is built from (module docstring: directions).

    ``sceneflow`` (for homography kernels) covers the frame's view with motions
    towards ``neighbour``; ``flow_forward`` / ``flow_backward`` (for displacement
    kernels) are 2D flows to the neighbour and to the frame on the other side.
    ``boundary_flow`` is the view's dense optical flow ``(forward, backward or None)``
    for :func:`~.operator.boundary_motion`.
    """

    index: int
    neighbour: int
    view: str
    sceneflow: SceneFlow | None
    flow_forward: np.ndarray | None
    flow_backward: np.ndarray | None
    boundary_flow: tuple | None = None


@dataclass(frozen=True)
class StereoMotion:
    """The motion of one stereo frame: per view, and the scene-flow estimate it came from.

    ``estimate`` is the :class:`~stereodeblur.sceneflow.estimate.SceneFlowEstimate` of
    the left view (``motion_source='sceneflow'``), else None.
    """

    index: int
    views: MappingProxyType
    estimate: SceneFlowEstimate | None = None


def invert_flow(flow: np.ndarray, *, num_iterations: int = 20) -> np.ndarray:
    """Flow ``g`` on the target grid with ``x = y + flow(y)`` and ``g(x) = y - x``.

    Fixed-point iteration ``g(x) = -flow(x + g(x))`` with bilinear sampling.
    """
    H, W = flow.shape[:2]
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    g = -flow.astype(np.float64)
    for _ in range(num_iterations):
        coords = [y + g[..., 1], x + g[..., 0]]
        g = -np.stack(
            [
                ndimage.map_coordinates(flow[..., c], coords, order=1, mode="nearest")
                for c in (0, 1)
            ],
            axis=-1,
        )
    return g.astype(np.float32)


def invert_known_flow(flow: np.ndarray) -> np.ndarray:
    """:func:`invert_flow` of a flow with NaN where unknown; NaN where the inverse lands there."""
    unknown = ~np.all(np.isfinite(flow), axis=2)
    inverse = invert_flow(np.where(unknown[..., None], 0.0, flow).astype(np.float32))
    if unknown.any():
        H, W = unknown.shape
        y, x = np.mgrid[0:H, 0:W]
        ys = np.clip(np.rint(y + inverse[..., 1]), 0, H - 1).astype(int)
        xs = np.clip(np.rint(x + inverse[..., 0]), 0, W - 1).astype(int)
        inverse[unknown[ys, xs]] = np.nan
    return inverse


def splat_order(nearness: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Flat indices of the ``ok`` pixels, the farthest (lowest ``nearness``) first: written
    in this order, the nearest surface wins (z-buffered splatting)."""
    order = np.argsort(np.where(ok, nearness, -np.inf).ravel(), kind="stable")
    return order[ok.ravel()[order]]


def fill_from_nearest(labels: np.ndarray, holes: np.ndarray) -> None:
    """Give each hole the label of the nearest pixel that is none (all holes: label 0)."""
    if holes.all():
        labels[:] = 0
    elif holes.any():
        _, (iy, ix) = ndimage.distance_transform_edt(holes, return_indices=True)
        labels[holes] = labels[iy[holes], ix[holes]]


def to_right_view(sceneflow: SceneFlow) -> SceneFlow:
    """Transfer a left-view scene flow to the right view (labels by z-buffered warping).

    Right pixels that no left pixel reaches (seen by the right camera only) take the
    label of the farther neighbouring surface and are marked occluded.
    """
    if sceneflow.view != "left":
        raise ValueError(f"expected a left-view scene flow, got view {sceneflow.view!r}")
    H, W = sceneflow.shape
    d = sceneflow.disparity()
    y, x = np.mgrid[0:H, 0:W]
    xr = np.round(x - d).astype(int)
    ok = (xr >= 0) & (xr < W) & np.isfinite(d)
    order = splat_order(d, ok)
    labels = np.full((H, W), -1, dtype=np.int32)
    disp = np.full((H, W), np.inf)
    labels[y.ravel()[order], xr.ravel()[order]] = sceneflow.labels.ravel()[order]
    disp[y.ravel()[order], xr.ravel()[order]] = d.ravel()[order]
    holes = labels < 0
    fill_from_nearest(labels, holes)
    if holes.any() and not holes.all():
        # Then from the pixel to its left or right instead, where that one is farther.
        for step in (1, -1):
            src = np.clip(x + step, 0, W - 1)
            cand = ~holes[y, src] & holes & (disp[y, src] < disp)
            labels[cand] = labels[y, src][cand]
            disp[cand] = disp[y, src][cand]
    occlusion = holes.copy()
    occlusion[y.ravel()[order], xr.ravel()[order]] |= sceneflow.occlusion.ravel()[order]
    return SceneFlow(
        sceneflow.camera, labels, sceneflow.normals, sceneflow.twists, occlusion, view="right"
    )


def sceneflow_motion(
    sceneflow: SceneFlow,
    index: int,
    neighbour: int,
    view: str,
    *,
    dense: tuple | None = None,
    settings: DeblurSettings | None = None,
) -> FrameMotion:
    """Motion of frame ``index`` of ``view`` from a left-view scene flow towards ``neighbour``;
    ``dense`` the view's dense flows (``boundary_flow``), its boundaries moved to them where
    ``settings`` relabel (:func:`moved_boundaries`)."""
    sf = to_right_view(sceneflow) if view == "right" else sceneflow
    if dense is not None and settings is not None:
        sf = moved_boundaries(sf, dense, settings)
    return FrameMotion(index, neighbour, view, sf, sf.flow(), sf.reversed().flow(), dense)


def gt_motions(scene: StereoScene, window: FrameWindow, views, settings) -> dict:
    """Scene flow fitted to the scene's ground truth (left view; right by transfer), per view.

    For the last frame the flow to the previous frame is the inverse of the gt flow into it.
    """
    from ..sceneflow.from_gt import (
        default_num_segments,
        sceneflow_from_gt,
        split_at_discontinuities,
    )
    from ..sceneflow.superpixels import slic_segments

    index, neighbour, other = window.index, window.neighbour, window.other
    check_gt(scene, index, settings, ())
    left_blurred = window.blurred("left")
    num = settings.segments or default_num_segments(left_blurred.shape[:2])
    if neighbour > index:
        flow = scene.read_gt_flow("left", index)
    else:
        flow = invert_known_flow(scene.read_gt_flow("left", neighbour))
    disparity = scene.read_gt_disparity("left", index)
    labels = split_at_discontinuities(slic_segments(left_blurred, num), disparity, flow)
    sf = sceneflow_from_gt(
        window.camera, disparity, scene.read_gt_disparity("left", neighbour), flow, labels
    )
    motions = {}
    if "left" in views:
        backward = None
        if other is not None and scene.has_gt("flow", "left", other):
            backward = invert_flow(scene.read_gt_flow("left", other))
        motions["left"] = FrameMotion(index, neighbour, "left", sf, flow, backward)
    if "right" in views:
        right = to_right_view(sf)
        motions["right"] = FrameMotion(
            index, neighbour, "right", right, right.flow().astype(np.float32), None
        )
    return motions


def view_dense_flow(window: FrameWindow, view: str) -> tuple:
    """Dense optical flow (DIS) of ``view``: ``(to the neighbour, to the other side or None)``.

    Computed on the frames' own grey levels. (The scene-flow estimate's initial flow of the
    left view is DIS on grey levels scaled by a gain common to the four frames: a different
    computation, so it is not reused here.)
    """
    from ..sceneflow import initial

    blurred = window.blurred(view)
    forward = initial.initial_optical_flow(blurred, window.frame(view, window.neighbour))
    backward = None
    if window.other is not None:
        backward = initial.initial_optical_flow(blurred, window.frame(view, window.other))
    return forward, backward


def estimate_motion(
    window: FrameWindow, settings: DeblurSettings, *, progress: ProgressCallback | None = None
) -> SceneFlowEstimate:
    """The scene-flow estimate of the left view from frame ``index`` towards its neighbour."""
    from ..sceneflow import estimate

    index, neighbour = window.index, window.neighbour
    frames = [window.frame(v, i) for i in (index, neighbour) for v in ("left", "right")]
    other = None
    if settings.estimator.other_side and window.other is not None:
        other = tuple(window.frame(v, window.other) for v in ("left", "right"))
    return estimate.estimate_scene_flow(
        *frames,
        window.camera,
        settings=settings.estimator,
        seed=settings.seed,
        exposure=window.exposure,
        progress=progress,
        other_side=other,
    )


def stereo_motion(
    scene: StereoScene,
    window: FrameWindow,
    views,
    settings: DeblurSettings,
    *,
    sceneflow: SceneFlow | None = None,
    dense: dict | None = None,
    progress: ProgressCallback | None = None,
) -> StereoMotion:
    """The motion of every view in ``views`` from ``settings.motion_source``, computed once.

    One scene-flow estimate (left view, transferred to the right by :func:`to_right_view`)
    and one dense flow per view and frame pair. ``sceneflow``: the left view's scene flow
    towards the neighbour, given instead of estimated (``motion_source='sceneflow'``);
    ``dense``: the views' dense flows (:func:`view_dense_flow`) if already computed.
    """
    index, neighbour = window.index, window.neighbour
    estimate = None
    known = dense or {}

    def dense_of(view):
        return known[view] if view in known else view_dense_flow(window, view)

    if sceneflow is not None:
        _check_sceneflow(sceneflow, window, settings)
        motions = {}
        for view in views:
            flows = dense_of(view) if uses_dense_flow(settings) else None
            motions[view] = sceneflow_motion(
                sceneflow, index, neighbour, view, dense=flows, settings=settings
            )
    elif settings.motion_source == "gt":
        motions = gt_motions(scene, window, views, settings)
    elif settings.motion_source == "initial-flow":
        motions = {}
        for view in views:
            forward, backward = dense_of(view)
            motions[view] = FrameMotion(index, neighbour, view, None, forward, backward)
    else:
        # The views' dense flows do not depend on the estimate: computed meanwhile, in a
        # thread of their own (OpenCV releases the GIL; the estimate mostly runs in one).
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="dense-flow") as pool:
            pending = {}
            if uses_dense_flow(settings):
                pending = {view: pool.submit(dense_of, view) for view in views}
            estimate = estimate_motion(window, settings, progress=progress)
            motions = {
                view: sceneflow_motion(
                    estimate.sceneflow,
                    index,
                    neighbour,
                    view,
                    dense=pending[view].result() if view in pending else None,
                    settings=settings,
                )
                for view in views
            }
    return StereoMotion(index, MappingProxyType(motions), estimate)


RELABEL_VERSION = 3
"""Version of :func:`moved_boundaries`' rule, in the benchmarks' cache signatures: raise it
whenever the rule changes."""

# Why: docs/defaults.md#relabel-radius
RELABEL_JUMP = 0.5
"""px: a pixel takes only a segment whose flow differs from its own segment's by more (and by
more than ``BOUNDARY_RELATIVE`` of it), as a motion boundary is told in the trust: the
segments of one surface are not swapped."""

# Why: docs/defaults.md#relabel-radius
RELABEL_MARGIN = 1.0
"""A pixel moves only if the other segment comes nearer the dense flows by more than this times
the view's median distance of the estimate to them: where the dense flow is wrong everywhere
(noisy fine stripes), one pixel's distance is no evidence."""


def relabel_rule(settings: DeblurSettings) -> int | None:
    """:data:`RELABEL_VERSION` where ``settings`` relabel (:func:`~.window.relabels`), else
    None: what the benchmarks' cache signatures hold of the relabelling."""
    return RELABEL_VERSION if relabels(settings) else None


def moved_boundaries(sceneflow: SceneFlow, dense: tuple, settings: DeblurSettings) -> SceneFlow:
    """A view's ``sceneflow`` with its boundaries moved to its dense flows ``dense``
    (``(forward, backward or None)``; :func:`~stereodeblur.sceneflow.relabel.relabel_by_flow`,
    ``settings.relabel_radius``, another surface only: :data:`RELABEL_JUMP`, by a margin:
    :data:`RELABEL_MARGIN`), or as it is where ``settings`` do not relabel
    (:func:`~.window.relabels`)."""
    from ..deconv.trust import BOUNDARY_RELATIVE
    from ..sceneflow.relabel import relabel_by_flow

    if not relabels(settings):
        return sceneflow
    return relabel_by_flow(
        sceneflow,
        *dense,
        radius=settings.relabel_radius,
        jump=RELABEL_JUMP,
        relative=BOUNDARY_RELATIVE,
        margin=RELABEL_MARGIN,
    )


def relabelled(motion: FrameMotion, settings: DeblurSettings) -> FrameMotion:
    """A given ``motion`` (its boundaries as estimated, with its dense flows) as
    :func:`stereo_motion` makes it: :func:`moved_boundaries`, the 2D flows from the result."""
    if motion.boundary_flow is None or not relabels(settings):
        return motion
    sf = moved_boundaries(motion.sceneflow, motion.boundary_flow, settings)
    return replace(motion, sceneflow=sf, flow_forward=sf.flow(), flow_backward=sf.reversed().flow())


def _check_sceneflow(sceneflow: SceneFlow, window: FrameWindow, settings) -> None:
    if settings.motion_source != "sceneflow":
        raise InputError(
            f"a given scene flow needs motion_source='sceneflow', got {settings.motion_source!r}"
        )
    if sceneflow.view != "left" or sceneflow.shape != window.shape:
        raise InputError(
            f"the scene flow given is of the {sceneflow.view} view, size {sceneflow.shape}; "
            f"expected the left view, size {window.shape}"
        )


# --------------------------------------------------------------------------- one view


def frame_motion(
    scene: StereoScene, index: int, view: str, settings: DeblurSettings, blurred=None
) -> FrameMotion:
    """Motion of frame ``index`` of ``view`` from the chosen source.

    ``blurred``: the frame, if already read.
    """
    known = None if blurred is None else {(view, index): blurred}
    window = read_window(scene, index, (view,), settings, known=known)
    return stereo_motion(scene, window, (view,), settings).views[view]


def dense_flow(scene: StereoScene, index: int, view: str, blurred=None) -> tuple:
    """Dense optical flow of frame ``index`` of ``view``: ``(to the neighbour, to the other
    side or None)`` (:func:`view_dense_flow`)."""
    from ..settings import DeblurSettings

    settings = DeblurSettings(motion_source="initial-flow", kernels="displacement")
    known = None if blurred is None else {(view, index): blurred}
    window = read_window(scene, index, (view,), settings, known=known)
    return view_dense_flow(window, view)


def check_motion(motion: FrameMotion, window: FrameWindow, view: str) -> None:
    """An :class:`InputError` unless ``motion`` is the motion of ``view`` in ``window``."""
    if (motion.index, motion.neighbour, motion.view) != (window.index, window.neighbour, view):
        raise InputError(
            f"the motion given is frame {motion.index} {motion.view} towards frame "
            f"{motion.neighbour}, expected frame {window.index} {view} towards {window.neighbour}"
        )
