"""What deblurring a frame returns: :class:`FrameResult` per view, :class:`StereoFrameResult`
per stereo frame (:mod:`.frame`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..deconv.irls import DeblurResult
from .exposure import ExposureEstimate
from .motion import FrameMotion, StereoMotion


@dataclass(frozen=True)
class FrameResult:
    """A deblurred frame with what produced it.

    ``alpha`` is the prior weight used; ``weight_steps`` the boundary-weight updates
    (:class:`~stereodeblur.deconv.weights.WeightsStep`: weights and the residual norm
    they came from, per IRLS iteration), empty with fixed weights; ``trust`` the trust in
    the blur model per pixel (``boundary_weights='adaptive'`` or ``'gated'``, else None).
    ``timings``: seconds of ``'motion'`` (reading the frames included; from
    :func:`~.frame.deblur_stereo_frame` an equal share of the stereo frame's, and so of
    ``'exposure'`` with ``settings.exposure='auto'``), ``'operator'`` and
    ``'deconvolution'`` (data weights, trust and alpha included; the further observations'
    operators in ``'observations'``). ``observations``: the names of the further
    observations the estimate used (``settings.observations``), e.g. ``('other-view',
    'next', 'previous')``. ``unexplained``: the pixels the range guard deblurred with no
    motion (``settings.range_guard``; bool ``(H, W)``), None where it found none.
    ``alpha_scale``: the factor of ``alpha`` per pixel (``settings.local_alpha``; float32
    ``(H, W)``), None where one alpha holds for the whole view. ``exposure``: the exposure
    time (seconds) the frame was deblurred for, given or estimated (``settings.exposure``);
    at 0 the blurred frame passes through.
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
    observations: tuple = ()
    unexplained: np.ndarray | None = None
    alpha_scale: np.ndarray | None = None
    exposure: float | None = None

    @property
    def image(self) -> np.ndarray:
        return np.clip(self.result.image, 0.0, 1.0)


@dataclass(frozen=True)
class StereoFrameResult:
    """The deblurred views of one stereo frame, from one window and one motion.

    ``frames`` (dict) maps each requested view to its :class:`FrameResult`; ``timings`` holds
    the seconds of the shared stages, ``'read'``, ``'exposure'`` (``settings.exposure='auto'``)
    and ``'motion'``. ``exposure``: the frames' estimate of the exposure (deblurred for with
    ``settings.exposure='auto'``, else the check of the given one; None for a given 0).
    """

    index: int
    frames: dict
    motion: StereoMotion
    timings: dict = field(default_factory=dict)
    exposure: ExposureEstimate | None = None
