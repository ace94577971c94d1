"""The pipeline's boundary-weight, boundary-mask and alpha switches."""

import numpy as np
import pytest

from stereodeblur.deconv.noise import auto_alpha
from stereodeblur.errors import InputError
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import DeblurSettings, deblur_frame, frame_motion
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    rendered = make_object_scene("squares", size=(64, 48), num_samples=8)
    return open_scene(write_rendered_scene(rendered, tmp_path_factory.mktemp("s") / "squares"))


FAST = {"num_irls": 3, "num_cg": 4, "num_samples": 8, "motion_source": "gt"}


def test_gt_mask_keeps_mixed_pixels_at_zero_weight(scene):
    mixed = scene.read_gt_mixed("left", 1)
    assert mixed.any()
    for weights in ("none", "adaptive"):
        settings = DeblurSettings(boundary_weights=weights, boundary_mask="gt", **FAST)
        result = deblur_frame(scene, 1, settings=settings)
        assert np.all(result.result.weights[mixed] == 0)
        np.testing.assert_array_equal(result.result.weights[~mixed], 1)
        assert result.weight_steps == ()
        assert (result.trust is None) == (weights == "none")


def test_alpha_auto_comes_from_the_blurred_frame(scene):
    blurred = scene.read_frame("left", 1)
    auto = deblur_frame(scene, 1, settings=DeblurSettings(boundary_weights="none", **FAST))
    assert auto.alpha == pytest.approx(auto_alpha(blurred))
    fixed = DeblurSettings(alpha=3e-4, boundary_weights="none", **FAST)
    assert deblur_frame(scene, 1, settings=fixed).alpha == 3e-4


def test_paper_weights_start_from_the_occlusion_and_follow_eq5(scene):
    settings = DeblurSettings(boundary_weights="paper", **FAST)
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    result = deblur_frame(scene, 1, settings=settings, motion=motion)
    first = result.result.weights_history[0]
    np.testing.assert_array_equal(first, np.where(motion.sceneflow.occlusion, 0, 1))
    step = result.weight_steps[-1]
    expected = np.exp(-4000 / 3 * step.residual_norm.astype(np.float64) ** 2)
    np.testing.assert_allclose(step.weights, expected, rtol=1e-5)


def test_adaptive_trust_with_given_motion_matches_a_fresh_run(scene):
    settings = DeblurSettings(**FAST)  # adaptive trust and auto alpha are the defaults
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    given = deblur_frame(scene, 1, settings=settings, motion=motion)
    fresh = deblur_frame(scene, 1, settings=settings)
    np.testing.assert_array_equal(given.image, fresh.image)
    np.testing.assert_array_equal(given.result.weights, 1)
    mixed = scene.read_gt_mixed("left", 1)
    assert given.trust[mixed].mean() < given.trust[~mixed].mean()  # boundaries are distrusted


def test_trust_uses_both_neighbouring_frames(scene):
    from stereodeblur.deconv.trust import motion_trust, near_motion_boundaries

    settings = DeblurSettings(**FAST)
    blurred = scene.read_frame("left", 1)
    motion = frame_motion(scene, 1, "left", settings, blurred)
    result = deblur_frame(scene, 1, settings=settings, motion=motion)
    forward = motion_trust(blurred, scene.read_frame("left", 2), motion.flow_forward)
    backward = motion_trust(blurred, scene.read_frame("left", 0), motion.flow_backward)
    band = near_motion_boundaries(motion.flow_forward, scene.info.exposure.duty_cycle)
    assert band.any() and not band.all()
    np.testing.assert_array_equal(result.trust[band], np.maximum(forward, backward)[band])
    np.testing.assert_array_equal(result.trust[~band], 1)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("alpha", -1.0, "alpha"),
        ("alpha", "often", "alpha"),
        ("boundary_weights", "always", "boundary weights"),
        ("boundary_mask", "estimated", "boundary mask"),
    ],
)
def test_bad_settings_are_input_errors(field, value, message):
    with pytest.raises(InputError, match=message):
        DeblurSettings(**{field: value})
