"""Scene flow at the image border of a static scene: the camera's motion must win the pixels
it carries out of the view (``SceneFlowSettings.dominant_leave_window``).

The calibration family's scene of seed 1059 at 160x120: a plane of fine stripes (3.9 px period
at 320x240) seen by a camera moving forward, yawing and moving sideways, 17 px of blur, no
noise. Along the stripes every shift matches; where the pixels the camera carries out of the
view at t + 1 pay a wrong match's cost, the border takes an aliased motion that stays in view.
"""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import frame_motion
from stereodeblur.sceneflow.settings import SceneFlowSettings
from stereodeblur.settings import DeblurSettings
from stereodeblur.synth.family import family_scene, write_family_scene


@pytest.fixture(scope="module")
def striped(tmp_path_factory):
    root = tmp_path_factory.mktemp("border") / "family_1059"
    write_family_scene(family_scene(1059, size=(160, 120)), root)
    return open_scene(root)


def _errors(scene, sceneflow: SceneFlowSettings) -> np.ndarray:
    """End-point errors of frame 1's estimate (left view, its segments as estimated)."""
    settings = DeblurSettings(relabel_radius=0, sceneflow=sceneflow)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    return np.linalg.norm(motion.sceneflow.flow() - scene.read_gt_flow("left", 1), axis=-1)


def test_the_camera_motion_wins_the_border_of_a_striped_static_scene(striped):
    error = _errors(striped, SceneFlowSettings(dominant_leave_window=16.0))
    assert np.mean(error > 3.0) < 0.005 and np.mean(error) < 1.0


def test_with_a_wrong_matchs_cost_at_the_border_an_aliased_motion_takes_it(striped):
    error = _errors(striped, replace(SceneFlowSettings(), dominant_leave_window=0.0))
    assert np.mean(error > 3.0) > 0.05
    width = error.shape[1]
    assert np.mean(error[:, -width // 8 :] > 3.0) > 0.3  # the border the camera leaves
