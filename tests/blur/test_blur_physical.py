"""The homography operator reproduces physically rendered blur (ray casting, not our operator)."""

import numpy as np
import pytest

from stereodeblur.blur.homography import homography_blur
from stereodeblur.blur.visibility import hidden_fraction, sceneflow_visibility
from stereodeblur.geometry import move_plane, se3_exp
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.synth.objects import make_object_scene
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
    A = homography_blur(sf, scene.exposure, num_samples=70, interpolation="bilinear")
    predicted = A.forward(scene.sharp[view][frame])
    border = 8
    err = np.abs(predicted - scene.frames[view][frame])[border:-border, border:-border]
    assert err.mean() < 0.01, err.mean()
    # It is the exact blur, not just any smoothing: the unblurred frame is much farther off.
    unblurred = np.abs(scene.sharp[view][frame] - scene.frames[view][frame])[
        border:-border, border:-border
    ]
    assert err.mean() < 0.25 * unblurred.mean(), (err.mean(), unblurred.mean())
    # Cubic sampling smooths the sharp image less than bilinear: closer to the rendering.
    cubic = homography_blur(sf, scene.exposure, num_samples=70, interpolation="cubic")
    err_cubic = np.abs(cubic.forward(scene.sharp[view][frame]) - scene.frames[view][frame])
    assert err_cubic[border:-border, border:-border].mean() < 0.85 * err.mean()


@pytest.mark.parametrize("view", ["left", "right"])
def test_layered_operator_reproduces_rendered_occlusions(view):
    """Four planar squares moving over a background, with their true planes and motions."""
    scene = make_object_scene("squares", size=(160, 120), num_frames=2, num_samples=48)
    frame = 1
    normals = []
    for obj in scene.objects:  # every object of this scene is a plane
        M = se3_exp(frame * obj.twist)
        normals.append(move_plane(obj.normal, M[:3, :3], M[:3, 3]))
    labels = scene.object_ids[view][frame]
    sf = SceneFlow(
        scene.camera,
        labels,
        np.array(normals),
        np.array([obj.twist for obj in scene.objects]),
        np.zeros(labels.shape, bool),
        view=view,
    )
    visible = sceneflow_visibility(sf, scene.exposure, 70)
    sharp, blurred = scene.sharp[view][frame], scene.frames[view][frame]
    mixed = scene.mixed[view][frame]
    inner = np.zeros(mixed.shape, bool)
    inner[8:-8, 8:-8] = True
    errors = {}
    for name, visible_ in (("paper", None), ("layered", visible)):
        A = homography_blur(sf, scene.exposure, num_samples=70, visible=visible_)
        err = np.abs(A.forward(sharp) - blurred).mean(-1)
        errors[name] = err[inner & mixed].mean(), err[inner & ~mixed].mean()
    # Where objects mix, showing the covering surface at every instant cuts the error by a
    # third (what remains: surfaces hidden at the reference instant, pixel-sized edges).
    assert errors["layered"][0] < 0.75 * errors["paper"][0], errors
    assert errors["layered"][1] < 0.003, errors  # elsewhere both are the exact blur
    assert errors["paper"][1] < 0.003, errors
    # Pixels that show a hidden surface for a quarter of the exposure are mixed ones.
    hidden = hidden_fraction(visible) >= 0.25
    assert hidden.sum() > 50
    assert np.mean(mixed[hidden]) > 0.9
