"""A rendered 12-frame stereo clip and one serial CLI run over it, shared by the clip tests."""

import pytest

from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene
from tests.clip.clip_helpers import FAST, NUM_FRAMES, SIZE, run_cli


@pytest.fixture(scope="session")
def clip_scene(tmp_path_factory):
    """Roll with exposure = frame interval: strong, curved blur even at 64x48."""
    scene = make_planar_scene(
        "long_exposure_roll", size=SIZE, num_frames=NUM_FRAMES, num_samples=32
    )
    return write_rendered_scene(scene, tmp_path_factory.mktemp("clip") / "scene")


@pytest.fixture(scope="session")
def reference_run(clip_scene, tmp_path_factory):
    """The whole clip, both views, deblurred serially through the CLI."""
    output = tmp_path_factory.mktemp("reference") / "out"
    result = run_cli("deblur", clip_scene, "-o", output, "--workers", "1", *FAST)
    result.output = output
    return result
