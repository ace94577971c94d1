import json

import numpy as np
import pytest

from stereodeblur.geometry import Exposure, move_plane, se3_exp
from stereodeblur.io.scene import open_scene
from stereodeblur.synth.planar import (
    PLANAR_MOTIONS,
    curvature_px,
    make_planar_scene,
    planar_camera,
    planar_setup,
    write_planar_set,
    write_rendered_scene,
)
from stereodeblur.synth.render import PlanarObject, SceneSetup, intersect_plane

PAPER_MOTIONS = ("upward", "forward", "forward_yaw", "yaw", "forward_roll", "lateral_pitch")
STRONG_MOTIONS = ("strong_yaw", "fast_approach", "long_exposure_roll")


def test_motion_set_and_textures():
    assert set(PAPER_MOTIONS + STRONG_MOTIONS) <= set(PLANAR_MOTIONS)
    setups = [planar_setup(name, size=(64, 48)) for name in PLANAR_MOTIONS]
    assert len({s.objects[0].texture_name for s in setups}) >= 6
    for name, setup in zip(PLANAR_MOTIONS, setups, strict=True):
        (plane,) = setup.objects
        np.testing.assert_array_equal(plane.twist, PLANAR_MOTIONS[name].twist)
        assert setup.camera.baseline == 0.12 and setup.exposure.frame_rate == 20.0
    camera = planar_camera((640, 480))
    np.testing.assert_allclose(camera.K[:2, 2], [319.5, 239.5])


def _pixels_per_texel(setup, step=20):
    """Smallest and largest local texture scale over a sparse pixel grid, both views,
    the first and last instant of the clip and the middle."""
    (plane,) = setup.objects
    width, height = setup.size
    y, x = np.mgrid[0:height:step, 0:width:step].astype(np.float64)
    tau = setup.exposure.duty_cycle
    low, high = np.inf, 0.0
    for s in (-tau / 2, (setup.num_frames - 1) / 2, setup.num_frames - 1 + tau / 2):
        for view in ("left", "right"):
            uv = [
                plane.texture_coordinates(
                    intersect_plane(
                        plane.normal, plane.twist, setup.camera, view, x + dx, y + dy, s
                    )[1]
                )
                for dx, dy in ((0, 0), (0.5, 0), (0, 0.5))
            ]
            # Jacobian of texture coordinates per pixel; its singular values in closed form.
            a, c = 2 * (uv[1][0] - uv[0][0]), 2 * (uv[1][1] - uv[0][1])
            b, d = 2 * (uv[2][0] - uv[0][0]), 2 * (uv[2][1] - uv[0][1])
            e = (a * a + b * b + c * c + d * d) / 2
            root = np.sqrt(np.maximum(e * e - (a * d - b * c) ** 2, 0))
            low = min(low, (1 / np.sqrt(e + root)).min())
            high = max(high, (1 / np.sqrt(e - root)).max())
    return low, high


@pytest.mark.parametrize("size", [(640, 480), (160, 120)])
def test_texture_is_not_minified_and_not_much_magnified(size):
    for name in PLANAR_MOTIONS:
        low, high = _pixels_per_texel(planar_setup(name, size=size))
        assert low >= 0.99, (name, low)
        assert high <= (2.0 if name in PAPER_MOTIONS else 2.8), (name, high)


def test_moderate_and_strong_motions():
    # At 320 x 240 all pixel measures are half those at 640 x 480.
    for name in PLANAR_MOTIONS:
        c = curvature_px(planar_setup(name, size=(320, 240)), 1, num_samples=8)
        if name in PAPER_MOTIONS:
            assert 1.5 <= c.blur_max_px <= 8.5, (name, c)
            assert c.max_px < 0.15, (name, c)
        else:
            assert c.max_px > 1.2 and c.blur_max_px > 20, (name, c)


def test_strong_yaw_bends_more_than_two_pixels_at_640x480():
    c = curvature_px(planar_setup("strong_yaw"), 1, num_samples=16)
    assert c.max_px > 2.0 and c.mean_px > 0.5


def _fronto_parallel(size, twist, distance=2.0):
    camera = planar_camera(size)
    texture = np.zeros((4, 4, 3), np.float32)
    plane = PlanarObject(
        [0, 0, 1 / distance], twist, texture, [0, 0, distance], np.eye(3)[:2], 0.01
    )
    return SceneSetup("test", camera, Exposure(20.0, 0.05), size, 3, (plane,))


def test_curvature_of_fronto_parallel_translation_is_zero():
    setup = _fronto_parallel((96, 72), [0.2, -0.1, 0.0, 0.0, 0.0, 0.0])
    c = curvature_px(setup, 1, num_samples=9)
    assert c.max_px < 1e-9
    # 0.2 m at 2 m with fx = 76.8: 7.68 px along x, 3.84 along y per frame, tau = 1.
    np.testing.assert_allclose(c.blur_max_px, 76.8 * np.hypot(0.1, 0.05), rtol=1e-9)


def test_curvature_of_roll_matches_circle():
    omega, size, border, num_samples = 0.3, (96, 72), 10, 9
    setup = _fronto_parallel(size, [0, 0, 0, 0, 0, omega])
    c = curvature_px(setup, 1, num_samples=num_samples, border=border)
    # A pixel at z = r e^{i phi} from the principal point moves on a circle: the
    # model follows the chords to the positions one frame later and earlier.
    y, x = np.mgrid[border : 72 - border, border : 96 - border]
    r = np.abs((x - 47.5) + 1j * (y - 35.5))
    s = Exposure(20.0, 0.05).sample_fractions(num_samples)
    chord = np.where(s > 0, np.exp(1j * omega) - 1, np.exp(-1j * omega) - 1)
    deviation = np.abs(np.exp(1j * omega * s) - 1 - np.abs(s) * chord).max()
    np.testing.assert_allclose(c.max_px, r.max() * deviation, rtol=1e-9)
    np.testing.assert_allclose(c.mean_px, r.mean() * deviation, rtol=1e-9)
    assert c.max_px > 0.3


def test_rendered_planar_scene_and_determinism():
    kw = dict(size=(64, 48), num_samples=8)
    scene = make_planar_scene("forward_roll", **kw)
    again = make_planar_scene("forward_roll", **kw)
    other = make_planar_scene("forward_roll", seed=1, **kw)
    assert scene.num_frames == 3 and len(scene.flow) == 2
    for view in ("left", "right"):
        for i in range(3):
            for field in ("frames", "sharp", "disparity", "mixed"):
                got, same = getattr(scene, field)[view][i], getattr(again, field)[view][i]
                np.testing.assert_array_equal(got, same)
            assert scene.frames[view][i].shape == (48, 64, 3)
            assert scene.frames[view][i].dtype == np.float32
            assert not scene.mixed[view][i].any()  # one plane fills the view
            disparity = scene.disparity[view][i]
            assert np.all(np.isfinite(disparity)) and disparity.min() > 0
    np.testing.assert_array_equal(scene.flow[1], again.flow[1])
    assert not np.allclose(scene.objects[0].normal, other.objects[0].normal)
    # The true objects: the plane at frame 0's centre and its twist; at the middle of
    # the clip (frame 1) it is 3 m away on the optical axis.
    (plane,) = scene.objects
    M = se3_exp(np.asarray(PLANAR_MOTIONS["forward_roll"].twist))
    middle = move_plane(plane.normal, M[:3, :3], M[:3, 3])
    np.testing.assert_allclose(1 / middle[2], PLANAR_MOTIONS["forward_roll"].distance)
    # Blurred, but with the sharp image's brightness.
    assert np.abs(scene.frames["left"][1] - scene.sharp["left"][1]).max() > 0.02
    np.testing.assert_allclose(
        scene.frames["left"][1].mean(), scene.sharp["left"][1].mean(), atol=0.01
    )


def test_write_rendered_scene(tmp_path):
    scene = make_planar_scene("yaw", size=(40, 30), num_samples=4)
    root = write_rendered_scene(scene, tmp_path / "yaw")
    disk = open_scene(root)
    assert disk.num_frames == 3 and disk.shape == (30, 40)
    np.testing.assert_allclose(disk.info.camera.K, scene.camera.K)
    assert disk.info.exposure == scene.exposure and disk.info.color == "linear"
    for view in ("left", "right"):
        for i in range(3):
            np.testing.assert_allclose(disk.read_frame(view, i), scene.frames[view][i], atol=1e-4)
            np.testing.assert_allclose(disk.read_gt_sharp(view, i), scene.sharp[view][i], atol=1e-4)
            np.testing.assert_array_equal(disk.read_gt_disparity(view, i), scene.disparity[view][i])
            np.testing.assert_array_equal(disk.read_gt_mixed(view, i), scene.mixed[view][i])
    for i in range(2):
        np.testing.assert_array_equal(disk.read_gt_flow("left", i), scene.flow[i])
    objects = json.loads((root / "gt" / "objects.json").read_text())
    assert objects["frame_rate"] == 20.0 and objects["reference"] == "frame 0 centre"
    (entry,) = objects["objects"]
    assert entry["id"] == 0 and entry["texture"] == scene.objects[0].texture_name
    np.testing.assert_allclose(entry["normal"], scene.objects[0].normal, rtol=1e-15)
    np.testing.assert_allclose(entry["twist"], PLANAR_MOTIONS["yaw"].twist)


def test_write_planar_set(tmp_path):
    seen = []
    paths = write_planar_set(tmp_path, size=(24, 18), names=["upward"], progress=seen.append)
    assert seen == ["upward"] and paths == [tmp_path / "upward"]
    assert open_scene(tmp_path / "upward").num_frames == 3


def test_bad_requests():
    with pytest.raises(ValueError, match="unknown planar scene"):
        planar_setup("sideways")
    with pytest.raises(ValueError, match="does not fill"):
        planar_setup("fast_approach", size=(32, 24), num_frames=20)
    with pytest.raises(ValueError, match="border"):
        curvature_px(planar_setup("upward", size=(32, 24)), 0, border=12)
