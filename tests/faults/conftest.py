"""A tiny rendered stereo clip and one uninterrupted serial run over it."""

import pytest

from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene
from tests.faults.helpers import FAST, NUM_FRAMES, SIZE, run_cli


@pytest.fixture(scope="session")
def tiny_scene(tmp_path_factory):
    scene = make_planar_scene(
        "long_exposure_roll", size=SIZE, num_frames=NUM_FRAMES, num_samples=32
    )
    return write_rendered_scene(scene, tmp_path_factory.mktemp("faults") / "scene")


@pytest.fixture(scope="session")
def reference(tiny_scene, tmp_path_factory):
    """The whole clip, both views, deblurred serially and uninterrupted."""
    output = tmp_path_factory.mktemp("faults-reference") / "out"
    result = run_cli("deblur", tiny_scene, "-o", output, "--workers", "1", "-q", *FAST)
    assert result.code == 0, result.stderr
    return output


@pytest.fixture(scope="session")
def slow_scene(tmp_path_factory):
    """Two 200x150 frames: a signal sent once a run has started lands before its first frame
    is written (about 2 s later with ``FAST``, 10 s with ``SLOW``; on the tiny clip a warm
    worker can write a frame first)."""
    scene = make_planar_scene("long_exposure_roll", size=(200, 150), num_frames=2, num_samples=32)
    return write_rendered_scene(scene, tmp_path_factory.mktemp("slow") / "scene")
