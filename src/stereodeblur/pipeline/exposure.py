"""The exposure time of a stereo frame from its blurred frames (``DeblurSettings.exposure='auto'``).

Each view's frame is compared with its optical flow (DIS) to the frames before and after: the
blur's extent along the motion, as a share of the motion over one frame interval, is the duty
cycle (:mod:`stereodeblur.blur.exposure`). Both views' windows vote in one sum.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..blur.exposure import (
    WINDOWS,
    central_flow,
    duty_cycle_curves,
    duty_cycle_from_curves,
    window_stride,
)
from ..geometry.camera import Exposure
from .window import VIEWS, FrameWindow


@dataclass(frozen=True)
class ExposureEstimate:
    """The exposure estimated for one stereo frame.

    Attributes
    ----------
    exposure : Exposure
        The frame rate and the estimated exposure time (0 where no window moved enough to
        tell, or the frames look sharp).
    confidence : float
        Share of bootstrap resamplings of the windows that agree within 20 %
        (:class:`~stereodeblur.blur.exposure.DutyEstimate`); 0 without windows.
    windows : int
        Windows (both views) that voted.
    """

    exposure: Exposure
    confidence: float
    windows: int


def estimate_exposure(window: FrameWindow) -> ExposureEstimate:
    """The exposure of ``window``'s frame from both views' blurred frames and their flows to
    the neighbouring frames (:func:`~stereodeblur.blur.exposure.duty_cycle_curves`)."""
    from ..sceneflow.initial import initial_optical_flow

    sides = [window.neighbour] + ([] if window.other is None else [window.other])
    stride = window_stride(window.shape, WINDOWS // len(VIEWS))
    curves = []
    for view in VIEWS:
        blurred = window.blurred(view)
        flows = {
            i - window.index: initial_optical_flow(blurred, window.frame(view, i)) for i in sides
        }
        curves.extend(duty_cycle_curves(blurred, central_flow(flows), stride=stride))
    found = duty_cycle_from_curves(curves)
    duty = 0.0 if not found.windows else found.duty_cycle
    rate = window.exposure.frame_rate
    exposure = Exposure(rate, min(duty / rate, 1 / rate))
    return ExposureEstimate(exposure, found.confidence, found.windows)
