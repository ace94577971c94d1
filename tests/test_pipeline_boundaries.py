"""The pipeline's boundary-weight, boundary-mask and alpha switches."""

from dataclasses import replace

import numpy as np
import pytest

from stereodeblur.blur.visibility import hidden_fraction, sceneflow_visibility
from stereodeblur.deconv.noise import auto_alpha
from stereodeblur.deconv.trust import BOUNDARY_RELATIVE, OUTSIDE_WEIGHT, leaves_view
from stereodeblur.deconv.weights import hidden_weights
from stereodeblur.errors import InputError
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import (
    DeblurSettings,
    boundary_motion,
    build_operator,
    deblur_frame,
    deblur_stereo_frame,
    frame_motion,
)
from stereodeblur.pipeline.motion import RELABEL_JUMP, RELABEL_MARGIN
from stereodeblur.sceneflow.relabel import relabel_by_flow
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    rendered = make_object_scene("squares", size=(64, 48), num_samples=8)
    return open_scene(write_rendered_scene(rendered, tmp_path_factory.mktemp("s") / "squares"))


# alpha 'auto': one solve per view (the boundary handling is what these tests look at)
# One observation per view: these tests are about each view's own data weights.
FAST = {
    "num_irls": 3,
    "num_cg": 4,
    "num_samples": 8,
    "motion_source": "gt",
    "alpha": "auto",
    "observations": "single",
}


def test_gt_mask_keeps_mixed_pixels_at_zero_weight(scene):
    mixed = scene.read_gt_mixed("left", 1)
    assert mixed.any()
    for weights in ("none", "adaptive"):
        settings = DeblurSettings(boundary_weights=weights, boundary_mask="gt", **FAST)
        result = deblur_frame(scene, 1, settings=settings)
        assert np.all(result.result.weights[mixed] == 0)
        expected = np.ones(mixed.shape, np.float32)
        if weights == "adaptive":  # low where the exposure path leaves the view, and
            motion = result.motion  # (true motion: no dense flow) where hidden surfaces show
            duty_cycle = scene.info.exposure.duty_cycle
            outside = leaves_view(motion.flow_forward, motion.flow_backward, duty_cycle)
            expected[outside] = OUTSIDE_WEIGHT
            visible = sceneflow_visibility(motion.sceneflow, scene.info.exposure, 8)
            expected *= hidden_weights(hidden_fraction(visible))
            assert np.any(expected[mixed] < 1)
        np.testing.assert_array_equal(result.result.weights[~mixed], expected[~mixed])
        assert result.weight_steps == ()
        assert (result.trust is None) == (weights == "none")


def test_alpha_auto_comes_from_the_blurred_frame(scene):
    blurred = scene.read_frame("left", 1)
    auto = deblur_frame(scene, 1, settings=DeblurSettings(boundary_weights="none", **FAST))
    assert auto.alpha == pytest.approx(auto_alpha(blurred))
    fixed = DeblurSettings(**{**FAST, "alpha": 3e-4}, boundary_weights="none")
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
    settings = DeblurSettings(**FAST, boundary_weights="adaptive")
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    given = deblur_frame(scene, 1, settings=settings, motion=motion)
    fresh = deblur_frame(scene, 1, settings=settings)
    np.testing.assert_array_equal(given.image, fresh.image)
    outside = leaves_view(motion.flow_forward, motion.flow_backward, scene.info.exposure.duty_cycle)
    assert outside.any() and not outside[4:-4, 4:-4].any()  # paths reach ~1 px
    expected = np.where(outside, np.float32(OUTSIDE_WEIGHT), np.float32(1))
    visible = sceneflow_visibility(motion.sceneflow, scene.info.exposure, 8)
    expected *= hidden_weights(hidden_fraction(visible))
    np.testing.assert_array_equal(given.result.weights, expected)
    mixed = scene.read_gt_mixed("left", 1)
    assert given.trust[mixed].mean() < given.trust[~mixed].mean()  # boundaries are distrusted


def test_adaptive_takes_the_blur_near_motion_boundaries_from_the_dense_flow(scene):
    settings = DeblurSettings(**{**FAST, "motion_source": "sceneflow"})
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    dense_forward, dense_backward = motion.boundary_flow
    assert dense_forward.shape == motion.flow_forward.shape and dense_backward is not None
    exposure = scene.info.exposure
    hybrid, band = boundary_motion(motion, exposure.duty_cycle)
    assert band.any() and not band.all()
    np.testing.assert_array_equal(hybrid.flow_forward[band], dense_forward[band])
    np.testing.assert_array_equal(hybrid.flow_backward[band], dense_backward[band])
    np.testing.assert_allclose(hybrid.flow_forward[~band], motion.flow_forward[~band], rtol=1e-6)
    merged = build_operator(hybrid, exposure, settings, flow_rows=band).matrix.toarray()
    homographies = build_operator(motion, exposure, settings).matrix.toarray()
    flow_kernels = DeblurSettings(**{**FAST, "kernels": "displacement"})
    displacements = build_operator(hybrid, exposure, flow_kernels).matrix.toarray()
    rows = band.ravel()
    np.testing.assert_array_equal(merged[rows], displacements[rows])
    np.testing.assert_array_equal(merged[~rows], homographies[~rows])
    assert not np.array_equal(merged, homographies)


def test_cubic_interpolation_reaches_both_kinds_of_rows(scene):
    settings = DeblurSettings(**{**FAST, "motion_source": "sceneflow", "interpolation": "cubic"})
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    exposure = scene.info.exposure
    hybrid, band = boundary_motion(motion, exposure.duty_cycle)
    merged = build_operator(hybrid, exposure, settings, flow_rows=band).matrix
    cubic = build_operator(motion, exposure, settings).matrix
    bilinear = build_operator(motion, exposure, DeblurSettings(**FAST, interpolation="bilinear"))
    bilinear = bilinear.matrix
    assert (cubic.data < 0).any() and (bilinear.data >= 0).all()
    assert cubic.nnz > 1.5 * bilinear.nnz
    flow_kernels = DeblurSettings(**{**FAST, "kernels": "displacement", "interpolation": "cubic"})
    displacements = build_operator(hybrid, exposure, flow_kernels).matrix
    rows = band.ravel()
    np.testing.assert_array_equal(merged[~rows].toarray(), cubic[~rows].toarray())
    np.testing.assert_array_equal(merged[rows].toarray(), displacements[rows].toarray())
    assert (displacements.data < 0).any()


def _spy(monkeypatch, module, function: str, keyword: str) -> list:
    """Record the ``keyword`` argument of every call of ``module.<function>``."""
    seen = []
    original = getattr(module, function)

    def spy(*args, **kwargs):
        seen.append(kwargs.get(keyword))
        return original(*args, **kwargs)

    monkeypatch.setattr(module, function, spy)
    return seen


def test_the_anchor_is_used_only_without_dense_flow_rows(scene, monkeypatch):
    import dataclasses

    from stereodeblur.pipeline import deconvolve

    anchors = _spy(monkeypatch, deconvolve, "deblur_irls", "anchor")
    settings = DeblurSettings(**{**FAST, "motion_source": "sceneflow"}, boundary_weights="adaptive")
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    hybrid = deblur_frame(scene, 1, settings=settings, motion=motion)
    plain = deblur_frame(
        scene, 1, settings=settings, motion=dataclasses.replace(motion, boundary_flow=None)
    )
    assert anchors[0] is None  # the dense flow's rows explain the boundaries
    assert anchors[1] is not None and anchors[1].max() > 0  # the anchor guards the homographies
    assert (hybrid.trust < 1).any() and (plain.trust < 1).any()


def test_the_operator_is_occlusion_aware_only_without_dense_flow_rows(scene, monkeypatch):
    from stereodeblur.pipeline import operator

    visibilities = _spy(monkeypatch, operator, "build_operator", "visible")
    estimated = DeblurSettings(**{**FAST, "motion_source": "sceneflow"})
    deblur_frame(scene, 1, settings=estimated)  # with the dense flow's rows
    true = DeblurSettings(**FAST)  # true motion: no dense flow
    result = deblur_frame(scene, 1, settings=true)
    deblur_frame(scene, 1, settings=DeblurSettings(**FAST, boundary_weights="none"))
    assert visibilities[0] is None and visibilities[2] is None
    visible = visibilities[1]
    assert visible is not None and visible.shape == (8,) + result.motion.sceneflow.shape
    hidden = hidden_fraction(visible) > 0
    assert hidden.any()
    assert np.all(result.result.weights[hidden] < 1)
    # --no-boundary-flow: the estimated scene flow's occlusion-aware rows everywhere
    own = deblur_frame(scene, 1, settings=replace(estimated, boundary_flow=False))
    assert own.motion.boundary_flow is not None  # computed to move the boundaries
    np.testing.assert_array_equal(
        visibilities[3],
        sceneflow_visibility(own.motion.sceneflow, scene.info.exposure, 8),
    )
    unmoved = replace(estimated, boundary_flow=False, relabel_radius=0)
    assert deblur_frame(scene, 1, settings=unmoved).motion.boundary_flow is None


def test_the_scene_flows_boundaries_move_to_the_dense_flows(scene):
    estimated = DeblurSettings(**{**FAST, "motion_source": "sceneflow"})
    unmoved = frame_motion(scene, 1, "left", replace(estimated, relabel_radius=0))
    moved = frame_motion(scene, 1, "left", estimated)
    expected = relabel_by_flow(
        unmoved.sceneflow,
        *unmoved.boundary_flow,
        radius=estimated.relabel_radius,
        jump=RELABEL_JUMP,
        relative=BOUNDARY_RELATIVE,
        margin=RELABEL_MARGIN,
    )
    assert not np.array_equal(expected.labels, unmoved.sceneflow.labels)
    np.testing.assert_array_equal(moved.sceneflow.labels, expected.labels)
    np.testing.assert_array_equal(moved.flow_forward, expected.flow())
    np.testing.assert_array_equal(moved.flow_backward, expected.reversed().flow())
    # A given scene flow is moved the same way; the paper's weights do not move it.
    given = deblur_stereo_frame(
        scene, 1, views=("left",), settings=estimated, sceneflow=unmoved.sceneflow
    )
    np.testing.assert_array_equal(given.motion.views["left"].sceneflow.labels, expected.labels)
    paper = replace(estimated, boundary_weights="paper")
    np.testing.assert_array_equal(
        frame_motion(scene, 1, "left", paper).sceneflow.labels, unmoved.sceneflow.labels
    )


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
        ("boundary_flow", "yes", "boundary_flow"),
        ("relabel_radius", -1, "relabel_radius"),
        ("relabel_radius", 2.5, "relabel_radius"),
    ],
)
def test_bad_settings_are_input_errors(field, value, message):
    with pytest.raises(InputError, match=message):
        DeblurSettings(**{field: value})


def test_gated_takes_the_dense_rows_only_where_the_dense_flow_predicts_clearly_better(scene):
    from stereodeblur.pipeline import GateTrusts, gate_trusts, read_window, view_operator
    from stereodeblur.settings import GATE_MARGIN

    settings = DeblurSettings(**{**FAST, "motion_source": "sceneflow"}, boundary_weights="gated")
    window = read_window(scene, 1, ("left",), settings)
    motion = frame_motion(scene, 1, "left", settings, window.blurred("left"))
    trusts = gate_trusts(window, "left", motion, noise_sigma=0.01)
    own, dense = trusts.own, trusts.dense
    _, band = boundary_motion(motion, window.exposure.duty_cycle)
    np.testing.assert_array_equal(own[~band], 1)
    np.testing.assert_array_equal(dense[~band], 1)
    assert (own[band] < 1).any() and (dense[band] != own[band]).any()
    built = view_operator(motion, window.exposure, settings, trusts=trusts)
    np.testing.assert_array_equal(built.flow_rows, band & (dense > own + GATE_MARGIN))
    # A dense flow that is always clearly better takes the whole band, as 'adaptive' does;
    # one that never is leaves the scene flow's homographies (and no occlusion-aware rows).
    ones, untrusted = np.ones_like(own), np.where(band, 0, 1).astype(np.float32)  # 1 off the band
    everywhere = view_operator(
        motion, window.exposure, settings, trusts=GateTrusts(untrusted, ones, 0.01)
    )
    adaptive = view_operator(
        motion,
        window.exposure,
        DeblurSettings(**{**FAST, "motion_source": "sceneflow"}, boundary_weights="adaptive"),
    )
    np.testing.assert_array_equal(everywhere.flow_rows, band)
    np.testing.assert_array_equal(
        everywhere.operator.matrix.toarray(), adaptive.operator.matrix.toarray()
    )
    assert adaptive.trusts is None
    nowhere = view_operator(motion, window.exposure, settings, trusts=GateTrusts(ones, ones, 0.01))
    assert not nowhere.flow_rows.any() and nowhere.hidden is None
    np.testing.assert_array_equal(
        nowhere.operator.matrix.toarray(),
        build_operator(motion, window.exposure, settings).matrix.toarray(),
    )


@pytest.mark.parametrize("source", ["gt", "sceneflow"])
def test_gated_never_anchors_and_keeps_the_outside_weights(scene, monkeypatch, source):
    from stereodeblur.pipeline import deconvolve

    anchors = _spy(monkeypatch, deconvolve, "deblur_irls", "anchor")
    settings = DeblurSettings(**{**FAST, "motion_source": source}, boundary_weights="gated")
    motion = frame_motion(scene, 1, "left", settings, scene.read_frame("left", 1))
    result = deblur_frame(scene, 1, settings=settings, motion=motion)
    adaptive = deblur_frame(
        scene,
        1,
        settings=DeblurSettings(**{**FAST, "motion_source": source}, boundary_weights="adaptive"),
        motion=motion,
    )
    assert anchors[0] is None
    assert result.trust is not None and (result.trust < 1).any()
    if source == "gt":  # no dense flow: the adaptive operator, data weights and trust
        assert anchors[1] is not None and anchors[1].max() > 0
        np.testing.assert_array_equal(result.result.weights, adaptive.result.weights)
        np.testing.assert_array_equal(result.trust, adaptive.trust)
        assert not np.array_equal(result.image, adaptive.image)
    else:
        duty_cycle = scene.info.exposure.duty_cycle
        outside = leaves_view(motion.flow_forward, motion.flow_backward, duty_cycle)
        expected = np.where(outside, np.float32(OUTSIDE_WEIGHT), np.float32(1))
        np.testing.assert_array_equal(result.result.weights, expected)
