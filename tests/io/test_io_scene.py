"""Tests of stereodeblur.io.scene: camera.json, opening and writing scenes."""

import json

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.geometry import Exposure, StereoCamera
from stereodeblur.io import (
    CameraInfo,
    SceneWriter,
    check_readable,
    linear_to_srgb,
    open_scene,
    read_camera,
    read_png,
    write_camera,
    write_png,
)

K = [[500.0, 0.0, 31.5], [0.0, 510.0, 23.5], [0.0, 0.0, 1.0]]
SHAPE = (48, 64)


def _info(color="linear", exposure=0.04):
    return CameraInfo(StereoCamera(np.array(K), 0.12), Exposure(20.0, exposure), color)


def _camera_dict(**changes):
    data = {
        "format": "stereo-video/1",
        "K": K,
        "baseline": 0.12,
        "frame_rate": 20.0,
        "exposure": 0.04,
        "color": "linear",
    }
    data.update(changes)
    return data


def _make_scene(root, *, num_frames=3, color="linear", channels=3, seed=0):
    """Write a scene of random frames; returns the linear frames {(view, i): image}."""
    rng = np.random.default_rng(seed)
    writer = SceneWriter(root, _info(color))
    frames = {}
    for view in ("left", "right"):
        for index in range(num_frames):
            image = rng.random(SHAPE if channels == 1 else (*SHAPE, 3))
            writer.write_frame(view, index, image)
            frames[view, index] = image
    return frames


def _raises(exc_type, match, func, *args):
    """Run ``func`` expecting ``exc_type`` with a one-line message matching ``match``."""
    with pytest.raises(exc_type, match=match) as info:
        func(*args)
    assert "\n" not in str(info.value)
    return str(info.value)


# --------------------------------------------------------------------------- camera.json


def test_camera_round_trip(tmp_path):
    info = _info("srgb", exposure=0.03)
    path = write_camera(tmp_path / "deep" / "camera.json", info)
    data = json.loads(path.read_text())
    assert data == _camera_dict(exposure=0.03, color="srgb")
    back = read_camera(path)
    np.testing.assert_array_equal(back.camera.K, np.array(K))
    assert back.camera.baseline == 0.12 and back.color == "srgb"
    assert back.exposure.frame_rate == 20.0 and back.exposure.exposure == 0.03
    assert read_camera(tmp_path / "deep").color == "srgb"  # a folder holding camera.json


def test_camera_color_defaults_to_linear(tmp_path):
    data = _camera_dict()
    del data["color"]
    (tmp_path / "camera.json").write_text(json.dumps(data))
    assert read_camera(tmp_path / "camera.json").color == "linear"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"K": [[500, 0, 31.5], [0, 510, 23.5]]}, "'K' must be a 3x3"),
        ({"K": [[500, 0, "a"], [0, 510, 23.5], [0, 0, 1]]}, r"'K\[0\]\[2\]' must be a finite"),
        ({"K": [[500, 0, 31.5], [0, 510, 23.5], [0, 1, 1]]}, "K must be"),
        ({"K": [[-5, 0, 31.5], [0, 510, 23.5], [0, 0, 1]]}, "fx, fy > 0"),
        ({"format": "stereo-video/2"}, "'format' must be 'stereo-video/1', got \"stereo-video/2\""),
        ({"baseline": 0}, "'baseline' must be > 0, got 0"),
        ({"baseline": True}, "'baseline' must be a finite number, got true"),
        ({"frame_rate": -20}, "'frame_rate' must be > 0, got -20"),
        ({"exposure": 0.06}, "exposure 0.06 s is longer than the frame interval"),
        ({"exposure": "0.04"}, "'exposure' must be a finite number"),
        ({"color": "rgb"}, "'color' must be 'linear' or 'srgb', got \"rgb\""),
        ({"colour": "srgb"}, "unknown key 'colour'"),
    ],
)
def test_camera_invalid_values(tmp_path, change, message):
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(_camera_dict(**change)))
    text = _raises(InputError, message, read_camera, path)
    assert str(path) in text


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{'format': 1}", "invalid JSON"),
        ("[1, 2]", "expected a JSON object"),
        ('{"format": "stereo-video/1"}', "missing key 'K'"),
        (json.dumps(_camera_dict()).replace("0.12", "NaN"), "'baseline' must be a finite"),
    ],
)
def test_camera_malformed(tmp_path, text, message):
    path = tmp_path / "camera.json"
    path.write_text(text)
    assert str(path) in _raises(InputError, message, read_camera, path)


# --------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("channels", [1, 3])
def test_scene_round_trip(tmp_path, channels):
    frames = _make_scene(tmp_path / "s", num_frames=3, channels=channels)
    scene = open_scene(tmp_path / "s")
    assert scene.root == tmp_path / "s" and scene.num_frames == 3
    assert scene.shape == SHAPE and scene.channels == channels and scene.bit_depth == 16
    assert scene.info.color == "linear" and scene.info.exposure.duty_cycle == pytest.approx(0.8)
    assert scene.frame_path("right", 2) == tmp_path / "s" / "right" / "000002.png"
    for (view, index), image in frames.items():
        back = scene.read_frame(view, index)
        assert back.dtype == np.float32 and back.shape == image.shape
        assert np.max(np.abs(back - image)) <= 0.5 / 65535 + 1e-7
    assert not any(p.name.startswith(".") for p in (tmp_path / "s" / "left").iterdir())


def test_srgb_scene_encodes_and_decodes(tmp_path):
    frames = _make_scene(tmp_path / "s", num_frames=2, color="srgb")
    scene = open_scene(tmp_path / "s")
    image = frames["left", 1]
    stored = read_png(scene.frame_path("left", 1))
    assert np.max(np.abs(stored - linear_to_srgb(image))) <= 0.5 / 65535 + 1e-7
    np.testing.assert_array_equal(scene.read_frame("left", 1, linear=False), stored)
    # The slope of sRGB decoding is at most 2.4 / 1.055 < 2.3: bound on the quantisation error.
    assert np.max(np.abs(scene.read_frame("left", 1) - image)) <= 2.3 * 0.5 / 65535 + 1e-6


def test_ground_truth_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    _make_scene(tmp_path / "s", num_frames=3, color="srgb")
    writer = SceneWriter(tmp_path / "s", _info("srgb"))  # resuming the same scene
    sharp = rng.random((*SHAPE, 3))
    disparity = rng.uniform(1, 30, SHAPE).astype(np.float32)
    disparity[0, :3] = [np.nan, -1.0, 0.0]
    flow = rng.standard_normal((*SHAPE, 2)).astype(np.float32)
    flow[1, 1, 0] = np.nan
    mixed = rng.random(SHAPE) > 0.7
    writer.write_gt_sharp("left", 1, sharp)
    writer.write_gt_disparity("left", 1, disparity)
    writer.write_gt_flow("left", 1, flow)
    writer.write_gt_mixed("right", 1, mixed)
    assert writer.path_for("disparity", "left", 1) == tmp_path / "s/gt/disparity/left/000001.pfm"
    assert writer.path_for("flow", "left", 1) == tmp_path / "s/gt/flow/left/000001.flo"

    scene = open_scene(tmp_path / "s")
    assert scene.gt_path("mixed", "right", 1) == tmp_path / "s/gt/mixed/right/000001.png"
    assert scene.has_gt("sharp", "left", 1) and not scene.has_gt("sharp", "right", 1)
    assert scene.has_gt("mixed", "right", 1) and not scene.has_gt("flow", "left", 0)
    assert np.max(np.abs(scene.read_gt_sharp("left", 1) - sharp)) <= 2.3 * 0.5 / 65535 + 1e-6
    back = scene.read_gt_disparity("left", 1)
    known = disparity > 0
    assert back.dtype == np.float32
    np.testing.assert_array_equal(np.isnan(back), ~known)
    np.testing.assert_array_equal(back[known], disparity[known])
    back = scene.read_gt_flow("left", 1)
    assert np.all(np.isnan(back[1, 1])) and np.isnan(back).sum() == 2
    finite = ~np.isnan(flow).any(axis=2)
    np.testing.assert_array_equal(back[finite], flow[finite])
    np.testing.assert_array_equal(scene.read_gt_mixed("right", 1), mixed)
    _raises(FileNotFoundError, "gt/flow/left/000000.flo", scene.read_gt_flow, "left", 0)
    _raises(InputError, "ground-truth kind", scene.has_gt, "depth", "left", 0)
    _raises(InputError, "out of range 0..2", scene.read_frame, "left", 3)
    _raises(InputError, "view must be", scene.read_frame, "center", 0)


def test_ground_truth_of_wrong_size(tmp_path):
    _make_scene(tmp_path / "s", num_frames=2)
    scene = open_scene(tmp_path / "s")
    path = write_png(scene.gt_path("sharp", "left", 0), np.zeros((SHAPE[0], SHAPE[1] + 1, 3)))
    text = _raises(InputError, "expected an image of shape", scene.read_gt_sharp, "left", 0)
    assert str(path) in text and "(48, 65, 3)" in text


# --------------------------------------------------------------------------- writer rules


def test_writer_refuses_to_touch_inputs(tmp_path):
    _make_scene(tmp_path / "in", num_frames=2)
    for target in (tmp_path / "in", tmp_path / "in" / "out", tmp_path):
        with pytest.raises(InputError, match="refusing to write") as info:
            SceneWriter(target, _info(), overwrite=True, protect=[tmp_path / "in"])
        assert str(tmp_path / "in") in str(info.value)
    SceneWriter(tmp_path / "out", _info(), protect=[tmp_path / "in"])  # a sibling is fine


def test_writer_root_rules(tmp_path):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("x")
    with pytest.raises(InputError, match="busy is not empty and not a scene"):
        SceneWriter(tmp_path / "busy", _info())
    SceneWriter(tmp_path / "busy", _info(), overwrite=True)
    assert read_camera(tmp_path / "busy" / "camera.json").color == "linear"
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        SceneWriter(tmp_path / "file", _info())
    (tmp_path / "empty").mkdir()
    SceneWriter(tmp_path / "empty", _info())


def test_writer_resumes_and_checks_camera(tmp_path):
    root = tmp_path / "s"
    image = np.random.default_rng(8).random((*SHAPE, 3))
    SceneWriter(root, _info()).write_frame("left", 0, image)
    mtime = (root / "camera.json").stat().st_mtime_ns
    writer = SceneWriter(root, _info())  # a later run of the same job
    assert (root / "camera.json").stat().st_mtime_ns == mtime
    writer.write_frame("right", 0, image)
    writer.write_frame("left", 1, image)
    writer.write_frame("right", 1, image)
    assert open_scene(root).num_frames == 2
    with pytest.raises(InputError, match="camera.json holds a different camera"):
        SceneWriter(root, _info("srgb"))
    SceneWriter(root, _info("srgb"), overwrite=True)
    assert read_camera(root).color == "srgb"
    with pytest.raises(InputError, match=r"000002.png with shape \(48, 64, 1\)"):
        SceneWriter(root, _info("srgb")).write_frame("left", 2, image[..., 0])
    with pytest.raises(InputError, match=r"shape \(48, 65\)"):
        writer.write_gt_disparity("left", 0, np.ones((48, 65)))


# --------------------------------------------------------------------------- bad scenes


def test_missing_camera_json(tmp_path):
    _make_scene(tmp_path / "s")
    (tmp_path / "s" / "camera.json").unlink()
    _raises(FileNotFoundError, "camera file not found: .*s/camera.json", open_scene, tmp_path / "s")
    _raises(FileNotFoundError, "scene folder not found: .*nope", open_scene, tmp_path / "nope")


def test_missing_view_folder(tmp_path):
    _make_scene(tmp_path / "s")
    for path in (tmp_path / "s" / "right").iterdir():
        path.unlink()
    (tmp_path / "s" / "right").rmdir()
    _raises(FileNotFoundError, "missing frame folder .*s/right", open_scene, tmp_path / "s")


def test_empty_view_folder(tmp_path):
    _make_scene(tmp_path / "s")
    for path in (tmp_path / "s" / "left").iterdir():
        path.unlink()
    _raises(InputError, "no frames in .*s/left", open_scene, tmp_path / "s")


def test_mismatched_frame_numbers(tmp_path):
    _make_scene(tmp_path / "s", num_frames=3)
    (tmp_path / "s" / "right" / "000002.png").unlink()
    text = _raises(InputError, "missing frame .*right/000002.png", open_scene, tmp_path / "s")
    assert "left/ has 3 frames, right/ has 2" in text


def test_gap_in_numbering(tmp_path):
    _make_scene(tmp_path / "s", num_frames=4)
    for view in ("left", "right"):
        (tmp_path / "s" / view / "000002.png").unlink()
    text = _raises(InputError, "missing frame .*left/000002.png", open_scene, tmp_path / "s")
    assert "contiguously from 000000 (next found is 000003.png)" in text


def test_single_frame(tmp_path):
    _make_scene(tmp_path / "s", num_frames=1)
    _raises(
        InputError, "a scene needs at least two frames, found 1 in .*s$", open_scene, tmp_path / "s"
    )


def test_badly_named_frame(tmp_path):
    _make_scene(tmp_path / "s", num_frames=2)
    write_png(tmp_path / "s" / "left" / "frame_2.png", np.zeros(SHAPE))
    (tmp_path / "s" / "left" / "readme.txt").write_text("ignored")
    (tmp_path / "s" / "left" / ".000002.png.tmp").write_text("ignored")
    _raises(InputError, "unexpected frame file name .*frame_2.png", open_scene, tmp_path / "s")
    (tmp_path / "s" / "left" / "frame_2.png").unlink()
    assert open_scene(tmp_path / "s").num_frames == 2


def test_frames_of_different_sizes(tmp_path):
    _make_scene(tmp_path / "s", num_frames=3)
    # The first frames of both views are checked on opening ...
    write_png(tmp_path / "s" / "right" / "000000.png", np.zeros((SHAPE[0], SHAPE[1] - 1, 3)))
    text = _raises(InputError, "right/000000.png is 63x48 16-bit RGB", open_scene, tmp_path / "s")
    assert "expected 64x48 16-bit RGB" in text
    write_png(tmp_path / "s" / "right" / "000000.png", np.zeros((*SHAPE, 3)), bit_depth=8)
    _raises(InputError, "right/000000.png is 64x48 8-bit RGB", open_scene, tmp_path / "s")
    write_png(tmp_path / "s" / "right" / "000000.png", np.zeros((*SHAPE, 3)))
    # ... the others by check_readable (before a run) and when they are read.
    path = tmp_path / "s" / "right" / "000001.png"
    write_png(path, np.zeros(SHAPE))
    scene = open_scene(tmp_path / "s")
    _raises(InputError, "right/000001.png is 64x48 grey, expected 64x48 RGB", check_readable, scene)
    check_readable(scene, ["left"])
    _raises(InputError, "right/000001.png has shape", scene.read_frame, "right", 1)


def test_unreadable_png(tmp_path):
    _make_scene(tmp_path / "s", num_frames=2)
    path = tmp_path / "s" / "left" / "000000.png"
    good = path.read_bytes()
    path.write_bytes(np.random.default_rng(9).bytes(500))
    _raises(InputError, "not a PNG file: .*left/000000.png", open_scene, tmp_path / "s")
    # A valid header with truncated data: found by check_readable, or on reading.
    path.write_bytes(good[: len(good) // 2])
    scene = open_scene(tmp_path / "s")
    _raises(InputError, "truncated PNG file .*left/000000.png", check_readable, scene)
    _raises(InputError, "truncated PNG file .*left/000000.png", scene.read_frame, "left", 0)
