"""The range guard: no motion where the estimate leaves [0, 1] over a whole region."""

import warnings

import numpy as np
import pytest

from stereodeblur.geometry import Exposure, StereoCamera
from stereodeblur.io.scene import CameraInfo, SceneWriter, open_scene
from stereodeblur.pipeline import DeblurSettings, FrameMotion, deblur_frame, neighbour_of

SIZE = (48, 40)  # width, height
PERIOD = 4.0
CAMERA = StereoCamera([[50.0, 0, SIZE[0] / 2], [0, 50.0, SIZE[1] / 2], [0, 0, 1]], 0.1)
FLOW_SETTINGS = {
    "kernels": "displacement",
    "motion_source": "initial-flow",
    "alpha": 1e-3,
    "boundary_weights": "none",
    "observations": "single",
    "num_irls": 2,
    "num_cg": 10,
    "num_samples": 16,
}


def _stripes(root):
    """A still scene of vertical stripes (period 4 px): its frames are its sharp images."""
    w, h = SIZE
    info = CameraInfo(
        CAMERA,
        Exposure(20.0, 0.04),  # duty cycle 0.8
        "linear",
    )
    x = np.arange(w)
    image = 0.5 + 0.35 * np.sin(2 * np.pi * x / PERIOD)
    image = np.repeat(np.broadcast_to(image, (h, w))[..., None], 3, axis=-1).astype(np.float32)
    writer = SceneWriter(root, info)
    for i in range(3):
        for view in ("left", "right"):
            writer.write_frame(view, i, image)
            writer.write_gt_sharp(view, i, image)
    return open_scene(root), image


def _across_the_stripes(scene):
    """A wrong motion across the stripes: a 3.4 px blur that leaves 17 % of their contrast."""
    w, h = SIZE
    forward = np.zeros((h, w, 2), np.float32)
    forward[..., 0] = 0.85 * PERIOD / 0.8
    neighbour = neighbour_of(1, scene.num_frames)
    return FrameMotion(1, neighbour, "left", None, forward, -forward)


@pytest.mark.parametrize("guard", [True, False])
def test_a_motion_that_cannot_have_made_the_frame_leaves_it_as_it_is(tmp_path, guard):
    scene, sharp = _stripes(tmp_path / "scene")
    settings = DeblurSettings(**FLOW_SETTINGS, range_guard=guard)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = deblur_frame(scene, 1, settings=settings, motion=_across_the_stripes(scene))
    said = [str(w.message) for w in caught if "range guard" in str(w.message)]
    assert len(said) == int(guard)
    inner = (slice(8, -8), slice(8, -8))
    error = np.sqrt(np.mean((result.image - sharp)[inner] ** 2))
    if guard:
        assert result.unexplained is not None and result.unexplained[inner].mean() > 0.9
        assert error < 0.02
    else:
        assert result.unexplained is None
        assert error > 0.1


def test_a_right_motion_is_not_touched(tmp_path):
    scene, sharp = _stripes(tmp_path / "scene")
    w, h = SIZE
    still = np.zeros((h, w, 2), np.float32)
    motion = FrameMotion(1, neighbour_of(1, scene.num_frames), "left", None, still, still)
    settings = DeblurSettings(
        kernels="displacement", motion_source="initial-flow", alpha=1e-3, num_irls=2, num_cg=10
    )
    result = deblur_frame(scene, 1, settings=settings, motion=motion)
    assert result.unexplained is None


def test_the_alpha_choice_scores_guarded_solutions(tmp_path, monkeypatch):
    """With ``alpha='held-out'`` every candidate is range-guarded before the other view
    judges it: the choice scores what the view's result would be."""
    from stereodeblur.pipeline import deblur_stereo_frame
    from stereodeblur.pipeline import frame as frame_module
    from stereodeblur.sceneflow.model import SceneFlow

    scene, sharp = _stripes(tmp_path / "scene")
    w, h = SIZE
    camera = CAMERA
    depth = camera.fx * camera.baseline / PERIOD  # disparity one period: the views agree
    speed = 0.85 * PERIOD / 0.8 * depth / camera.fx  # the same wrong motion as above
    sceneflow = SceneFlow(
        camera,
        np.zeros((h, w), np.int32),
        np.array([[0.0, 0.0, 1.0 / depth]]),
        np.array([[speed, 0.0, 0.0, 0.0, 0.0, 0.0]]),
        np.zeros((h, w), bool),
    )
    scored = []
    error = frame_module.prediction_error
    monkeypatch.setattr(
        frame_module,
        "prediction_error",
        lambda image, *a, **k: scored.append(image) or error(image, *a, **k),
    )
    settings = DeblurSettings(
        kernels="homography",
        motion_source="sceneflow",
        alpha="held-out",
        boundary_weights="none",
        observations="single",
        num_irls=2,
        num_cg=10,
        num_samples=16,
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = deblur_stereo_frame(scene, 1, settings=settings, sceneflow=sceneflow)
    said = [str(w.message) for w in caught if "range guard" in str(w.message)]
    assert len(said) == 2  # once per view, not per candidate
    inner = (slice(8, -8), slice(8, -8))
    assert len(scored) >= 4  # at least two candidates per view
    for image in scored:
        assert np.sqrt(np.mean((image - sharp)[inner] ** 2)) < 0.02
    for view in ("left", "right"):
        frame = result.frames[view]
        assert frame.unexplained is not None and frame.unexplained[inner].mean() > 0.9


def test_a_motion_that_fails_on_much_of_the_frame_is_trusted_nowhere(tmp_path, monkeypatch):
    """Stripes on the left half, a smooth ramp on the right, the wrong motion everywhere: the
    guard finds the stripes; covering more than ``RANGE_WHOLE`` of the frame, they take it all."""
    from stereodeblur import settings as constants

    scene, _ = _stripes(tmp_path / "stripes")
    w, h = SIZE
    half = np.array(scene.read_frame("left", 1))
    half[:, w // 2 :] = np.linspace(0.3, 0.7, w - w // 2)[None, :, None]
    info = CameraInfo(CAMERA, Exposure(20.0, 0.04), "linear")
    writer = SceneWriter(tmp_path / "half", info)
    for i in range(3):
        for view in ("left", "right"):
            writer.write_frame(view, i, half)
    scene = open_scene(tmp_path / "half")
    settings = DeblurSettings(**FLOW_SETTINGS)
    found = {}
    for whole in (1.0, constants.RANGE_WHOLE):
        monkeypatch.setattr(constants, "RANGE_WHOLE", whole)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = deblur_frame(scene, 1, settings=settings, motion=_across_the_stripes(scene))
        found[whole] = result.unexplained
    assert 0.2 < found[1.0].mean() < 0.8 and not found[1.0][:, -8:].any()
    assert found[constants.RANGE_WHOLE].all()
