"""The exposure time of a stereo frame from its blurred frames.

Each view's frame is compared with its optical flow (DIS) to the frames before and after: the
blur's extent along the motion, as a share of the motion over one frame interval, is the duty
cycle (:mod:`stereodeblur.blur.exposure`). The views' windows vote in one sum. With
``DeblurSettings.exposure='auto'`` the estimate is deblurred for; with an exposure given, a
warning says when the frames disagree with it (:func:`exposure_doubt`).
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
from .window import FrameWindow

EXPOSURE_TOLERANCE = 1.4
"""A given exposure more than this factor away from the frames' estimate is doubted (a
warning; the given one is used). Why: docs/defaults.md#exposure-check"""
DOUBT_WINDOWS = 20
"""Fewer windows (small or still frames) say too little to doubt a given exposure."""


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


def estimate_exposure(window: FrameWindow, dense: dict) -> ExposureEstimate:
    """The exposure of ``window``'s frame from the blurred frames of the views in ``dense`` and
    their dense flows (``{view: (to the neighbour, to the other side or None)}``,
    :func:`~.motion.view_dense_flow`; :func:`~stereodeblur.blur.exposure.duty_cycle_curves`)."""
    stride = window_stride(window.shape, WINDOWS // len(dense))
    curves = []
    for view, (forward, backward) in dense.items():
        flows = {window.neighbour - window.index: forward}
        if backward is not None:
            flows[window.other - window.index] = backward
        curves.extend(duty_cycle_curves(window.blurred(view), central_flow(flows), stride=stride))
    found = duty_cycle_from_curves(curves)
    duty = 0.0 if not found.windows else found.duty_cycle
    rate = window.exposure.frame_rate
    exposure = Exposure(rate, min(duty / rate, 1 / rate))
    return ExposureEstimate(exposure, found.confidence, found.windows)


def exposure_doubt(given: Exposure, found: ExposureEstimate, frame: str) -> str | None:
    """One line for a ``frame`` (e.g. 'frame 12') whose exposure ``given`` and the one its frames
    say (``found``, from at least :data:`DOUBT_WINDOWS` windows) differ by more than a factor
    :data:`EXPOSURE_TOLERANCE`, else None."""
    seconds, said = given.exposure, found.exposure.exposure
    agree = said * EXPOSURE_TOLERANCE >= seconds >= said / EXPOSURE_TOLERANCE
    if found.windows < DOUBT_WINDOWS or agree:
        return None
    return (
        f"{frame}: the exposure given, {seconds:.3g} s, looks too "
        f"{'long' if seconds > said else 'short'}: the frames say about {said:.2g} s "
        "(--exposure auto uses the frames' estimate)"
    )
