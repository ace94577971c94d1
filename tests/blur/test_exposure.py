"""The exposure (duty cycle) estimated from a blurred frame and its optical flow, checked on
physically rendered blur (ray casting: straight and curved paths)."""

from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.blur.exposure import (
    DEFAULT_CANDIDATES,
    central_flow,
    duty_cycle_curves,
    duty_cycle_from_curves,
    estimate_duty_cycle,
    window_stride,
)
from stereodeblur.geometry.camera import Exposure
from stereodeblur.sceneflow.initial import initial_optical_flow
from stereodeblur.synth.planar import FRAME_RATE, planar_setup
from stereodeblur.synth.render import render_scene


def rendered(name: str, duty: float, size=(320, 240)):
    """Frames 0-2 of the left view of planar scene ``name`` exposed for ``duty``."""
    setup = planar_setup(name, size=size, num_frames=3)
    setup = replace(setup, exposure=Exposure(FRAME_RATE, duty / FRAME_RATE))
    return render_scene(setup, num_samples=24).frames["left"]


@pytest.mark.parametrize(
    ("name", "duty"), [("upward", 0.8), ("yaw", 0.4), ("long_exposure_roll", 0.4)]
)
def test_the_duty_cycle_of_rendered_blur_within_ten_percent(name, duty):
    frames = rendered(name, duty)
    flow = central_flow(
        {
            1: initial_optical_flow(frames[1], frames[2]),
            -1: initial_optical_flow(frames[1], frames[0]),
        }
    )
    found = estimate_duty_cycle(frames[1], flow)
    assert abs(found.duty_cycle / duty - 1) <= 0.1, found
    assert found.windows > 50 and found.confidence > 0.9


def test_central_flow_is_the_mean_motion_per_frame_interval():
    rng = np.random.default_rng(0)
    forward = rng.normal(size=(4, 5, 2))
    backward = -forward + 0.2
    assert np.allclose(central_flow({1: forward, -1: backward}), forward - 0.1)
    assert np.allclose(central_flow({2: forward}), forward / 2)
    with pytest.raises(ValueError, match="flows must all be"):
        central_flow({1: forward, -1: backward[:3]})


def test_one_window_cannot_outvote_the_others():
    """Each window adds at most the cap: one window sure of another answer loses to ten."""
    cand = DEFAULT_CANDIDATES
    agreeing = np.tile(100 * (cand - 0.5) ** 2, (10, 1))
    stubborn = 1e6 * (cand - 0.1) ** 2
    found = duty_cycle_from_curves(np.vstack([agreeing, stubborn]))
    assert found.duty_cycle == cand[np.abs(cand - 0.5).argmin()] and found.windows == 11
    assert np.isnan(duty_cycle_from_curves(np.empty((0, cand.size))).duty_cycle)


def test_a_still_frame_has_no_window():
    """Windows need motion (2 px per frame): a still frame has none, and more windows need
    more pixels (their spacing grows with the frame)."""
    frame = np.random.default_rng(1).random((96, 128))
    assert duty_cycle_curves(frame, np.zeros((96, 128, 2))).shape == (0, DEFAULT_CANDIDATES.size)
    assert window_stride((240, 320)) == 16 and window_stride((480, 640)) == 32
