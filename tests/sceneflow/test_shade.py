"""Scene flow in deep shade: a dark hedge behind a sunlit bush must keep its own depth.

On KITTI 2015's frame 000007 a hedge in deep shade took the disparity of the bushes in front of
it (``benchmarks/kitti_sceneflow.py``). Rendered here (:func:`.driving.shaded_hedge`): under shot
noise the sunlit parts set the image's one noise level, which in linear light is far above the
dark hedge's own noise and texture, so its census codes read as flat, every disparity matches,
and the bush's proposal took 89 % of it. The frames' noise is now measured in their darkest
tenth too: it is far below the image's level there, so the census compares the square root
(``docs/defaults.md#census-encoding``), and the hedge keeps its depth (1.2 % outliers).
"""

import warnings

import numpy as np
import pytest

from stereodeblur.sceneflow import estimate_scene_flow
from stereodeblur.sceneflow.preparation import prepare_frames
from stereodeblur.sceneflow.settings import SceneFlowSettings

from .driving import shaded_hedge


@pytest.fixture(scope="module")
def hedge():
    return shaded_hedge()


def _hedge_outliers(scene, settings: SceneFlowSettings) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SceneFlowWarning on weak texture is allowed
        estimate = estimate_scene_flow(*scene.frames, scene.camera, settings=settings)
    error = np.abs(estimate.sceneflow.disparity() - scene.disparity)
    return float(np.mean(error[scene.hedge] > 3.0))


def test_the_scene_is_a_dark_hedge_behind_a_bright_bush(hedge):
    assert hedge.hedge.mean() > 0.15 and hedge.bush.mean() > 0.1
    frame = hedge.frames[0]
    assert np.median(frame[hedge.hedge]) < 0.01 and np.median(frame[hedge.bush]) > 0.2
    assert np.median(hedge.disparity[hedge.hedge]) < np.median(hedge.disparity[hedge.bush]) - 5


def test_the_frames_pick_the_square_root(hedge):
    prepared = prepare_frames(hedge.frames, SceneFlowSettings())
    assert prepared.census_gamma == 0.5
    assert prepare_frames(hedge.frames, SceneFlowSettings(census_gamma=1.0)).census_gamma == 1.0


def test_the_hedge_keeps_its_depth(hedge):
    assert _hedge_outliers(hedge, SceneFlowSettings()) < 0.05
