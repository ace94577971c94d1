"""Shared fixtures: tiny scenes written in the scene format."""

import signal

import numpy as np
import pytest

from stereodeblur.geometry import Exposure, StereoCamera
from stereodeblur.io.scene import CameraInfo, SceneWriter


def write_tiny_scene(root, *, num_frames=3, size=(40, 32), seed=0, gt=True):
    """A static random-texture scene: frames equal their sharp images, zero flow."""
    w, h = size
    info = CameraInfo(
        StereoCamera([[50.0, 0, w / 2], [0, 50.0, h / 2], [0, 0, 1]], 0.1),
        Exposure(20.0, 0.04),
        "linear",
    )
    rng = np.random.default_rng(seed)
    writer = SceneWriter(root, info)
    for i in range(num_frames):
        for view in ("left", "right"):
            img = rng.random((h, w, 3)).astype(np.float32)
            writer.write_frame(view, i, img)
            if gt:
                writer.write_gt_sharp(view, i, img)
                writer.write_gt_disparity(view, i, np.full((h, w), 2.0, np.float32))
        if gt and i + 1 < num_frames:
            writer.write_gt_flow("left", i, np.zeros((h, w, 2), np.float32))
    return root


@pytest.fixture
def tiny_scene(tmp_path):
    return write_tiny_scene(tmp_path / "scene")


def pytest_configure(config):
    """Ctrl-C as at a terminal, also where the test run was started as a background job (which
    starts with SIGINT ignored, a disposition every process it starts would inherit): the
    interrupt tests send SIGINT to the command line and expect it to stop."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
