"""DeblurSettings <-> options in one place: round trips, defaults and limits."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereodeblur.cli import build_parser
from stereodeblur.cli.settings_options import arguments_for, settings_from_arguments
from stereodeblur.evaluation.paper_columns import COLUMNS, MASKED_COLUMNS, TRUE_MOTION
from stereodeblur.settings import DeblurSettings
from tests.cli.refusals import refused, tree_checksums


def _parse(*options):
    return settings_from_arguments(build_parser().parse_args(["deblur", "s", "-o", "o", *options]))


def test_no_options_give_the_default_settings():
    assert _parse() == DeblurSettings()


@pytest.mark.parametrize("column", COLUMNS + MASKED_COLUMNS + (TRUE_MOTION,), ids=lambda c: c.key)
def test_every_bench_column_is_reachable_from_the_command_line(column):
    settings = column.settings(DeblurSettings(num_samples=16, num_irls=3, num_cg=7))
    assert _parse(*arguments_for(settings)) == settings


def test_interpolation_option_round_trips():
    settings = _parse("--interpolation", "cubic")
    assert settings == DeblurSettings(interpolation="cubic")
    assert _parse(*arguments_for(settings)) == settings


def test_bench_paper_takes_the_same_options():
    args = build_parser().parse_args(["bench", "paper", "--samples", "9", "--irls", "3"])
    settings = settings_from_arguments(args)
    assert (settings.num_samples, settings.num_irls) == (9, 3)
    assert settings.num_cg == DeblurSettings().num_cg


@pytest.mark.parametrize(
    "option, value, fragments",
    [
        ("--samples", "1", ["--samples", "2..1000", "1"]),
        ("--samples", "100000", ["--samples", "2..1000", "100000"]),
        ("--irls", "0", ["--irls", "1..1000"]),
        ("--cg", "0", ["--cg", "1..1000"]),
        ("--alpha", "1e300", ["--alpha", "(0, 1]", "1e300"]),
        ("--alpha", "0", ["--alpha", "(0, 1]"]),
        ("--alpha", "nan", ["--alpha", "(0, 1]"]),
        ("--segments", "0", ["--segments", "1..100000"]),
        ("--workers", "0", ["--workers", "1..1024"]),
        ("--exposure", "-1", ["--exposure", "> 0"]),
    ],
)
def test_option_limits_are_checked_before_the_run(tiny_scene, tmp_path, capsys, option, value,
                                                  fragments):  # fmt: skip
    out = tmp_path / "out"
    argv = ["deblur", tiny_scene, "-o", out, "--motion-source", "gt", option, value]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=fragments)


def test_cross_view_alpha_without_a_disparity_is_refused(tiny_scene, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["deblur", tiny_scene, "-o", out, "--motion-source", "initial-flow"]
    argv += ["--kernels", "displacement", "--alpha", "cross-view"]
    fragments = ["--alpha", "cross-view", "initial-flow"]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=fragments)


def test_huge_frame_range_is_refused_without_expanding_it(tiny_scene, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["deblur", tiny_scene, "-o", out, "--frames", "0:100000000000"]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=["--frames", "0:3"])


def test_checksums_see_a_changed_byte(tiny_scene):
    before = tree_checksums(tiny_scene)
    path = tiny_scene / "camera.json"
    path.write_bytes(path.read_bytes() + b" ")
    assert tree_checksums(tiny_scene) != before


def test_library_parameters_map_to_their_options():
    from stereodeblur.cli.settings_options import option_for

    assert option_for("num_samples") == "--samples"
    assert option_for("boundary_weights") == "--boundary-weights"
    assert option_for("frame_rate") == "--frame-rate"
    assert option_for("no_such_parameter") is None
    assert option_for(None) is None


def test_an_input_error_naming_a_parameter_points_at_the_option(tmp_path, capsys):
    from stereodeblur.cli import main
    from tests.io.stereo_layouts import write_video_pair

    rng = np.random.default_rng(0)
    frames = [rng.random((24, 32, 3)) for _ in range(3)]
    K = [[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]]
    left, right, _ = write_video_pair(tmp_path, frames, frames, np.array(K), 0.1)
    assert main(["deblur", str(left), str(right), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "(option --calib)" in err[0], err


FUZZ = settings(max_examples=150, deadline=None, derandomize=True)


@FUZZ
@given(
    kernels=st.sampled_from(["homography", "displacement"]),
    motion_source=st.sampled_from(["gt", "sceneflow", "initial-flow"]),
    num_samples=st.integers(2, 1000),
    alpha=st.one_of(st.just("auto"), st.floats(1e-12, 1.0)),
    num_irls=st.integers(1, 1000),
    num_cg=st.integers(1, 1000),
    num_segments=st.one_of(st.none(), st.integers(1, 100_000)),
    boundary_weights=st.sampled_from(["adaptive", "gated", "paper", "none"]),
    boundary_mask=st.sampled_from([None, "gt"]),
)
def test_any_settings_round_trip_through_the_options(**fields):
    if fields["motion_source"] == "initial-flow":
        fields["kernels"] = "displacement"
    settings_value = DeblurSettings(**fields)
    assert _parse(*arguments_for(settings_value)) == settings_value


@FUZZ
@given(text=st.text(max_size=30))
def test_option_types_accept_or_refuse_in_one_line(text):
    import argparse

    from stereodeblur.cli.base import integer, names, positive_number, size, sizes
    from stereodeblur.cli.render_view import vector3
    from stereodeblur.cli.settings_options import alpha

    for parse in (size, sizes, names, integer(2, 1000), positive_number, alpha, vector3):
        try:
            parse(text)
        except argparse.ArgumentTypeError as err:
            assert "\n" not in str(err)
