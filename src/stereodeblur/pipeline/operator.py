"""The blur operator of one view, from its motion (paper Eq. 3-4, or 2D displacements)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..geometry.camera import Exposure
from .motion import FrameMotion
from .window import occlusion_aware, uses_boundary_flow

if TYPE_CHECKING:
    from ..blur.operator import SparseBlur
    from ..settings import DeblurSettings


@dataclass(frozen=True)
class GateTrusts:
    """Trusts of a view's motion (``own``) and of its dense flow (``dense``) in the motion's
    boundary band, float32 ``(H, W)``, and the noise level they were measured with
    (``boundary_weights='gated'``, :func:`~stereodeblur.pipeline.gate_trusts`)."""

    own: np.ndarray
    dense: np.ndarray
    noise_sigma: float


@dataclass(frozen=True)
class ViewOperator:
    """A view's blur operator and the motion it was built from.

    ``motion`` is the motion the operator uses (its 2D flows taken from the dense flow in
    the band ``flow_rows``, if any), ``own`` the motion before that (the scene flow's own);
    ``hidden`` the share of the exposure each pixel shows a surface the frame centre hides
    (occlusion-aware operators, :func:`visibility`), else None; ``trusts`` the
    :class:`GateTrusts` that gated the band (``boundary_weights='gated'``), else None.
    """

    operator: SparseBlur
    motion: FrameMotion
    own: FrameMotion
    flow_rows: np.ndarray | None = None
    hidden: np.ndarray | None = None
    trusts: GateTrusts | None = None


def boundary_motion(
    motion: FrameMotion, duty_cycle: float, *, band=None
) -> tuple[FrameMotion, np.ndarray]:
    """The motion with its 2D flows taken from ``motion.boundary_flow`` near motion boundaries.

    Where the exposure mixes two surfaces the blurred edge travels with the occluding one,
    and the dense flow of the blurred frames follows it; a piecewise-rigid scene flow gives
    each pixel the one surface it shows at the frame's centre, and the dense flow's straight
    kernels explain those pixels better (``docs/defaults.md#boundary-flow``). Returns
    the motion and the boundary band (bool ``(H, W)``,
    :func:`~stereodeblur.deconv.trust.near_motion_boundaries` of the scene flow's 2D flow, unless
    ``band`` gives it): pass it to :func:`build_operator` as ``flow_rows``.
    """
    from ..deconv.trust import near_motion_boundaries

    if band is None:
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
    from ..blur.displacement import displacement_blur

    forward = motion.flow_forward
    backward = -forward if motion.flow_backward is None else motion.flow_backward
    num = settings.num_samples
    interpolation = settings.interpolation
    if settings.kernels == "displacement":
        return displacement_blur(
            forward, backward, exposure, num_samples=num, interpolation=interpolation
        )
    from ..blur.homography import homography_blur

    substitute = None
    if flow_rows is not None and np.any(flow_rows):
        flow_rows = np.asarray(flow_rows, dtype=bool)
        rows = displacement_blur(
            forward,
            backward,
            exposure,
            num_samples=num,
            rows=flow_rows,
            interpolation=interpolation,
        )
        substitute = (rows, flow_rows)
    return homography_blur(
        motion.sceneflow,
        exposure,
        num_samples=num,
        visible=visible,
        substitute=substitute,
        interpolation=interpolation,
    )


def visibility(motion: FrameMotion, exposure: Exposure, settings: DeblurSettings, flow_rows):
    """The segment every pixel shows at every instant, or None for the paper's operator.

    With ``boundary_weights='adaptive'`` or ``'gated'`` and homography kernels whose rows
    near motion boundaries are the scene flow's own (no dense flow, ``flow_rows`` None), the
    operator lets each instant show the surface that covers the pixel then
    (:mod:`stereodeblur.blur.visibility`) and the pixels that show surfaces hidden at
    the reference instant get :func:`~stereodeblur.deconv.weights.hidden_weights`. With
    the estimated scene flow, whose boundaries lie somewhere in the blurred edges, the
    dense flow's rows are used there instead (``docs/defaults.md#boundary-flow``).
    """
    if not occlusion_aware(settings) or flow_rows is not None:
        return None
    from ..blur.visibility import sceneflow_visibility

    return sceneflow_visibility(motion.sceneflow, exposure, settings.num_samples)


def view_operator(
    motion: FrameMotion, exposure: Exposure, settings: DeblurSettings, *, trusts=None
):
    """The :class:`ViewOperator` of a view's motion under ``settings``.

    ``trusts`` (:class:`GateTrusts`): the dense flow's rows are then taken only where its
    trust is higher than the motion's by more than :data:`~stereodeblur.settings.GATE_MARGIN`
    (within the boundary band: both trusts are 1 outside it).
    """
    from ..settings import GATE_MARGIN

    own, flow_rows = motion, None
    gate = None if trusts is None else trusts.dense > trusts.own + GATE_MARGIN
    if uses_boundary_flow(settings) and motion.boundary_flow is not None:
        motion, flow_rows = boundary_motion(motion, exposure.duty_cycle, band=gate)
    visible = visibility(motion, exposure, settings, flow_rows)
    operator = build_operator(motion, exposure, settings, flow_rows=flow_rows, visible=visible)
    hidden = None
    if visible is not None:
        from ..blur.visibility import hidden_fraction

        hidden = hidden_fraction(visible)
    return ViewOperator(operator, motion, own, flow_rows, hidden, trusts)
