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
