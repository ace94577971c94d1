import dataclasses

import pytest

from stereodeblur.errors import InputError
from stereodeblur.sceneflow.settings import SceneFlowSettings


def test_defaults_are_valid_and_frozen():
    settings = SceneFlowSettings()
    assert settings.num_segments is None and settings.motion_prior_share is None
    assert SceneFlowSettings(motion_prior_share=0.003).motion_prior_share == 0.003
    with pytest.raises(dataclasses.FrozenInstanceError):
        settings.smoothness = 1.0


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("num_segments", 0),
        ("num_segments", 2.5),
        ("plane_hypotheses", 0),
        ("num_sweeps", True),
        ("num_region_rounds", -1),
        ("census_threshold", 0.0),
        ("census_denoise", -1.0),
        ("smoothness", float("nan")),
        ("truncation", float("inf")),
        ("edge_floor", 1.5),
        ("min_global_fraction", -0.1),
        ("refine_scale", "0.25"),
        ("motion_prior_share", 1.5),
        ("motion_prior_share", "none"),
        ("other_side", 1),
    ],
)
def test_invalid_values_name_the_field(name, value):
    with pytest.raises(InputError, match=f"SceneFlowSettings.{name} "):
        SceneFlowSettings(**{name: value})


def test_replace_keeps_validating():
    assert dataclasses.replace(SceneFlowSettings(), num_segments=300).num_segments == 300
    with pytest.raises(InputError, match="max_neighbours"):
        dataclasses.replace(SceneFlowSettings(), max_neighbours=0)
