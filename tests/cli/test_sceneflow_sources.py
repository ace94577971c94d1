"""``stereodeblur sceneflow`` reads every source ``deblur`` reads: the same clip as a scene
folder, KITTI 2015 / 2012 / raw folders and a lossless video pair gives the same files."""

import numpy as np
import pytest

from stereodeblur.io.formats import read_png
from stereodeblur.io.scene import CameraInfo, SceneWriter, open_scene
from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene
from tests.clip.clip_helpers import run_cli
from tests.io.stereo_layouts import (
    to_u8,
    write_kitti_2012,
    write_kitti_2015,
    write_kitti_raw,
    write_video_pair,
)

SIZE = (64, 48)
NUM_FRAMES = 3
# What every run writes for frame I (the layout of a scene's gt/).
WRITTEN = ("disparity/left/{:06d}.pfm", "flow/left/{:06d}.flo", "occlusion/left/{:06d}.png")


def _scene8(root, frames, camera, timing):
    """A scene folder holding ``frames`` (8-bit values, grey or RGB)."""
    writer = SceneWriter(root, CameraInfo(camera, timing, "srgb"))
    for view, images in frames.items():
        for i, image in enumerate(images):
            writer.write_frame(view, i, to_u8(image) / 255.0, bit_depth=8, linear=False)
    return root


@pytest.fixture(scope="module")
def layouts(tmp_path_factory):
    """One rendered clip in every layout; each entry: the source arguments."""
    root = tmp_path_factory.mktemp("sources")
    rendered = write_rendered_scene(
        make_planar_scene("yaw", size=SIZE, num_frames=NUM_FRAMES, num_samples=16),
        root / "rendered",
    )
    scene = open_scene(rendered)
    camera, timing = scene.info.camera, scene.info.exposure
    frames = {v: [scene.read_frame(v, i) for i in range(NUM_FRAMES)] for v in ("left", "right")}
    grey = {v: [f.mean(axis=-1) for f in images] for v, images in frames.items()}
    given = ["--exposure", timing.exposure, "--frame-rate", timing.frame_rate]
    rate = {"frame_rate": timing.frame_rate}
    left, right, calib = write_video_pair(
        root / "video", frames["left"], frames["right"], camera.K, camera.baseline, **rate
    )
    kitti = (frames["left"], frames["right"], camera.K, camera.baseline)
    return {
        "scene": [_scene8(root / "scene8", frames, camera, timing)],
        "scene-grey": [_scene8(root / "scene8-grey", grey, camera, timing)],
        "kitti-2015": [write_kitti_2015(root / "kitti2015", *kitti), *given],
        "kitti-2012": [
            write_kitti_2012(
                root / "kitti2012",
                [to_u8(f) / 255.0 for f in grey["left"]],
                [to_u8(f) / 255.0 for f in grey["right"]],
                camera.K,
                camera.baseline,
            ),
            *given,
        ],
        "kitti-raw": [write_kitti_raw(root / "2011_09_26", *kitti, **rate), *given],
        "video": [left, right, "--calib", calib, *given],
    }


def _sceneflow(tmp_path, source, *options):
    out = tmp_path / "out"
    result = run_cli("sceneflow", *source, "-o", out, "-q", *options)
    assert result.code == 0, result.stderr
    return out, result


def _same_files(a, b, frame, *, name=None):
    """``a``'s files of ``frame`` (named ``name``, else NNNNNN) equal ``b``'s (NNNNNN)."""
    name = name or f"{frame:06d}"
    for pattern in WRITTEN:
        path = pattern.format(frame)
        other = path.replace(f"{frame:06d}", name)
        assert (a / other).read_bytes() == (b / path).read_bytes(), other
    saved = [
        np.load(a / "sceneflow" / f"{name}.npz"),
        np.load(b / "sceneflow" / f"{frame:06d}.npz"),
    ]
    for key in ("labels", "normals", "twists", "occlusion"):
        np.testing.assert_array_equal(saved[0][key], saved[1][key], err_msg=key)


@pytest.fixture(scope="module")
def from_scene(layouts, tmp_path_factory):
    """The scene folders' scene flow of frame 1: what every other layout must give."""
    return {
        kind: _sceneflow(tmp_path_factory.mktemp(kind), layouts[kind], "--frames", "1")[0]
        for kind in ("scene", "scene-grey")
    }


# Frame 1 of the clip in each source's numbers, and its name in the results.
NUMBER = {"kitti-2015": 11, "kitti-2012": 11, "kitti-raw": 1, "video": 1}
NAME = {"kitti-2015": "000000_11", "kitti-2012": "000000_11", "kitti-raw": "0000000001",
        "video": "000001"}  # fmt: skip


@pytest.mark.parametrize("kind", ["kitti-2015", "kitti-2012", "kitti-raw", "video"])
def test_every_source_gives_the_scene_folders_scene_flow(kind, layouts, from_scene, tmp_path):
    """The same scene flow, in files named as the source names the frame."""
    number = NUMBER[kind]
    out, result = _sceneflow(tmp_path, layouts[kind], "--frames", str(number))
    assert f"frame {number} -> {number + 1}" in result.stdout
    reference = from_scene["scene-grey" if kind == "kitti-2012" else "scene"]
    _same_files(out, reference, 1, name=NAME[kind])


def test_kitti_needs_no_exposure_for_the_scene_flow(layouts, tmp_path):
    out, _ = _sceneflow(tmp_path, layouts["kitti-2015"][:1], "--frames", "10")
    assert (out / "sceneflow" / "000000_10.npz").is_file()


def test_a_frame_range_writes_one_file_of_each_kind_per_frame(layouts, from_scene, tmp_path):
    """'1:3' is frames 1 and 2; the last frame's scene flow points back to frame 1."""
    debug = tmp_path / "debug"
    out, result = _sceneflow(tmp_path, layouts["scene"], "--frames", "1:3", "--debug-dir", debug)
    assert "frame 1 -> 2" in result.stdout and "frame 2 -> 1" in result.stdout
    for frame in (1, 2):
        for pattern in (*WRITTEN, "sceneflow/{:06d}.npz"):
            assert (out / pattern.format(frame)).is_file()
        for name in ("segments", "disparity", "initial_disparity", "flow", "occlusion"):
            picture = read_png(debug / f"{frame:06d}" / f"{name}.png")
            assert picture.shape[0] > SIZE[1] and picture.shape[1:] == (SIZE[0], 3)
    assert not (out / "sceneflow" / "000000.npz").exists()
    _same_files(out, from_scene["scene"], 1)
