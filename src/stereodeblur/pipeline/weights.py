"""Data weights, weight update, anchor, trust and prior weight of one view's deconvolution."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..settings import NOISE_RULES
from .motion import FrameMotion
from .operator import GateTrusts, ViewOperator
from .window import FrameWindow

if TYPE_CHECKING:
    from ..io.protocol import StereoScene
    from ..settings import DeblurSettings


@dataclass(frozen=True)
class DataTerms:
    """What the deconvolution of one view weighs (see ``DeblurSettings.boundary_weights``).

    Parameters
    ----------
    weights : ndarray, float32, shape (H, W)
        ``w_0``; ``'adaptive'``, ``'gated'``: :data:`~stereodeblur.deconv.trust.OUTSIDE_WEIGHT`
        where the exposure path leaves the view (:func:`~stereodeblur.deconv.trust.leaves_view`),
        times :func:`~stereodeblur.deconv.weights.hidden_weights` with an occlusion-aware
        operator, else 1.
    update : callable or None
        For ``deblur_irls(update_weights=...)``; it keeps its steps in ``.history``.
    anchor : ndarray, float32, shape (H, W), or None
        For ``deblur_irls(anchor=...)``; ``'adaptive'`` only, and None where the
        operator's rows near motion boundaries come from the dense flow.
    trust : ndarray, float32, shape (H, W), or None
        Trust in the motion the operator uses near motion boundaries, 1 elsewhere
        (``'adaptive'``, ``'gated'``; it does not include the pixels whose path leaves the
        view).
    alpha : float
        The prior weight of Eq. 6 (:func:`resolve_alpha`).
    noise_sigma : float
        The blurred frame's noise estimate the alpha and the trust were computed from.
    alpha_scale : ndarray, float32, shape (H, W), or None
        Per-pixel factor of ``alpha`` (:func:`~.alpha.local_scale`); None: alpha everywhere.
    """

    weights: np.ndarray
    update: object | None
    anchor: np.ndarray | None
    trust: np.ndarray | None
    alpha: float
    noise_sigma: float
    alpha_scale: np.ndarray | None = None

    @property
    def steps(self) -> tuple:
        """The weight updates' steps after a run (empty with fixed weights)."""
        return tuple(getattr(self.update, "history", ()))


class _MaskedUpdate:
    """A weight update whose result is multiplied by a fixed 0/1 mask."""

    def __init__(self, update, mask):
        self.update, self.mask = update, mask

    def __call__(self, n, blurred, residual, estimate, weights):
        return self.update(n, blurred, residual, estimate, weights) * self.mask

    @property
    def history(self) -> list:
        return self.update.history


def frame_trust(
    window: FrameWindow, view: str, motion: FrameMotion, *, noise_sigma: float, band=None
) -> np.ndarray:
    """Trust in ``motion`` near its flow discontinuities, 1 elsewhere, float32 ``(H, W)``.

    The better of the predictions of the neighbouring frames that exist, each along the
    flow that leads to it (:func:`~stereodeblur.deconv.trust.motion_trust`). Occlusions
    show as large residuals, and what is covered on one side is seen on the other; the
    scene flow's occlusion mask is wider than that and is not used. ``band``: the pixels
    near the motion's flow discontinuities, if already known
    (:func:`~stereodeblur.deconv.trust.near_motion_boundaries` of ``motion.flow_forward``).
    """
    (trust,) = frame_trusts(window, view, (motion,), noise_sigma=noise_sigma, bands=(band,))
    return trust


def frame_trusts(
    window: FrameWindow, view: str, motions, *, noise_sigma: float, bands
) -> list[np.ndarray]:
    """:func:`frame_trust` of each of several motions of ``view`` (``bands``: one each, or
    None), sharing the work (:func:`~stereodeblur.deconv.trust.motion_trusts`); the trusts
    towards the preceding frame are computed meanwhile in a thread of their own."""
    from ..deconv.trust import motion_trusts, near_motion_boundaries

    blurred = window.blurred(view)
    backward = [i for i, m in enumerate(motions) if m.flow_backward is not None]
    if window.other is None:
        backward = []
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="trust") as pool:
        if backward:
            preceding = window.frame(view, window.other)
            flows = [motions[i].flow_backward for i in backward]
            pending = pool.submit(motion_trusts, blurred, preceding, flows, noise_sigma=noise_sigma)
        following = window.frame(view, window.neighbour)
        flows = [motion.flow_forward for motion in motions]
        trusts = motion_trusts(blurred, following, flows, noise_sigma=noise_sigma)
        duty_cycle = window.exposure.duty_cycle
        bands = [
            near_motion_boundaries(motion.flow_forward, duty_cycle) if band is None else band
            for motion, band in zip(motions, bands, strict=True)
        ]
        if backward:
            for i, trust in zip(backward, pending.result(), strict=True):
                trusts[i] = np.maximum(trusts[i], trust)
    return [
        np.where(band, trust, 1.0).astype(np.float32)
        for trust, band in zip(trusts, bands, strict=True)
    ]


def gate_trusts(
    window: FrameWindow, view: str, motion: FrameMotion, *, noise_sigma: float
) -> GateTrusts | None:
    """:func:`frame_trust` of ``motion`` and of its dense flow, both in ``motion``'s
    boundary band (1 outside it); None without a dense flow (``boundary_weights='gated'``)."""
    from dataclasses import replace

    from ..deconv.trust import near_motion_boundaries

    if motion.boundary_flow is None:
        return None
    band = near_motion_boundaries(motion.flow_forward, window.exposure.duty_cycle)
    forward, backward = motion.boundary_flow
    dense = replace(
        motion,
        flow_forward=forward,
        flow_backward=-forward if backward is None else backward,
        boundary_flow=None,
    )
    own, dense = frame_trusts(
        window, view, (motion, dense), noise_sigma=noise_sigma, bands=(band, band)
    )
    return GateTrusts(own, dense, noise_sigma)


def resolve_alpha(settings: DeblurSettings, blurred: np.ndarray, trust=None, *, noise_sigma=None):
    """The prior weight of a run: ``settings.alpha``, or for ``'auto'`` (and as the floor of
    ``'held-out'``) :func:`~stereodeblur.deconv.noise.auto_alpha` of ``blurred`` (from
    ``noise_sigma`` if given), raised to :func:`~stereodeblur.deconv.trust.alpha_from_trust`
    with a trust map.
    """
    if settings.alpha not in NOISE_RULES:
        return float(settings.alpha)
    from ..deconv.noise import alpha_from_sigma, estimate_noise_sigma

    sigma = estimate_noise_sigma(blurred) if noise_sigma is None else noise_sigma
    alpha = alpha_from_sigma(sigma)
    if trust is not None:
        from ..deconv.trust import alpha_from_trust

        alpha = max(alpha, alpha_from_trust(trust))
    return alpha


def _gt_mask(scene: StereoScene, view: str, index: int) -> np.ndarray:
    """Data weights 0 on the scene's gt/mixed pixels of a frame, 1 elsewhere."""
    from ..deconv.weights import initial_weights_from_occlusion

    if not scene.has_gt("mixed", view, index):
        path = scene.gt_path("mixed", view, index)
        raise InputError(f"boundary_mask='gt' needs {path}, which is missing")
    return initial_weights_from_occlusion(scene.read_gt_mixed(view, index))


def data_terms(
    scene: StereoScene,
    window: FrameWindow,
    view: str,
    view_operator: ViewOperator,
    settings: DeblurSettings,
) -> DataTerms:
    """Data weights, update, anchor, trust and alpha of ``view`` (see :class:`DataTerms`).

    The trust of the motion the operator uses and, where the dense flow mends the
    boundaries, the scene flow's own trust (what ``alpha='auto'`` follows: the dense flow
    does not mend the segments' misfit elsewhere) share one noise estimate and the window.
    """
    from ..deconv.noise import estimate_noise_sigma
    from ..deconv.weights import PaperWeights, hidden_weights, initial_weights_from_occlusion

    blurred = window.blurred(view)
    gate = view_operator.trusts
    sigma = estimate_noise_sigma(blurred) if gate is None else gate.noise_sigma
    motion, sf = view_operator.motion, view_operator.motion.sceneflow
    dense_rows = view_operator.flow_rows is not None
    shape = tuple(motion.flow_forward.shape[:2]) if sf is None else sf.shape
    weights = np.ones(shape, np.float32)
    update = anchor = trust = alpha_trust = None
    if settings.boundary_weights == "paper":
        update = PaperWeights()
        if sf is not None:
            weights = initial_weights_from_occlusion(sf.occlusion)
    elif settings.boundary_weights in ("adaptive", "gated"):
        from ..deconv.trust import OUTSIDE_WEIGHT, leaves_view, trust_anchor

        # Pixels whose exposure path leaves the view show content the blur model replaces
        # by the edge pixel's: a small data weight (not an anchor, and not in the trust
        # map, so that alpha does not rise for them; stereodeblur.deconv.trust).
        duty_cycle = window.exposure.duty_cycle
        outside = leaves_view(motion.flow_forward, motion.flow_backward, duty_cycle)
        weights = np.where(outside, OUTSIDE_WEIGHT, 1.0).astype(np.float32)
        if gate is not None:  # 'gated': measured for the gate
            trust = np.where(view_operator.flow_rows, gate.dense, gate.own).astype(np.float32)
            alpha_trust = gate.own
        else:
            motions, bands = [motion], [None]
            if dense_rows and settings.alpha in NOISE_RULES:  # and the own flow's, in its band
                motions.append(view_operator.own)
                bands.append(view_operator.flow_rows)
            trusts = frame_trusts(window, view, motions, noise_sigma=sigma, bands=bands)
            trust, alpha_trust = trusts[0], trusts[-1]
        if settings.boundary_weights == "adaptive" and not dense_rows:
            anchor = trust_anchor(trust)
    if settings.boundary_mask == "gt":
        keep = _gt_mask(scene, view, window.index)
        weights = weights * keep
        if update is not None:
            update = _MaskedUpdate(update, keep)
    if view_operator.hidden is not None:
        weights = weights * hidden_weights(view_operator.hidden)
    alpha = resolve_alpha(settings, blurred, alpha_trust, noise_sigma=sigma)
    return DataTerms(weights, update, anchor, trust, alpha, sigma)
