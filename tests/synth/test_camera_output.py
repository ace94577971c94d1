"""The camera of benchmarks/camera_output.py: its noise, its encoding, its seed."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from stereodeblur.io.srgb import linear_to_srgb, srgb_to_linear

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.fixture(scope="module")
def camera():
    sys.path.insert(0, str(BENCHMARKS))  # it imports calibrate_defaults by name
    try:
        spec = importlib.util.spec_from_file_location(
            "camera_output", BENCHMARKS / "camera_output.py"
        )
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(BENCHMARKS))
        sys.modules.pop("calibrate_defaults", None)


@pytest.mark.parametrize("level", [0.02, 0.25, 0.7])
def test_camera_noise_is_shot_and_read_noise_in_8_bit_srgb(camera, level):
    linear = np.full((200, 200, 3), level)
    frame = camera.camera_frame(linear, np.random.default_rng(0))
    assert frame.dtype == np.uint8
    decoded = srgb_to_linear(frame / 255.0)
    electrons = level * camera.FULL_WELL
    expected = np.sqrt(electrons + camera.READ_NOISE**2) / camera.FULL_WELL
    quantisation = (srgb_to_linear(linear_to_srgb(level) + 0.5 / 255) - level) / np.sqrt(3)
    assert abs(decoded.mean() - level) < 0.05 * level
    assert abs(decoded.std() - np.hypot(expected, quantisation)) < 0.1 * expected


def test_camera_frames_repeat_with_the_seed(camera):
    linear = np.random.default_rng(1).uniform(0, 1, (16, 16, 3))
    first = camera.camera_frame(linear, np.random.default_rng(5))
    again = camera.camera_frame(linear, np.random.default_rng(5))
    other = camera.camera_frame(linear, np.random.default_rng(6))
    assert np.array_equal(first, again) and not np.array_equal(first, other)
