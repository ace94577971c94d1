"""Warnings about the input reach the terminal, not only the run log."""

import numpy as np

from stereodeblur.cli import main
from tests.io.stereo_layouts import write_video_pair

K = np.array([[40.0, 0.0, 31.5], [0.0, 40.0, 23.5], [0.0, 0.0, 1.0]])


def test_videos_of_different_lengths_warn_on_stderr(tmp_path, capsys):
    rng = np.random.default_rng(0)
    frames = [rng.random((48, 64, 3)) for _ in range(8)]
    left, right, calib = write_video_pair(tmp_path / "in", frames, frames[:4], K, 0.1)
    out = tmp_path / "out"
    argv = [left, right, "--calib", calib, "--exposure", "0.01", "-o", out, "--frames", "1"]
    fast = ["--views", "left", "--motion-source", "initial-flow", "--kernels", "displacement"]
    fast += ["--samples", "2", "--irls", "1", "--cg", "1", "--workers", "1", "-q"]
    assert main(["deblur", *map(str, argv), *fast]) == 0
    err = capsys.readouterr().err.splitlines()
    warnings = [line for line in err if line.startswith("stereodeblur: warning: ")]
    assert len(warnings) == 1 and "using the first 4" in warnings[0], err
    assert (out / "left" / "000001.png").is_file()


def test_frames_left_out_for_lack_of_ground_truth_are_reported(tmp_path, capsys):
    from tests.conftest import write_tiny_scene

    scene = write_tiny_scene(tmp_path / "scene", num_frames=4)
    for kind, suffix in (("disparity", "pfm"), ("flow", "flo")):
        (scene / "gt" / kind / "left" / f"000001.{suffix}").unlink()
    out = tmp_path / "out"
    argv = ["deblur", str(scene), "-o", str(out), "--motion-source", "gt", "--views", "left"]
    fast = ["--samples", "2", "--irls", "1", "--cg", "1", "--workers", "1", "-q"]
    assert main([*argv, *fast]) == 0
    err = capsys.readouterr().err.splitlines()
    warnings = [line for line in err if line.startswith("stereodeblur: warning: ")]
    assert warnings and all("ground-truth" in w for w in warnings), err
    assert len(warnings) == len(set(warnings))


def test_an_exposure_the_frames_contradict_warns_once_per_frame(tmp_path, capsys):
    """A plane exposed for 0.8 of the frame interval, told 0.3 of it: one line names the frame,
    the exposure given and the frames' estimate; told the truth, no warning."""
    from dataclasses import replace

    from stereodeblur.geometry.camera import Exposure
    from stereodeblur.synth.planar import FRAME_RATE, planar_setup, write_rendered_scene
    from stereodeblur.synth.render import render_scene

    setup = planar_setup("upward", size=(160, 120), num_frames=3)
    setup = replace(setup, exposure=Exposure(FRAME_RATE, 0.8 / FRAME_RATE))
    scene = write_rendered_scene(render_scene(setup, num_samples=24), tmp_path / "upward")
    fast = ["--views", "left", "--frames", "1", "--samples", "4", "--irls", "1", "--cg", "1"]
    fast += ["--workers", "1", "-q", "--overwrite"]
    out = tmp_path / "out"
    shown = {}
    for told in (0.3, 0.8):
        exposure = str(told / FRAME_RATE)
        assert main(["deblur", str(scene), "-o", str(out), "--exposure", exposure, *fast]) == 0
        err = capsys.readouterr().err.splitlines()
        shown[told] = [line for line in err if "looks too" in line]
    assert shown[0.8] == []
    (line,) = shown[0.3]
    assert line.startswith("stereodeblur: warning: frame 1: the exposure given, 0.015 s, looks")
    assert "too short: the frames say about 0.04" in line, line  # 0.8 x 0.05 s
