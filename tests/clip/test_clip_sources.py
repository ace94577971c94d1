"""The same clip as a scene folder, KITTI folders and two lossless videos deblurs the same."""

import pytest

from stereodeblur.io.scene import CameraInfo, SceneWriter, open_scene
from tests.clip.clip_helpers import NUM_FRAMES, frame_files, run_cli
from tests.io.stereo_layouts import (
    to_u8,
    write_kitti_2015,
    write_kitti_raw,
    write_video_pair,
)

ESTIMATED = ["--motion-source", "sceneflow", "--irls", "2", "--cg", "5", "--samples", "16"]
FRAMES = ["--frames", "5:7", "--workers", "1", "-q"]


@pytest.fixture(scope="module")
def layouts(clip_scene, tmp_path_factory):
    """The clip quantised to 8 bits, in four layouts that hold the same values."""
    scene = open_scene(clip_scene)
    root = tmp_path_factory.mktemp("layouts")
    frames = {v: [scene.read_frame(v, i) for i in range(NUM_FRAMES)] for v in ("left", "right")}
    camera, timing = scene.info.camera, scene.info.exposure
    writer = SceneWriter(root / "scene8", CameraInfo(camera, timing, "srgb"))
    for view, images in frames.items():
        for i, image in enumerate(images):
            writer.write_frame(view, i, to_u8(image) / 255.0, bit_depth=8, linear=False)
    timing_options = ["--exposure", timing.exposure, "--frame-rate", timing.frame_rate]
    kitti = write_kitti_2015(
        root / "kitti", frames["left"], frames["right"], camera.K, camera.baseline
    )
    raw = write_kitti_raw(
        root / "2011_09_26", frames["left"], frames["right"], camera.K, camera.baseline
    )
    left, right, calib = write_video_pair(
        root / "video", frames["left"], frames["right"], camera.K, camera.baseline
    )
    return {
        "scene": [root / "scene8"],
        "kitti-2015": [kitti, *timing_options],
        "kitti-raw": [raw, "--exposure", timing.exposure],
        "video": [left, right, "--calib", calib, "--exposure", timing.exposure],
    }


@pytest.fixture(scope="module")
def scene_result(layouts, tmp_path_factory):
    out = tmp_path_factory.mktemp("from-scene") / "out"
    result = run_cli("deblur", *layouts["scene"], "-o", out, *FRAMES, *ESTIMATED)
    assert result.code == 0, result.stderr
    assert len(frame_files(out)) == 4
    return out


@pytest.mark.parametrize("kind", ["kitti-2015", "kitti-raw", "video"])
def test_other_layouts_deblur_to_the_same_frames(kind, layouts, scene_result, tmp_path):
    out = tmp_path / "out"
    result = run_cli("deblur", *layouts[kind], "-o", out, *FRAMES, *ESTIMATED)
    assert result.code == 0, result.stderr
    assert frame_files(out) == frame_files(scene_result)
    assert (out / "camera.json").read_text() == (scene_result / "camera.json").read_text()
    for name in frame_files(out):
        assert (out / name).read_bytes() == (scene_result / name).read_bytes(), name


def test_kitti_without_exposure_is_a_one_line_error(layouts, tmp_path):
    out = tmp_path / "out"
    result = run_cli("deblur", layouts["kitti-2015"][0], "-o", out, *FRAMES, *ESTIMATED)
    assert result.code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--exposure" in lines[0] and "kitti" in lines[0]
    assert not out.exists()
