"""The frame window: neighbours, the frames read, and the ground truth a frame needs."""

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import DeblurSettings, gt_needs, neighbour_of, other_side, read_window
from tests.conftest import write_tiny_scene

GT = DeblurSettings(motion_source="gt")


@pytest.fixture
def scene(tmp_path):
    return open_scene(write_tiny_scene(tmp_path / "tiny", num_frames=3))


def test_neighbours():
    assert [neighbour_of(i, 3) for i in range(3)] == [1, 2, 1]
    assert [other_side(i, 3) for i in range(3)] == [None, 0, None]


def test_the_window_holds_read_only_frames(scene):
    window = read_window(scene, 1, ("left", "right"), DeblurSettings())
    assert (window.index, window.neighbour, window.other) == (1, 2, 0)
    assert set(window.images) == {(v, i) for v in ("left", "right") for i in (0, 1, 2)}
    np.testing.assert_array_equal(window.blurred("right"), scene.read_frame("right", 1))
    with pytest.raises(ValueError):
        window.blurred("left")[0, 0] = 0
    with pytest.raises(KeyError, match="no left frame 7"):
        window.frame("left", 7)
    given = scene.read_frame("left", 1)
    read_window(scene, 1, ("left",), GT, known={("left", 1): given})
    given[0, 0] = 0  # the caller's array stays writable


def test_gt_needs_lists_the_motions_and_masks_files(scene):
    path = scene.gt_path
    assert gt_needs(scene, 1, DeblurSettings()) == []
    assert gt_needs(scene, 1, GT) == [
        path("disparity", "left", 1),
        path("disparity", "left", 2),
        path("flow", "left", 1),
    ]
    assert gt_needs(scene, 2, GT) == [  # the last frame: motion to the previous frame
        path("disparity", "left", 2),
        path("disparity", "left", 1),
        path("flow", "left", 1),
    ]
    masked = DeblurSettings(boundary_mask="gt")
    assert gt_needs(scene, 0, masked, views=("right",)) == [path("mixed", "right", 0)]


def test_missing_ground_truth_is_named(scene):
    from stereodeblur.pipeline import deblur_frame

    scene.gt_path("disparity", "left", 2).unlink()
    with pytest.raises(InputError, match="motion_source='gt' needs .*disparity.*000002"):
        deblur_frame(scene, 1, settings=GT)
    with pytest.raises(InputError, match="out of range"):
        gt_needs(scene, 3, GT)


def test_the_estimator_reads_the_other_side_where_it_matches_there(scene):
    from dataclasses import replace

    from stereodeblur.pipeline import frame_motion
    from stereodeblur.sceneflow import SceneFlowSettings

    single = replace(DeblurSettings(), observations="single", boundary_flow=False, relabel_radius=0)
    assert ("right", 0) not in read_window(scene, 1, ("left",), single).images
    other = replace(single, sceneflow=SceneFlowSettings(other_side=True))
    assert ("right", 0) in read_window(scene, 1, ("left",), other).images
    first = read_window(scene, 0, ("left",), other)  # no other side: frames 0 and 1 only
    assert {i for _, i in first.images} == {0, 1}
    assert frame_motion(scene, 1, "left", other).sceneflow is not None
