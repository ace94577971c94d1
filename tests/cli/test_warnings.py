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


def _upward_scene(root):
    """A plane exposed for 0.8 of the frame interval (0.04 s)."""
    from dataclasses import replace

    from stereodeblur.geometry.camera import Exposure
    from stereodeblur.synth.planar import FRAME_RATE, planar_setup, write_rendered_scene
    from stereodeblur.synth.render import render_scene

    setup = planar_setup("upward", size=(160, 120), num_frames=3)
    setup = replace(setup, exposure=Exposure(FRAME_RATE, 0.8 / FRAME_RATE))
    return write_rendered_scene(render_scene(setup, num_samples=24), root)


FAST_LEFT = ["--views", "left", "--frames", "1", "--samples", "4", "--irls", "1", "--cg", "1"]


def test_an_exposure_the_frames_contradict_warns_once_per_frame(tmp_path, capsys):
    """Told 0.3 of the frame interval: one line names the frame, the exposure given and the
    frames' estimate; told the truth, no warning."""
    scene = _upward_scene(tmp_path / "upward")
    fast = [*FAST_LEFT, "--workers", "1", "-q", "--overwrite"]
    out = tmp_path / "out"
    shown = {}
    for told in ("0.015", "0.04"):
        assert main(["deblur", str(scene), "-o", str(out), "--exposure", told, *fast]) == 0
        err = capsys.readouterr().err.splitlines()
        shown[told] = [line for line in err if "looks too" in line]
    assert shown["0.04"] == []
    (line,) = shown["0.015"]
    assert line.startswith("stereodeblur: warning: frame 1: the exposure given, 0.015 s, looks")
    assert "too short: the frames say about 0.04" in line, line


def test_a_frame_deblurred_with_a_saved_sceneflow_warns_the_same_way(tmp_path, capsys):
    scene = _upward_scene(tmp_path / "upward")
    assert main(["sceneflow", str(scene), "--frames", "1", "-o", str(tmp_path / "sf"), "-q"]) == 0
    saved = tmp_path / "sf" / "sceneflow" / "000001.npz"
    capsys.readouterr()
    argv = ["deblur", str(scene), "-o", str(tmp_path / "out"), "--sceneflow", str(saved)]
    assert main([*argv, "--exposure", "0.015", *FAST_LEFT, "-q"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("stereodeblur: warning: frame 1: the exposure"), err
