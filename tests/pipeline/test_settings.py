"""DeblurSettings: one constant per default, validated on construction."""

import dataclasses

import pytest

from stereodeblur import settings as defaults
from stereodeblur.errors import InputError
from stereodeblur.pipeline import DeblurSettings
from stereodeblur.sceneflow.settings import SceneFlowSettings


def test_defaults_are_the_module_constants():
    s = DeblurSettings()
    assert s.motion_source == "sceneflow" == defaults.DEFAULT_MOTION_SOURCE
    assert (s.num_samples, s.num_irls, s.num_cg) == (70, 4, 25)
    assert s.num_samples == defaults.NUM_SAMPLES and defaults.PAPER_ALPHA == 1e-3
    assert (s.kernels, s.alpha, s.boundary_weights) == ("homography", "held-out", "gated")
    assert s.sceneflow == SceneFlowSettings()


def test_num_segments_overrides_the_estimators():
    base = DeblurSettings(sceneflow=SceneFlowSettings(num_segments=300))
    assert base.estimator.num_segments == base.segments == 300
    given = dataclasses.replace(base, num_segments=200)
    assert given.estimator.num_segments == given.segments == 200
    assert given.estimator.census_threshold == SceneFlowSettings().census_threshold
    assert DeblurSettings().segments is None


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("kernels", "gauss", "kernels"),
        ("interpolation", "lanczos", "interpolation must be one of bilinear, cubic"),
        ("motion_source", "guess", "motion source"),
        ("num_samples", 0, "num_samples"),
        ("num_irls", 1.5, "num_irls"),
        ("num_cg", True, "num_cg"),
        ("num_segments", -3, "num_segments"),
        ("seed", "zero", "seed"),
        ("alpha", float("nan"), "alpha"),
        ("num_samples", 1, r"num_samples must be a whole number in 2\.\.1000, got 1"),
        ("num_samples", 100_000, r"in 2\.\.1000"),
        ("num_cg", 0, r"num_cg must be a whole number in 1\.\.1000"),
        ("num_irls", 1001, r"in 1\.\.1000"),
        ("num_segments", 10**6, r"in 1\.\.100000"),
        ("alpha", 1e300, r"alpha must be 'held-out', 'auto', 'cross-view' or in \(0, 1\]"),
        ("sceneflow", {"num_segments": 3}, "SceneFlowSettings"),
    ],
)
def test_bad_settings_name_the_field(field, value, message):
    with pytest.raises(InputError, match=message):
        DeblurSettings(**{field: value})


def test_initial_flow_needs_displacement_kernels():
    with pytest.raises(InputError, match="kernels='displacement'"):
        DeblurSettings(motion_source="initial-flow")
    DeblurSettings(motion_source="initial-flow", kernels="displacement")
