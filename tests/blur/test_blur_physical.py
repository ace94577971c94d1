"""The homography operator reproduces physically rendered blur (ray casting, not our operator)."""

import numpy as np
import pytest

from stereodeblur.blur.homography import homography_blur
from stereodeblur.geometry import move_plane, se3_exp
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.synth.planar import make_planar_scene


@pytest.mark.parametrize("name", ["strong_yaw", "fast_approach", "long_exposure_roll"])
@pytest.mark.parametrize("view", ["left", "right"])
def test_operator_reproduces_rendered_blur(name, view):
    scene = make_planar_scene(name, size=(160, 120), num_frames=2, num_samples=48)
    (plane,) = scene.objects
    frame = 1
    M = se3_exp(frame * plane.twist)  # the plane at frame 1's centre
    normal = move_plane(plane.normal, M[:3, :3], M[:3, 3])
    H, W = scene.frames[view][frame].shape[:2]
    sf = SceneFlow(
        scene.camera,
        np.zeros((H, W), np.int32),
        normal[None],
        plane.twist[None],
        np.zeros((H, W), bool),
        view=view,
    )
    A = homography_blur(sf, scene.exposure, num_samples=70)
    predicted = A.forward(scene.sharp[view][frame])
    border = 8
    err = np.abs(predicted - scene.frames[view][frame])[border:-border, border:-border]
    assert err.mean() < 0.01, err.mean()
    # It is the exact blur, not just any smoothing: the unblurred frame is much farther off.
    unblurred = np.abs(scene.sharp[view][frame] - scene.frames[view][frame])[
        border:-border, border:-border
    ]
    assert err.mean() < 0.25 * unblurred.mean(), (err.mean(), unblurred.mean())
