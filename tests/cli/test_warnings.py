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
