"""Semi-real clips from a photograph: against the ray-cast renders of the same scene."""

import numpy as np
import pytest

from stereodeblur.evaluation.metrics import psnr
from stereodeblur.synth.photo import PhotoScene, render_clip, render_instant
from stereodeblur.synth.planar import make_planar_scene

SIZE = (160, 120)


@pytest.fixture(scope="module", params=["forward_yaw", "lateral_pitch"])
def rendered(request):
    return make_planar_scene(request.param, size=SIZE, num_samples=24)


def photo_of(scene, frame=1) -> PhotoScene:
    """The ray-cast scene's sharp frame, its disparity and its (only) twist."""
    (plane,) = scene.objects
    views = ("left", "right")
    return PhotoScene(
        images={v: scene.sharp[v][frame].mean(axis=2) for v in views},
        disparity={v: scene.disparity[v][frame] for v in views},
        labels={v: np.zeros(scene.sharp[v][frame].shape[:2], dtype=np.int64) for v in views},
        twists=np.asarray(plane.twist)[None],
        camera=scene.camera,
    )


def test_an_instant_moves_the_photograph_as_the_scene_moves(rendered):
    photo = photo_of(rendered)
    border = 12
    for view in ("left", "right"):
        moved, _ = render_instant(photo, view, 1.0)
        truth = rendered.sharp[view][2].mean(axis=2)
        assert psnr(moved[..., 0], truth, border=border) > 33.0
        # Not the photograph itself: the test can tell a motion from none.
        assert psnr(photo.images[view], truth, border=border) < 30.0


def test_blurred_frames_match_the_ray_cast_ones(rendered):
    photo = photo_of(rendered)
    clip = render_clip(photo, rendered.exposure, num_samples=24)
    border = 12
    for view in ("left", "right"):
        for i in range(3):
            truth = rendered.frames[view][i].mean(axis=2)
            assert psnr(clip.frames[view][i], truth, border=border) > 33.0, (view, i)
            sharp = rendered.sharp[view][i].mean(axis=2)
            assert psnr(clip.sharp[view][i], sharp, border=border) > 33.0, (view, i)
            inner = (slice(border, -border), slice(border, -border))
            disparity = rendered.disparity[view][i][inner]
            assert np.abs(clip.disparity[view][i][inner] - disparity).max() < 0.02
        assert np.array_equal(clip.sharp[view][1], photo.images[view])
    inner = (slice(border, -border), slice(border, -border))
    for i in range(2):
        assert np.abs(clip.flow[i][inner] - rendered.flow[i][inner]).max() < 0.05, i
    assert clip.longest_blur > 2.0


def test_the_nearest_surface_hides_the_one_behind():
    # A near square moving right over a static far wall: where it covers the wall at s = 1,
    # the render shows the square.
    H, W = 40, 60
    from stereodeblur.geometry.camera import StereoCamera

    K = np.array([[50.0, 0, (W - 1) / 2], [0, 50.0, (H - 1) / 2], [0, 0, 1]])
    camera = StereoCamera(K, 0.1)
    image = np.full((H, W), 0.2, np.float32)
    disparity = np.full((H, W), 0.5)
    labels = np.zeros((H, W), np.int64)
    image[15:25, 10:20], disparity[15:25, 10:20], labels[15:25, 10:20] = 0.9, 5.0, 1
    # 10 px to the right per frame at depth fx * baseline / 5 = 1.
    twists = np.array([[0.0] * 6, [10.0 / 50.0, 0, 0, 0, 0, 0]])
    photo = PhotoScene(
        {"left": image, "right": image}, {"left": disparity, "right": disparity},
        {"left": labels, "right": labels}, twists, camera,
    )  # fmt: skip
    moved, depth = render_instant(photo, "left", 1.0)
    assert np.allclose(moved[16:24, 21:29, 0], 0.9, atol=1e-3)
    assert np.allclose(depth[16:24, 21:29], 1.0)
    assert np.allclose(moved[16:24, 11:19, 0], 0.2, atol=0.05)  # the wall, filled in
