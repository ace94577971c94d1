"""The exposure time of a stereo frame from its blurred frames.

Each view's frame is compared with its optical flow (DIS) to the frames before and after: the
blur's extent along the motion, as a share of the motion over one frame interval, is the duty
cycle (:mod:`stereodeblur.blur.exposure`). The views' windows vote in one sum. With
``DeblurSettings.exposure='auto'`` the estimate is deblurred for, unless the blur it gives is
under :data:`SHARP_BLUR` pixels (the frames then pass through); with an exposure given, a
warning says when the frames disagree with it (:func:`exposure_doubt`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..blur.exposure import (
    WINDOWS,
    central_flow,
    duty_cycle_curves,
    duty_cycle_from_curves,
    window_motion,
    window_stride,
)
from ..errors import FrameWarning
from ..geometry.camera import Exposure
from ..progress import report
from ..settings import DeblurSettings
from .motion import view_dense_flow
from .window import FrameWindow

EXPOSURE_TOLERANCE = 1.4
"""A given exposure more than this factor away from the frames' estimate is doubted (a
warning; the given one is used). Why: docs/defaults.md#exposure-check"""
DOUBT_WINDOWS = 20
"""Fewer windows (small or still frames) say too little to doubt a given exposure."""
SHARP_BLUR = 2.0
"""An estimate whose blur is shorter (pixels, in the median moving window) reads the frames as
sharp: ``exposure='auto'`` passes them through. Why: docs/defaults.md#sharp-frames"""


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
    blur : float
        The blur this exposure gives the median moving window (pixels; 0 without windows).
    """

    exposure: Exposure
    confidence: float
    windows: int
    blur: float

    @property
    def sharp(self) -> bool:
        """Whether the frames read as sharp (blur under :data:`SHARP_BLUR` pixels)."""
        return self.blur < SHARP_BLUR


def estimate_exposure(window: FrameWindow, dense: dict) -> ExposureEstimate:
    """The exposure of ``window``'s frame from the blurred frames of the views in ``dense`` and
    their dense flows (``{view: (to the neighbour, to the other side or None)}``,
    :func:`~.motion.view_dense_flow`; :func:`~stereodeblur.blur.exposure.duty_cycle_curves`)."""
    stride = window_stride(window.shape, WINDOWS // len(dense))
    curves, speeds = [], []
    for view, (forward, backward) in dense.items():
        flows = {window.neighbour - window.index: forward}
        if backward is not None:
            flows[window.other - window.index] = backward
        flow = central_flow(flows)
        motion = window_motion(flow, stride)
        curves.extend(duty_cycle_curves(window.blurred(view), flow, stride=stride, motion=motion))
        speeds.extend(np.hypot(*motion[2].T))
    found = duty_cycle_from_curves(curves)
    duty = 0.0 if not found.windows else found.duty_cycle
    rate = window.exposure.frame_rate
    blur = duty * float(np.median(speeds)) if speeds else 0.0
    return ExposureEstimate(Exposure(rate, duty / rate), found.confidence, found.windows, blur)


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


def exposed_window(window: FrameWindow, views, settings: DeblurSettings, progress, label: str):
    """``window`` with its exposure estimated from ``views`` (``settings.exposure='auto'``), the
    estimate (None for a given exposure 0) and the views' dense flows it was made from
    (:func:`~.motion.view_dense_flow`, for the motion to reuse). A given exposure the frames
    disagree with is kept, with a :class:`~stereodeblur.errors.FrameWarning`
    (:func:`exposure_doubt`; ``label`` names the frame, e.g. 'frame 12')."""
    auto = settings.exposure == "auto"
    if not auto and window.exposure.exposure == 0:
        return window, None, None
    report(progress, "exposure (from the frames)" if auto else "exposure check")
    dense = {view: view_dense_flow(window, view) for view in views}
    found = estimate_exposure(window, dense)
    seconds, duty = found.exposure.exposure, found.exposure.duty_cycle
    said = f"exposure {seconds:.4g} s (duty cycle {duty:.2f}, blur {found.blur:.1f} px, "
    said += f"{found.windows} windows)"
    if auto and found.sharp and seconds > 0:
        said += f": read as sharp frames (blur under {SHARP_BLUR:g} px), passed through"
    report(progress, said)
    if auto:
        used = Exposure(found.exposure.frame_rate, 0.0) if found.sharp else found.exposure
        return replace(window, exposure=used), found, dense
    doubt = exposure_doubt(window.exposure, found, label)
    if doubt is not None:
        warnings.warn(doubt, FrameWarning, stacklevel=3)
    return window, found, dense
