"""Deblur one frame or a clip: orchestration of motion, blur operator and deconvolution.

Frame i of a view is deblurred with the motion from frame i to i + 1; the last
frame uses the motion to frame i - 1 (the scene flow from i to i - 1). Motion
sources are orthogonal to kernel types, so every variant of the paper's tables
is a combination of ``motion_source`` and ``kernels``:

- ``motion_source='gt'``: planes and motions fitted per superpixel (cut where the
  gt jumps) to the scene's gt/disparity (frames i, i + 1) and gt/flow (frame i);
  2D displacements taken directly from gt/flow.
- ``motion_source='sceneflow'``: piecewise-rigid scene flow estimated from the
  blurred stereo frames; 2D displacements are its projection. The view's initial
  optical flow comes along (``FrameMotion.boundary_flow``): near motion boundaries the
  adaptive boundary handling takes the blur from it (see :func:`boundary_motion`).
- ``motion_source='initial-flow'``: the initial optical flow of the left view alone
  (monocular); only ``kernels='displacement'`` can use it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import ndimage

from .blur.operator import SparseBlur
from .deconv.irls import DeblurResult, deblur_irls
from .errors import InputError
from .geometry.camera import Exposure
from .sceneflow.from_gt import (
    default_num_segments,
    sceneflow_from_gt,
    split_at_discontinuities,
)
from .sceneflow.model import SceneFlow
from .sceneflow.superpixels import slic_segments

KERNELS = ("homography", "displacement")
MOTION_SOURCES = ("gt", "sceneflow", "initial-flow")
BOUNDARY_WEIGHTS = ("adaptive", "paper", "none")
BOUNDARY_MASKS = (None, "gt")
PAPER_ALPHA = 1e-3
"""The paper's prior weight (Eq. 6)."""


@dataclass(frozen=True)
class DeblurSettings:
    """Choices and tuning of one deblurring run; defaults are the paper's.

    Parameters
    ----------
    kernels : {'homography', 'displacement'}
        Blur kernels from plane-induced homographies (paper Eq. 3-4) or from straight
        2D displacements (Kim and Lee 2015).
    motion_source : {'gt', 'sceneflow', 'initial-flow'}
    num_samples : int
        Time samples over the exposure (paper: N = 70).
    alpha : float or 'auto'
        Prior weight of Eq. 6; ``'auto'`` (default) sets it from the noise level of the
        blurred frame (:func:`stereodeblur.deconv.noise.auto_alpha`), and with
        ``boundary_weights='adaptive'`` at least to what the share of pixels whose motion
        is not trusted calls for (:func:`stereodeblur.deconv.trust.alpha_from_trust`);
        the paper's is 0.001 (:data:`PAPER_ALPHA`).
    num_irls, num_cg : int
        Iteration counts (paper: 10, 25).
    num_segments : int or None
        Superpixels of the scene flow; None scales 1200 at 640x480 with image area.
    seed : int
    boundary_weights : {'adaptive', 'paper', 'none'}
        Handling of the pixels the blur model cannot explain (motion boundaries, motion
        errors; Sec. 3): ``'adaptive'`` (default) keeps ``w = 1`` (but a small weight
        where the exposure path leaves the view); near the motion's flow discontinuities
        it takes the blur from the initial optical flow where the motion has one
        (:func:`boundary_motion`); without a dense flow, or with displacement kernels, it
        anchors the estimate to the blurred frame where the motion fails to predict both
        neighbouring frames instead (:mod:`stereodeblur.deconv.trust`), and homography
        kernels become occlusion-aware (:func:`visibility`);
        ``'paper'`` Eq. 5 as published (:class:`~stereodeblur.deconv.weights.PaperWeights`,
        updated every IRLS iteration) started from the scene flow's occlusion mask (from 1
        without a scene flow); ``'none'`` ``w = 1``.
    boundary_mask : {None, 'gt'}
        ``'gt'``: the scene's gt/mixed pixels get weight 0 throughout (the paper's
        masked experiment, Table 2), on top of ``boundary_weights``.
    """

    kernels: str = "homography"
    motion_source: str = "gt"
    num_samples: int = 70
    alpha: float | str = "auto"
    num_irls: int = 10
    num_cg: int = 25
    num_segments: int | None = None
    seed: int = 0
    boundary_weights: str = "adaptive"
    boundary_mask: str | None = None

    def __post_init__(self):
        if self.kernels not in KERNELS:
            raise InputError(f"kernels must be one of {', '.join(KERNELS)}, got {self.kernels!r}")
        if self.motion_source not in MOTION_SOURCES:
            raise InputError(
                f"motion source must be one of {', '.join(MOTION_SOURCES)}, "
                f"got {self.motion_source!r}"
            )
        if self.motion_source == "initial-flow" and self.kernels != "displacement":
            raise InputError("--motion-source initial-flow needs --kernels displacement")
        if self.num_samples < 1:
            raise InputError(f"num_samples must be >= 1, got {self.num_samples}")
        if self.alpha != "auto":
            if isinstance(self.alpha, str | bool) or not (
                np.isfinite(self.alpha) and self.alpha > 0
            ):
                raise InputError(f"alpha must be 'auto' or a positive number, got {self.alpha!r}")
        if self.boundary_weights not in BOUNDARY_WEIGHTS:
            raise InputError(
                f"boundary weights must be one of {', '.join(BOUNDARY_WEIGHTS)}, "
                f"got {self.boundary_weights!r}"
            )
        if self.boundary_mask not in BOUNDARY_MASKS:
            raise InputError(f"boundary mask must be 'gt' or None, got {self.boundary_mask!r}")


@dataclass(frozen=True)
class FrameMotion:
    """The motion a frame's blur operator is built from.

    ``sceneflow`` (for homography kernels) covers the frame's view with motions
    towards ``neighbour``; ``flow_forward`` / ``flow_backward`` (for displacement
    kernels) are 2D flows to the next and previous frames. ``boundary_flow`` is the view's
    dense optical flow ``(forward, backward or None)`` for :func:`boundary_motion`.
    """

    index: int
    neighbour: int
    view: str
    sceneflow: SceneFlow | None
    flow_forward: np.ndarray | None
    flow_backward: np.ndarray | None
    boundary_flow: tuple | None = None


@dataclass(frozen=True)
class FrameResult:
    """A deblurred frame with what produced it.

    ``alpha`` is the prior weight used; ``weight_steps`` the boundary-weight updates
    (:class:`~stereodeblur.deconv.weights.WeightsStep`: weights and the residual norm
    they came from, per IRLS iteration), empty with fixed weights; ``trust`` the trust in
    the blur model per pixel (``boundary_weights='adaptive'``, else None).
    """

    index: int
    view: str
    blurred: np.ndarray
    result: DeblurResult
    motion: FrameMotion
    timings: dict = field(default_factory=dict)
    alpha: float | None = None
    weight_steps: tuple = ()
    trust: np.ndarray | None = None

    @property
    def image(self) -> np.ndarray:
        return np.clip(self.result.image, 0.0, 1.0)


def neighbour_of(index: int, num_frames: int) -> int:
    """The frame whose motion deblurs ``index``: the next one, or the previous for the last."""
    return index + 1 if index + 1 < num_frames else index - 1


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
    order = np.argsort(np.where(ok, d, -np.inf).ravel(), kind="stable")  # far first, near last
    order = order[ok.ravel()[order]]
    labels = np.full((H, W), -1, dtype=np.int32)
    disp = np.full((H, W), np.inf)
    labels[y.ravel()[order], xr.ravel()[order]] = sceneflow.labels.ravel()[order]
    disp[y.ravel()[order], xr.ravel()[order]] = d.ravel()[order]
    holes = labels < 0
    if holes.all():
        labels[:] = 0
    elif holes.any():
        # Fill each hole from the nearest pixel to its left or right, whichever is farther.
        _, (iy, ix) = ndimage.distance_transform_edt(holes, return_indices=True)
        labels[holes] = labels[iy[holes], ix[holes]]
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


def _gt_motion(scene, index, neighbour, view, settings, blurred) -> FrameMotion:
    """Scene flow fitted to the scene's ground truth (left view; right by transfer)."""
    needed = [("disparity", index), ("disparity", neighbour), ("flow", min(index, neighbour))]
    for kind, i in needed:
        if not scene.has_gt(kind, "left", i):
            raise InputError(
                f"--motion-source gt needs {scene.gt_path(kind, 'left', i)}, which is missing"
            )
    if neighbour < index:
        raise InputError(
            f"--motion-source gt cannot deblur the last frame {index} (no gt flow to a later frame)"
        )
    left_blurred = blurred if view == "left" else scene.read_frame("left", index)
    num = settings.num_segments or default_num_segments(left_blurred.shape[:2])
    flow = scene.read_gt_flow("left", index)
    disparity = scene.read_gt_disparity("left", index)
    labels = split_at_discontinuities(slic_segments(left_blurred, num), disparity, flow)
    sf = sceneflow_from_gt(
        scene.info.camera,
        disparity,
        scene.read_gt_disparity("left", neighbour),
        flow,
        labels,
    )
    flow_backward = None
    if index > 0 and scene.has_gt("flow", "left", index - 1):
        flow_backward = invert_flow(scene.read_gt_flow("left", index - 1))
    if view == "right":
        sf = to_right_view(sf)
        flow, flow_backward = sf.flow().astype(np.float32), None
    return FrameMotion(index, neighbour, view, sf, flow, flow_backward)


def frame_motion(scene, index: int, view: str, settings: DeblurSettings, blurred) -> FrameMotion:
    """Motion of frame ``index`` of ``view`` from the chosen source."""
    neighbour = neighbour_of(index, scene.num_frames)
    if settings.motion_source == "gt":
        return _gt_motion(scene, index, neighbour, view, settings, blurred)
    from .sceneflow.estimate import estimate_scene_flow

    if settings.motion_source == "initial-flow":
        flow, backward = dense_flow(scene, index, view, blurred)
        return FrameMotion(index, neighbour, view, None, flow, backward)
    frames = [scene.read_frame(v, i) for i in (index, neighbour) for v in ("left", "right")]
    estimate = estimate_scene_flow(
        *frames,
        scene.info.camera,
        num_segments=settings.num_segments,
        seed=settings.seed,
        exposure=scene.info.exposure,
    )
    motion = sceneflow_motion(estimate.sceneflow, index, neighbour, view)
    return with_boundary_flow(motion, scene, settings, blurred)


def uses_boundary_flow(settings: DeblurSettings) -> bool:
    """Whether ``settings`` take the blur near motion boundaries from the dense flow."""
    return settings.boundary_weights == "adaptive" and settings.kernels == "homography"


def with_boundary_flow(motion: FrameMotion, scene, settings: DeblurSettings, blurred):
    """``motion`` with the view's :func:`dense_flow` as ``boundary_flow`` if ``settings`` use it."""
    if not uses_boundary_flow(settings):
        return motion
    return replace(motion, boundary_flow=dense_flow(scene, motion.index, motion.view, blurred))


def dense_flow(scene, index: int, view: str, blurred) -> tuple:
    """The initial optical flow of frame ``index`` of ``view``: ``(forward, backward)``.

    ``forward`` leads to the frame's neighbour (:func:`neighbour_of`, as if it were the
    next frame); ``backward`` to the frame on the other side, None if there is none.
    """
    from .sceneflow.estimate import initial_optical_flow

    neighbour = neighbour_of(index, scene.num_frames)
    flow = initial_optical_flow(blurred, scene.read_frame(view, neighbour))
    backward = None
    if neighbour > index and index > 0:
        backward = initial_optical_flow(blurred, scene.read_frame(view, index - 1))
    if neighbour < index:  # last frame: the flow to the previous frame leads
        flow, backward = -flow, flow
    return flow, backward


def sceneflow_motion(sceneflow: SceneFlow, index: int, neighbour: int, view: str) -> FrameMotion:
    """Motion of frame ``index`` of ``view`` from a left-view scene flow towards ``neighbour``."""
    sf = sceneflow
    if neighbour < index:  # motion to the previous frame, as a motion towards the next one
        sf = sf.reversed()
    if view == "right":
        sf = to_right_view(sf)
    return FrameMotion(index, neighbour, view, sf, sf.flow(), sf.reversed().flow())


def boundary_motion(motion: FrameMotion, duty_cycle: float) -> tuple[FrameMotion, np.ndarray]:
    """The motion with its 2D flows taken from ``motion.boundary_flow`` near motion boundaries.

    Where the exposure mixes two surfaces the blurred edge travels with the occluding one,
    and the dense flow of the blurred frames follows it; a piecewise-rigid scene flow gives
    each pixel the one surface it shows at the frame's centre. On the benchmark's object
    scenes the dense flow's straight kernels explain those pixels better than the segments'
    homographies (``stereodeblur bench paper``). Returns the motion and the boundary band
    (bool ``(H, W)``, :func:`~stereodeblur.deconv.trust.near_motion_boundaries` of the scene
    flow's 2D flow): pass it to :func:`build_operator` as ``flow_rows``.
    """
    from .deconv.trust import near_motion_boundaries

    band = near_motion_boundaries(motion.flow_forward, duty_cycle)
    forward, backward = motion.boundary_flow
    backward = -forward if backward is None else backward
    inside = band[..., None]
    return (
        replace(
            motion,
            flow_forward=np.where(inside, forward, motion.flow_forward).astype(np.float32),
            flow_backward=np.where(inside, backward, motion.flow_backward).astype(np.float32),
        ),
        band,
    )


def build_operator(
    motion: FrameMotion,
    exposure: Exposure,
    settings: DeblurSettings,
    *,
    flow_rows=None,
    visible=None,
) -> SparseBlur:
    """The blur operator of a frame: homography- or displacement-induced.

    ``flow_rows`` (bool ``(H, W)``) gives homography kernels' pixels that take their rows
    from the displacement kernels of ``motion``'s 2D flows instead; ``visible`` the segment
    every pixel shows at every instant (:func:`visibility`).
    """
    from .blur.displacement import displacement_blur

    forward = motion.flow_forward
    backward = -forward if motion.flow_backward is None else motion.flow_backward
    num = settings.num_samples
    if settings.kernels == "displacement":
        return displacement_blur(forward, backward, exposure, num_samples=num)
    from .blur.homography import homography_blur
    from .blur.operator import merge_rows

    operator = homography_blur(motion.sceneflow, exposure, num_samples=num, visible=visible)
    if flow_rows is None or not np.any(flow_rows):
        return operator
    return merge_rows(
        operator, displacement_blur(forward, backward, exposure, num_samples=num), flow_rows
    )


def visibility(motion: FrameMotion, exposure: Exposure, settings: DeblurSettings, flow_rows):
    """The segment every pixel shows at every instant, or None for the paper's operator.

    With ``boundary_weights='adaptive'`` and homography kernels whose rows near motion
    boundaries are the scene flow's own (no dense flow, ``flow_rows`` None), the operator
    lets each instant show the surface that covers the pixel then
    (:mod:`stereodeblur.blur.visibility`) and the pixels that show surfaces hidden at
    the reference instant get :func:`~stereodeblur.deconv.weights.hidden_weights`. With
    the true motion of the ten object scenes at 640x480 that gained 1.16 dB (every scene);
    with the estimated scene flow, whose boundaries lie somewhere in the blurred edges,
    the dense flow's rows there are better (same result with or without it on top).
    """
    if not uses_boundary_flow(settings) or flow_rows is not None:
        return None
    from .blur.visibility import sceneflow_visibility

    return sceneflow_visibility(motion.sceneflow, exposure, settings.num_samples)


def resolve_alpha(settings: DeblurSettings, blurred: np.ndarray, trust=None) -> float:
    """The prior weight of a run: ``settings.alpha``, or for ``'auto'`` :func:`auto_alpha` of
    ``blurred``, raised to :func:`~stereodeblur.deconv.trust.alpha_from_trust` with a trust map.
    """
    if settings.alpha == "auto":
        from .deconv.noise import auto_alpha

        alpha = auto_alpha(blurred)
        if trust is not None:
            from .deconv.trust import alpha_from_trust

            alpha = max(alpha, alpha_from_trust(trust))
        return alpha
    return float(settings.alpha)


class _MaskedUpdate:
    """A weight update whose result is multiplied by a fixed 0/1 mask."""

    def __init__(self, update, mask):
        self.update, self.mask = update, mask

    def __call__(self, n, blurred, residual, estimate, weights):
        return self.update(n, blurred, residual, estimate, weights) * self.mask


def frame_trust(scene, index: int, view: str, motion: FrameMotion, blurred) -> np.ndarray:
    """Trust in ``motion`` near its flow discontinuities, 1 elsewhere, float32 ``(H, W)``.

    The better of the predictions of the two neighbouring frames
    (:func:`~stereodeblur.deconv.trust.motion_trust`). Occlusions show as large residuals,
    and what is covered on one side is seen on the other; the scene flow's occlusion mask
    is wider than that and is not used.
    """
    from .deconv.noise import estimate_noise_sigma
    from .deconv.trust import motion_trust, near_motion_boundaries

    sigma = estimate_noise_sigma(blurred)
    following = scene.read_frame(view, motion.neighbour)
    trust = motion_trust(blurred, following, motion.flow_forward, noise_sigma=sigma)
    other = 2 * index - motion.neighbour  # the frame on the other side, if any
    if motion.flow_backward is not None and 0 <= other < scene.num_frames:
        preceding = scene.read_frame(view, other)
        backward = motion_trust(blurred, preceding, motion.flow_backward, noise_sigma=sigma)
        trust = np.maximum(trust, backward)
    band = near_motion_boundaries(motion.flow_forward, scene.info.exposure.duty_cycle)
    return np.where(band, trust, 1.0).astype(np.float32)


def boundary_weighting(
    scene,
    index: int,
    view: str,
    settings: DeblurSettings,
    motion: FrameMotion,
    blurred,
    *,
    dense_rows: bool = False,
):
    """Data weights, weight update, anchor and trust of a run (see DeblurSettings).

    ``dense_rows``: the operator's rows near motion boundaries come from the dense flow
    (:func:`boundary_motion`), which explains them; no anchor to the blurred frame then,
    which would only keep their blur (bench paper 640x480, object scenes: +0.15 / +0.08 dB
    and SSIM +0.003 without it).

    Returns
    -------
    weights : ndarray, float32, shape (H, W)
        ``w_0``; ``'adaptive'``: :data:`~stereodeblur.deconv.trust.OUTSIDE_WEIGHT` where
        the exposure path leaves the view (:func:`~stereodeblur.deconv.trust.leaves_view`),
        else 1.
    update : callable or None
        For ``deblur_irls(update_weights=...)``; it keeps its steps in ``.history``
        (a masked update in ``.update.history``).
    anchor, trust : ndarray, float32, shape (H, W), or None
        For ``deblur_irls(anchor=...)`` (None with ``dense_rows``), and the trust it came
        from: the motion's trust
        near motion boundaries, 1 elsewhere (what ``alpha='auto'`` reads; it does not
        include the pixels whose exposure path leaves the view).
    """
    from .deconv.weights import PaperWeights, initial_weights_from_occlusion

    sf = motion.sceneflow
    shape = tuple(motion.flow_forward.shape[:2]) if sf is None else sf.shape
    weights = np.ones(shape, np.float32)
    update = anchor = trust = None
    if settings.boundary_weights == "paper":
        update = PaperWeights()
        if sf is not None:
            weights = initial_weights_from_occlusion(sf.occlusion)
    elif settings.boundary_weights == "adaptive":
        from .deconv.trust import OUTSIDE_WEIGHT, leaves_view, trust_anchor

        # Pixels whose exposure path leaves the view show content the blur model replaces
        # by the edge pixel's: a small data weight (not an anchor, and not in the trust
        # map, so that alpha does not rise for them; stereodeblur.deconv.trust).
        duty_cycle = scene.info.exposure.duty_cycle
        outside = leaves_view(motion.flow_forward, motion.flow_backward, duty_cycle)
        weights = np.where(outside, OUTSIDE_WEIGHT, 1.0).astype(np.float32)
        trust = frame_trust(scene, index, view, motion, blurred)
        anchor = None if dense_rows else trust_anchor(trust)
    if settings.boundary_mask == "gt":
        if not (hasattr(scene, "has_gt") and scene.has_gt("mixed", view, index)):
            where = scene.gt_path("mixed", view, index) if hasattr(scene, "gt_path") else "gt/"
            raise InputError(f"--boundary-mask gt needs {where}, which is missing")
        keep = initial_weights_from_occlusion(scene.read_gt_mixed(view, index))
        weights = weights * keep
        if update is not None:
            update = _MaskedUpdate(update, keep)
    return weights, update, anchor, trust


def deblur_frame(
    scene,
    index: int,
    *,
    view: str = "left",
    settings: DeblurSettings | None = None,
    weights: np.ndarray | None = None,
    motion: FrameMotion | None = None,
    progress: Callable[[str], None] | None = None,
) -> FrameResult:
    """Deblur frame ``index`` of ``view`` of an open scene.

    ``weights`` replaces the initial data weights chosen by ``settings``; ``motion``
    (from :func:`frame_motion` with the same settings) skips the motion estimation.
    """
    settings = settings or DeblurSettings()
    say = progress or (lambda message: None)
    if not 0 <= index < scene.num_frames:
        raise InputError(f"frame {index} is out of range: the scene has {scene.num_frames} frames")
    timings = {}
    t0 = time.perf_counter()
    blurred = scene.read_frame(view, index)
    if motion is None:
        say(f"frame {index} {view}: motion ({settings.motion_source})")
        motion = frame_motion(scene, index, view, settings, blurred)
    timings["motion"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    say(f"frame {index} {view}: blur operator ({settings.kernels})")
    flow_rows = None
    own = motion
    if uses_boundary_flow(settings) and motion.boundary_flow is not None:
        motion, flow_rows = boundary_motion(motion, scene.info.exposure.duty_cycle)
    visible = visibility(motion, scene.info.exposure, settings, flow_rows)
    operator = build_operator(
        motion, scene.info.exposure, settings, flow_rows=flow_rows, visible=visible
    )
    timings["operator"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    initial, update, anchor, trust = boundary_weighting(
        scene, index, view, settings, motion, blurred, dense_rows=flow_rows is not None
    )
    if visible is not None:
        from .blur.visibility import hidden_fraction
        from .deconv.weights import hidden_weights

        initial = initial * hidden_weights(hidden_fraction(visible))
        del visible
    alpha_trust = trust
    if flow_rows is not None and settings.alpha == "auto":
        # The dense flow mends the boundaries, not the segments' misfit elsewhere: alpha
        # follows the scene flow's own trust (stereodeblur.deconv.trust.alpha_from_trust).
        alpha_trust = frame_trust(scene, index, view, own, blurred)
    alpha = resolve_alpha(settings, blurred, alpha_trust)
    result = deblur_irls(
        blurred,
        operator,
        weights=initial if weights is None else weights,
        alpha=alpha,
        num_irls=settings.num_irls,
        num_cg=settings.num_cg,
        update_weights=update,
        anchor=anchor,
        progress=lambda n, total: say(f"frame {index} {view}: IRLS {n}/{total}"),
    )
    timings["deconvolution"] = time.perf_counter() - t0
    steps = tuple(getattr(getattr(update, "update", update), "history", ()))
    return FrameResult(index, view, blurred, result, motion, timings, alpha, steps, trust)
