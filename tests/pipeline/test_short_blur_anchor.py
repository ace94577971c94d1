"""The anchor to the blurred frame where the blur is short: where the data terms put it."""

import numpy as np
import pytest

from stereodeblur.deconv.trust import short_blur_anchor
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import DeblurSettings
from stereodeblur.pipeline.frame import build_view_operator
from stereodeblur.pipeline.motion import stereo_motion
from stereodeblur.pipeline.weights import data_terms
from stereodeblur.pipeline.window import read_window
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene

FAST = {"motion_source": "gt", "num_samples": 16, "num_irls": 2, "num_cg": 5}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    rendered = make_object_scene("squares", size=(64, 48), num_samples=16)
    return open_scene(write_rendered_scene(rendered, tmp_path_factory.mktemp("s") / "squares"))


def _terms(scene, **options):
    settings = DeblurSettings(**FAST, **options)
    window = read_window(scene, 1, ("left", "right"), settings)
    motion = stereo_motion(scene, window, ("left", "right"), settings).views["left"]
    operator = build_view_operator(window, motion, settings)
    return data_terms(scene, window, "left", operator, settings), motion, window


@pytest.mark.parametrize("handling", ["gated", "adaptive"])
def test_the_anchor_follows_the_motions_blur_length(scene, handling):
    terms, motion, window = _terms(scene, short_blur_anchor=0.2, boundary_weights=handling)
    expected = short_blur_anchor(
        motion.flow_forward, motion.flow_backward, window.exposure.duty_cycle, 0.2
    )
    assert 0 < expected.max() and expected.min() < 0.2  # the scene has short and long blurs
    if handling == "gated":
        np.testing.assert_array_equal(terms.anchor, expected)
    else:  # the larger of it and the trust's anchor
        assert np.all(terms.anchor >= expected) and terms.anchor.shape == expected.shape


@pytest.mark.parametrize(
    "options",
    [
        {},  # the default: none
        {"short_blur_anchor": 0.2, "boundary_weights": "paper"},
        {"short_blur_anchor": 0.2, "boundary_weights": "none"},
    ],
)
def test_no_anchor_by_default_nor_with_the_papers_handling(scene, options):
    terms, _, _ = _terms(scene, **options)
    assert terms.anchor is None
