"""The same clip as a scene folder, KITTI folders and two lossless videos deblurs the same;
results keep the source's frame names and --frames counts in the source's numbers."""

import json

import pytest

from stereodeblur.io.scene import CameraInfo, SceneWriter, open_scene
from tests.clip.clip_helpers import NUM_FRAMES, frame_files, run_cli
from tests.io.stereo_layouts import (
    to_u8,
    write_kitti_2015,
    write_kitti_raw,
    write_video_pair,
)

# A KITTI folder has no ground-truth motion: the quickest estimate instead.
QUICK = ["--motion-source", "sceneflow", "--irls", "1", "--cg", "2", "--samples", "8"]
ESTIMATED = ["--motion-source", "sceneflow", "--irls", "2", "--cg", "5", "--samples", "16"]
FRAMES = ["--workers", "1", "-q"]
# Frames 5 and 6 of the clip in each source's numbers, and their names in the results.
SELECTED = {"scene": "5:7", "kitti-2015": "15:17", "kitti-raw": "5:7", "video": "5:7"}
NAMES = {
    "scene": ["000005", "000006"],
    "kitti-2015": ["000000_15", "000000_16"],
    "kitti-raw": ["0000000005", "0000000006"],
    "video": ["000005", "000006"],
}


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
    frames = ["--frames", SELECTED["scene"]]
    result = run_cli("deblur", *layouts["scene"], "-o", out, *frames, *FRAMES, *ESTIMATED)
    assert result.code == 0, result.stderr
    assert len(frame_files(out)) == 4
    return out


@pytest.mark.parametrize("kind", ["kitti-2015", "kitti-raw", "video"])
def test_other_layouts_deblur_to_the_same_frames(kind, layouts, scene_result, tmp_path):
    """Same values (sRGB by default, as the scene folder states), the source's own names."""
    out = tmp_path / "out"
    frames = ["--frames", SELECTED[kind]]
    result = run_cli("deblur", *layouts[kind], "-o", out, *frames, *FRAMES, *ESTIMATED)
    assert result.code == 0, result.stderr
    names = {f"{v}/{n}.png": f"{v}/{s}.png" for v in ("left", "right")
             for n, s in zip(NAMES[kind], NAMES["scene"], strict=True)}  # fmt: skip
    assert frame_files(out) == sorted(names)
    assert frame_files(scene_result) == sorted(names.values())
    assert (out / "camera.json").read_text() == (scene_result / "camera.json").read_text()
    assert '"color": "srgb"' in (out / "camera.json").read_text()
    for name, same in names.items():
        assert (out / name).read_bytes() == (scene_result / same).read_bytes(), name


def test_a_kitti_run_resumes_by_its_frame_names(layouts, tmp_path):
    """A second run over more frames skips those the first finished (named 000000_NN)."""
    out = tmp_path / "out"
    source = layouts["kitti-2015"]
    first = run_cli("deblur", *source, "-o", out, "--frames", "15", *FRAMES, *QUICK)
    assert first.code == 0, first.stderr
    assert frame_files(out) == ["left/000000_15.png", "right/000000_15.png"]
    written = (out / "left" / "000000_15.png").stat().st_mtime_ns
    second = run_cli("deblur", *source, "-o", out, "--frames", "15:17", *FRAMES, *QUICK)
    assert second.code == 0, second.stderr
    assert "2 already done" in second.stdout
    assert (out / "left" / "000000_15.png").stat().st_mtime_ns == written
    assert frame_files(out)[1] == "left/000000_16.png" and len(frame_files(out)) == 4


def test_frames_outside_the_sources_numbers_are_refused(layouts, tmp_path):
    """KITTI 2015's frames are numbered from 10 here: frame 5 is not one of them."""
    result = run_cli("deblur", *layouts["kitti-2015"], "-o", tmp_path / "out", "--frames", "5",
                     *FRAMES, *QUICK)  # fmt: skip
    assert result.code == 2
    assert "frame 5 is not in 10..21" in result.stderr


def test_kitti_without_exposure_estimates_it(layouts, clip_scene, tmp_path):
    """KITTI states no exposure: each frame's is estimated from its blurred frames, shown
    with its progress and kept in the run log, one per stereo frame (the estimator's accuracy
    is tested in tests/blur: at 64x48 this roll's comes out about 0.6 of the truth)."""
    out = tmp_path / "out"
    source = [layouts["kitti-2015"][0], *layouts["kitti-2015"][3:]]  # the frame rate alone
    frames = ["--frames", SELECTED["kitti-2015"], "--workers", "1"]
    result = run_cli("deblur", *source, "-o", out, *frames, *QUICK)
    assert result.code == 0, result.stderr
    truth = open_scene(clip_scene).info.exposure.exposure
    shown = [line for line in result.stderr.splitlines() if ": exposure 0" in line]
    assert len(shown) == 2, result.stderr
    records = [json.loads(line) for line in (out / "run-log.jsonl").read_text().splitlines()]
    estimates = [r["exposure"] for r in records if r["event"] == "frame"]
    assert len(estimates) == 4 and all(0.5 * truth <= e <= truth for e in estimates), estimates
    assert estimates[0] == estimates[1] and estimates[2] == estimates[3]  # one per stereo frame
