"""Scene flow on a driving scene: the camera's motion must win the road.

A flat, weakly textured road with hard shadows between a hedge and a wall, the camera
moving forward by 60 px per frame at the bottom of the image, blurred frames, frame
t + 1 brighter than frame t (:mod:`tests.sceneflow.driving`).
"""

import warnings

import numpy as np
import pytest

from stereodeblur.sceneflow import estimate_scene_flow
from stereodeblur.sceneflow.settings import SceneFlowSettings

from .driving import driving_pair


@pytest.fixture(scope="module")
def road():
    pair = driving_pair((320, 240), bottom_flow=60.0, duty_cycle=0.3, gain=1.2, num_samples=8)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SceneFlowWarning on weak texture is allowed
        estimate = estimate_scene_flow(*pair.frames, pair.camera, exposure=pair.exposure)
    return pair, estimate


def test_the_scene_moves_as_asked(road):
    pair, _ = road
    width = pair.flow.shape[1]
    assert pair.road.mean() > 0.3 and pair.road[-1].all()
    assert 59.0 < pair.flow[-1, width // 2, 1] < 61.0  # down, at the bottom centre
    assert np.linalg.norm(pair.flow[-1], axis=-1).max() > 80.0  # more in the corners
    assert pair.frames[2].mean() > 1.1 * pair.frames[0].mean()  # the gain change


def test_flow_on_the_road_within_a_pixel(road):
    pair, estimate = road
    error = np.linalg.norm(estimate.sceneflow.flow() - pair.flow, axis=-1)
    initial = np.linalg.norm(estimate.initial_flow - pair.flow, axis=-1)
    on_road = pair.road
    bottom = on_road & (np.arange(on_road.shape[0]) >= 7 * on_road.shape[0] // 8)[:, None]
    assert initial[bottom].mean() > 5.0  # the dense flow alone fails there
    assert error[on_road].mean() < 1.0
    assert error[bottom].mean() < 1.5


def test_one_motion_explains_the_road(road):
    pair, estimate = road
    sf = estimate.sceneflow
    twists = sf.twists[sf.labels[pair.road]]
    _, counts = np.unique(np.round(twists, 9), axis=0, return_counts=True)
    assert counts.max() > 0.9 * counts.sum()


@pytest.mark.slow
def test_a_weaker_motion_prior_lets_the_images_correct_the_ego_motion():
    # Sharp frames (as in KITTI), 80 px at the bottom, 40 % brighter at t + 1, half the
    # road's texture: the motion fitted to the dense flow (which fails at the bottom) is
    # about 1 % slow, and the per-pixel motion prior of the refinement keeps it there.
    pair = driving_pair(
        (320, 240), bottom_flow=80.0, duty_cycle=0.0, gain=1.4, road_contrast=0.015, num_samples=1
    )
    errors = {}
    for share in (None, 0.003):
        settings = SceneFlowSettings(motion_prior_share=share)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            estimate = estimate_scene_flow(*pair.frames, pair.camera, settings=settings)
        error = np.linalg.norm(estimate.sceneflow.flow() - pair.flow, axis=-1)
        errors[share] = error[pair.road].mean()
    assert errors[0.003] < 0.5 < errors[None] < 1.0


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="blur balancing moves the road's motion 2 % off")
def test_blurred_fast_road_with_a_gain_change():
    # 80 px at the bottom, blur over half the frame interval, 40 % brighter at t + 1, half
    # the texture. The fused motion is right (0.03 %) and the first refinement keeps it;
    # the blur-balanced second refinement (no prior) takes it 1.9 % slow: 1.3 px on the
    # road. Without balancing 0.40 px, but the planar scene fast_approach needs the balancing
    # (docs/defaults.md#blur-balancing).
    pair = driving_pair(
        (320, 240), bottom_flow=80.0, duty_cycle=0.5, gain=1.4, road_contrast=0.015, num_samples=8
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        estimate = estimate_scene_flow(*pair.frames, pair.camera, exposure=pair.exposure)
    error = np.linalg.norm(estimate.sceneflow.flow() - pair.flow, axis=-1)
    assert error[pair.road].mean() < 1.0
