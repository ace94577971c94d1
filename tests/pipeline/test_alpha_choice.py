"""Alpha chosen by predicting the other view: 'cross-view' and 'held-out'."""

from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
import pytest

from stereodeblur.cli.settings_options import alpha as alpha_option
from stereodeblur.deconv.irls import Observation
from stereodeblur.deconv.noise import alpha_from_sigma
from stereodeblur.errors import InputError
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import DeblurSettings, deblur_frame, deblur_stereo_frame
from stereodeblur.pipeline.alpha import (
    OtherView,
    below_floor,
    choose,
    held_out_error,
    local_alpha_acts,
    local_alpha_here,
    local_error,
    local_scale,
    local_terms,
    observed_error,
    own_error,
    prediction_error,
    searched,
    undominated,
    warp_to_other,
)
from stereodeblur.settings import (
    CROSS_VIEW_ALPHAS,
    CROSS_VIEW_KEEP,
    HELD_OUT_MIN_WEIGHT,
    HELD_OUT_NOISE_RATIO,
    HELD_OUT_SPAN,
    HELD_OUT_STOP,
    HELD_OUT_TIE,
    LOCAL_ALPHA_DOWN,
    LOCAL_ALPHA_NOISE,
    LOCAL_ALPHA_WINDOW,
    PAPER_ALPHA,
)
from stereodeblur.synth.objects import make_object_scene
from stereodeblur.synth.planar import write_rendered_scene

FAST = {"num_irls": 2, "num_cg": 3, "num_samples": 8}
GLOBAL = {**FAST, "local_alpha": "off"}  # one alpha per view: the choice's own solution


class _Identity:
    def forward(self, image):
        return image


def _texture(shape, seed=0):
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return 0.5 + 0.2 * np.sin(0.3 * cols + 0.2 * rows) + 0.05 * rng.standard_normal(shape)


def test_warp_takes_the_left_view_to_the_right_and_back():
    left = _texture((20, 40))
    disparity = np.full((20, 40), 3.0)
    right = np.roll(left, -3, axis=1)  # x_R(u) = x_L(u + 3)
    to_right = warp_to_other(left, disparity, +1)
    np.testing.assert_allclose(to_right[:, :-3], right[:, :-3], atol=1e-12)
    to_left = warp_to_other(right, disparity, -1)
    np.testing.assert_allclose(to_left[:, 3:], left[:, 3:], atol=1e-12)


def test_warp_interpolates_fractional_disparities_of_colour_images():
    left = np.stack([_texture((16, 30), seed) for seed in range(3)], axis=-1)
    disparity = np.full((16, 30), 2.5)
    warped = warp_to_other(left, disparity, +1)
    expected = 0.5 * (np.roll(left, -2, axis=1) + np.roll(left, -3, axis=1))
    np.testing.assert_allclose(warped[:, :-3], expected[:, :-3], atol=1e-12)


def test_prediction_error_leaves_out_the_worst_pixels():
    left = _texture((30, 40))
    disparity = np.full((30, 40), 2.0)
    right = np.roll(left, -2, axis=1)
    other = OtherView(_Identity(), right, disparity, +1)
    assert prediction_error(left, other, border=4) < 1e-20
    occluded = right.copy()
    occluded[10:12, 10:20] += 1.0  # 20 of 22 x 32 pixels: within the share left out
    assert (1 - CROSS_VIEW_KEEP) * 22 * 32 > 20
    assert prediction_error(left, OtherView(_Identity(), occluded, disparity, +1), border=4) < 1e-20
    noisy = right + 0.1
    assert prediction_error(left, OtherView(_Identity(), noisy, disparity, +1), border=4) == (
        pytest.approx(0.01)
    )


def test_the_gates_error_counts_the_pixels_the_other_view_sees_in_full():
    image = _texture((30, 40))
    seen = np.ones((30, 40), np.float32)
    assert observed_error(image, Observation(_Identity(), image, seen), border=4) < 1e-20
    occluded, unseen = image.copy(), seen.copy()
    occluded[10:12, 10:20] += 1.0
    unseen[10:12, 10:20] = 0.0  # the observation does not see them: they do not count
    assert observed_error(image, Observation(_Identity(), occluded, unseen), border=4) < 1e-20
    counted = observed_error(image, Observation(_Identity(), occluded, seen), border=4)
    assert counted == pytest.approx(20 / (22 * 32))  # untrimmed
    outside = seen.copy()
    outside[10:12, 10:20] = 0.1  # exposures that leave the view: below the least weight
    assert 0.1 < HELD_OUT_MIN_WEIGHT
    assert observed_error(image, Observation(_Identity(), occluded, outside), border=4) < 1e-20
    edge = image.copy()
    edge[:4] += 1.0  # within the border
    assert observed_error(image, Observation(_Identity(), edge, seen), border=4) < 1e-20
    colour = np.stack([image] * 3, axis=-1)
    noisy = Observation(_Identity(), colour + 0.1, seen * HELD_OUT_MIN_WEIGHT)
    assert observed_error(colour, noisy, border=4) == pytest.approx(0.01)
    blind = Observation(_Identity(), image, np.zeros_like(seen))
    assert observed_error(image, blind, border=4) == np.inf


def test_the_held_out_error_sums_the_observations_errors_where_each_sees():
    image = _texture((30, 40))
    seen = np.ones((30, 40), np.float32)
    other = Observation(_Identity(), image, seen)  # the other view agrees with the estimate
    moved = image.copy()
    moved[10:12, 10:20] += 1.0  # a motion error the other view shares does not show there
    following = Observation(_Identity(), moved, seen)
    assert held_out_error(image, [other], border=4) < 1e-20
    error = held_out_error(image, [other, following], border=4)
    assert error == pytest.approx(20 / (22 * 32))
    assert held_out_error(image, [other, following, following], border=4) == pytest.approx(
        2 * error
    )
    unseen = Observation(_Identity(), moved, np.where(moved > image, 0.0, seen))
    assert held_out_error(image, [other, unseen], border=4) < 1e-20


def test_the_own_error_is_the_views_own_frame_predicted_off_the_border():
    image = _texture((30, 40))
    blurred = image.copy()
    blurred[:4] += 1.0  # in the border: not counted
    assert own_error(image, _Identity(), blurred, border=4) < 1e-20
    blurred[10:12, 10:20] += 0.1
    assert own_error(image, _Identity(), blurred, border=4) == pytest.approx(0.01 * 20 / (22 * 32))


def test_a_candidate_a_larger_alpha_fits_as_well_is_dropped():
    alphas = (2e-5, 3e-5, 1e-4, 3e-4, 1e-3)
    # a noiseless striped frame: the own frame fits best at 1e-4, the floor's solve rings
    assert undominated(alphas, (15.0, 10.2, 7.2, 13.4, 42.1)) == [2, 3, 4]
    assert undominated(alphas, (1.0, 2.0, 3.0, 4.0, 5.0)) == [0, 1, 2, 3, 4]  # the usual
    assert undominated(alphas, (2.0, 2.0, 3.0, 1.0, 5.0)) == [3, 4]  # a tie is dominated
    assert undominated(alphas[:1], (9.0,)) == [0]
    assert undominated((3e-4, 1e-4, 2e-5), (2.0, 1.0, 3.0)) == [0, 1]  # in any order


def test_below_the_floor_only_where_the_other_view_is_predicted_to_its_noise():
    sigma = 0.005
    noise = alpha_from_sigma(sigma)
    floor = 1e-3
    assert noise < 1e-4
    within = 0.5 * HELD_OUT_NOISE_RATIO * 2 * sigma**2
    tried = below_floor(floor, within, sigma)
    assert tried == (*(a for a in CROSS_VIEW_ALPHAS[::-1] if noise < a < floor), noise)
    assert tried[:2] == (3e-4, 1e-4)
    assert below_floor(floor, 2 * HELD_OUT_NOISE_RATIO * 2 * sigma**2, sigma) == ()
    assert below_floor(noise, within, sigma) == ()  # the floor is the noise rule's own
    assert below_floor(floor, within, 0.0) == ()  # no noise: nothing is within it


def test_the_choice_is_one_step_above_the_best_predictor_within_the_grid():
    assert choose([3.0, 2.0, 1.0, 2.0, 3.0, 4.0]) == 3
    assert choose([5.0, 4.0, 3.0, 2.0, 1.5, 1.0]) == 5
    assert choose([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]) == 1


def test_held_out_takes_the_tied_predictor_nearest_the_papers_alpha():
    alphas = (2e-5, 1e-4, 3e-4, 1e-3, 3e-3)
    close = 1.0 + 0.5 * HELD_OUT_TIE
    assert choose([1.0, 0.5, 0.4, 0.3, 0.2], "held-out", alphas) == 4  # a clear minimum
    assert choose([1.0, close, 2.0, 3.0, 4.0], "held-out", alphas) == 1  # tied, nearer 1e-3
    assert choose([2.0, 1.0, 1.0, close, 2.0], "held-out", alphas) == 3  # 1e-3 itself
    assert choose([2.0, 2.0, 2.0, 1.0, close], "held-out", alphas) == 3
    low = 1.0 + 2 * HELD_OUT_TIE
    assert choose([1.0, low, low, low, low], "held-out", alphas) == 0  # not tied: the best
    # equally far from the paper's alpha in log alpha: the larger
    assert choose([1.0, 1.0], "held-out", (PAPER_ALPHA / 2, PAPER_ALPHA * 2)) == 1


def test_held_out_searches_past_a_bump_and_stops_at_a_rise_a_decade_up():
    bump, rise = 1.0 + 0.5 * HELD_OUT_STOP, 1.0 + 2 * HELD_OUT_STOP
    assert HELD_OUT_TIE < 0.5 * HELD_OUT_STOP
    decade = (1e-4, 3e-4, 1e-3, 3e-3)
    assert not searched("held-out", [1.0], decade[:1])
    assert not searched("held-out", [1.0, bump], decade[:2])  # a small bump: search on
    assert not searched("held-out", [1.0, bump, 0.5], decade[:3])
    assert searched("held-out", [1.0, rise, rise], decade[:3])
    assert searched("held-out", [1.0, bump, 0.5, 0.5 * rise], (1e-5, 3e-5, 1e-4, 1e-3))
    # a rise within a decade of the best: not yet (the best and the next may both ring)
    assert not searched("held-out", [1.0, rise], decade[:2])
    assert not searched("held-out", [1.0, rise, rise], (2.1e-5, 3e-5, 1e-4))
    assert searched("held-out", [1.0, rise, rise, rise], (2.1e-5, 3e-5, 1e-4, 3e-4))
    assert HELD_OUT_SPAN == pytest.approx(10.0)
    assert not searched("cross-view", [1.0, rise, rise], decade[:3])


def _searched_as_held_out(errors, alphas, count):
    """Whether ``errors`` of the candidates ``alphas`` is what 'held-out' scores on ``count``
    candidates: the search went on past each but the last, and stopped at the last unless all
    were solved."""
    assert 2 <= len(errors) <= count
    for k in range(1, len(errors)):
        assert not searched("held-out", errors[:k], alphas[:k])
    assert len(errors) == count or searched("held-out", errors, alphas)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    rendered = make_object_scene("squares", size=(64, 48), num_samples=8)
    return open_scene(write_rendered_scene(rendered, tmp_path_factory.mktemp("s") / "squares"))


@pytest.mark.parametrize("source", ["gt", "sceneflow"])
def test_each_view_takes_the_grid_solution_it_chose(scene, source):
    chosen = deblur_stereo_frame(
        scene, 1, settings=DeblurSettings(**FAST, motion_source=source, alpha="cross-view")
    )
    for view, frame in chosen.frames.items():
        assert frame.alpha in CROSS_VIEW_ALPHAS
        fixed = deblur_stereo_frame(
            scene, 1, settings=DeblurSettings(**FAST, motion_source=source, alpha=frame.alpha)
        )
        np.testing.assert_array_equal(frame.image, fixed.frames[view].image)


def test_one_view_is_the_stereo_frames_view(scene):
    settings = DeblurSettings(**FAST, motion_source="gt", alpha="cross-view")
    right = deblur_frame(scene, 1, view="right", settings=settings)
    stereo = deblur_stereo_frame(scene, 1, settings=settings)
    assert right.alpha == stereo.frames["right"].alpha
    np.testing.assert_array_equal(right.image, stereo.frames["right"].image)


def test_the_monocular_path_cannot_predict_the_other_view():
    with pytest.raises(InputError, match="needs a disparity"):
        DeblurSettings(motion_source="initial-flow", kernels="displacement", alpha="cross-view")


def test_given_motion_is_refused(scene):
    settings = DeblurSettings(**FAST, motion_source="gt", alpha="cross-view")
    with pytest.raises(InputError, match="motion of both views itself"):
        deblur_frame(scene, 1, settings=settings, motion=object())


def test_the_option_accepts_the_rule():
    assert alpha_option("cross-view") == "cross-view"
    assert DeblurSettings(alpha="cross-view").alpha == "cross-view"
    with pytest.raises(InputError, match="'held-out', 'auto', 'cross-view' or in"):
        DeblurSettings(alpha="crossview")


@pytest.mark.parametrize(
    ("observations", "scored", "unused"),
    [
        ("other-view", "prediction_error", "held_out_error"),
        ("all", "held_out_error", "prediction_error"),  # the neighbouring frames observed
    ],
)
def test_held_out_takes_the_best_predictor_of_auto_and_the_grid_above_it(
    scene, monkeypatch, observations, scored, unused
):
    from stereodeblur.pipeline import frame as frame_module

    source = "sceneflow"  # the true motion's choice: the last test of this file
    errors, held = [], []
    real = getattr(frame_module, scored)

    def recorded(image, other, *, border):
        held.append(other)
        errors.append(real(image, other, border=border))
        return errors[-1]

    def not_called(*args, **kwargs):
        raise AssertionError(f"{unused} is not the score with observations={observations!r}")

    monkeypatch.setattr(frame_module, scored, recorded)
    monkeypatch.setattr(frame_module, unused, not_called)
    settings = DeblurSettings(
        **FAST, motion_source=source, alpha="held-out", observations=observations
    )
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    if observations == "all":  # the other view's and both neighbouring frames' observations
        assert all(len(observed) == 3 for observed in held)
    auto = deblur_stereo_frame(scene, 1, settings=replace(settings, alpha="auto")).frames["left"]
    candidates = [auto.alpha, *(a for a in CROSS_VIEW_ALPHAS if a > auto.alpha)]
    _searched_as_held_out(errors, candidates[: len(errors)], len(candidates))
    assert chosen.alpha == candidates[choose(errors, "held-out", candidates)]
    fixed = replace(settings, alpha=chosen.alpha)
    expected = deblur_stereo_frame(scene, 1, settings=fixed).frames["left"]
    np.testing.assert_array_equal(chosen.image, expected.image)


def test_held_out_is_auto_without_the_other_view(scene):
    monocular = {**FAST, "motion_source": "initial-flow", "kernels": "displacement"}
    held_out = deblur_frame(scene, 1, settings=DeblurSettings(**monocular, alpha="held-out"))
    auto = deblur_frame(scene, 1, settings=DeblurSettings(**monocular, alpha="auto"))
    assert held_out.alpha == auto.alpha
    np.testing.assert_array_equal(held_out.image, auto.image)
    settings = DeblurSettings(**FAST, motion_source="gt", alpha="held-out")
    motion = deblur_frame(scene, 1, settings=settings).motion  # a given motion of one view
    given = deblur_frame(scene, 1, settings=settings, motion=motion)
    plain = deblur_frame(  # a given motion also keeps the single observation
        scene,
        1,
        settings=DeblurSettings(**FAST, motion_source="gt", alpha="auto", observations="single"),
    )
    assert given.alpha == plain.alpha
    np.testing.assert_array_equal(given.image, plain.image)


def test_held_out_chooses_from_the_own_frame_then_adds_the_observations(scene, monkeypatch):
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    observed = {**FAST, "motion_source": "sceneflow", "observations": "other-view"}
    auto = deblur_stereo_frame(scene, 1, settings=DeblurSettings(**observed, alpha="auto"))
    grid = (auto.frames["left"].alpha * 4,)  # one candidate above 'auto'
    monkeypatch.setattr(alpha_module, "CROSS_VIEW_ALPHAS", grid)
    solved = []

    def falling(image, other, *, border):  # the candidate above 'auto' predicts better
        solved.append(image)
        return 1.0 / len(solved)

    monkeypatch.setattr(frame_module, "prediction_error", falling)
    held_out = deblur_stereo_frame(scene, 1, settings=DeblurSettings(**observed, alpha="held-out"))
    assert len(solved) == 4  # two candidates per view, solved from the view's own frame
    for view in ("left", "right"):
        frame = held_out.frames[view]
        assert frame.alpha == grid[0] and frame.observations == ("other-view",)
        fixed = DeblurSettings(**observed, alpha=grid[0])
        expected = deblur_stereo_frame(scene, 1, views=(view,), settings=fixed).frames[view]
        np.testing.assert_array_equal(frame.image, expected.image)
    single = deblur_stereo_frame(
        scene,
        1,
        views=("left",),
        settings=DeblurSettings(
            **FAST, motion_source="sceneflow", alpha=grid[0], observations="single"
        ),
    )
    np.testing.assert_array_equal(solved[1], np.clip(single.frames["left"].image, 0, 1))


def test_cross_view_chooses_as_without_the_observed_other_view(scene):
    observed = {**FAST, "motion_source": "gt", "alpha": "cross-view"}
    both = deblur_stereo_frame(
        scene, 1, settings=DeblurSettings(**observed, observations="other-view")
    )
    own = deblur_stereo_frame(scene, 1, settings=DeblurSettings(**observed, observations="single"))
    for view in ("left", "right"):
        assert both.frames[view].alpha == own.frames[view].alpha
        assert both.frames[view].observations == ("other-view",)


def _scripted_held_out(scene, monkeypatch, factors, errors, paper=None):
    """``'held-out'`` on the left view with the grid at ``factors`` times ``'auto'``'s alpha and
    the prediction errors ``errors`` in turn (and the paper's alpha at grid step ``paper``);
    returns the number of candidates scored, the chosen alpha and the grid."""
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    settings = DeblurSettings(**FAST, motion_source="sceneflow", alpha="held-out")
    auto = deblur_stereo_frame(
        scene, 1, settings=replace(settings, alpha="auto"), views=("left",)
    ).frames["left"]
    grid = tuple(auto.alpha * k for k in factors)
    monkeypatch.setattr(alpha_module, "CROSS_VIEW_ALPHAS", grid)
    if paper is not None:
        monkeypatch.setattr(alpha_module, "PAPER_ALPHA", grid[paper])
    errors, calls = iter(errors), []

    def scripted(image, other, *, border):
        calls.append(1)
        return next(errors)

    monkeypatch.setattr(frame_module, "prediction_error", scripted)
    monkeypatch.setattr(frame_module, "held_out_error", scripted)  # the neighbours observed
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    return len(calls), chosen.alpha, grid


def test_held_out_skips_a_best_predictor_that_a_larger_alpha_fits_better(scene, monkeypatch):
    from stereodeblur.pipeline import frame as frame_module

    monkeypatch.setattr(frame_module, "PAPER_ALPHA", 1.0)  # no solve but the candidates'
    fits = iter([3.0, 1.0, 2.0])  # grid[0] fits the own frame better than the floor
    monkeypatch.setattr(frame_module, "own_error", lambda *a, border: next(fits))
    errors = [1.0, 1.05, 1.0 + 3 * HELD_OUT_STOP]  # the floor predicts best, not tied
    assert errors[1] > (1 + HELD_OUT_TIE) * errors[0]
    calls, alpha, grid = _scripted_held_out(scene, monkeypatch, (2, 4), errors)
    assert calls == 3 and alpha == grid[0] and next(fits, None) is None


def test_held_out_stops_once_the_prediction_error_rises_a_decade_up(scene, monkeypatch):
    errors = [3.0, 2.0, 2.5, 2.5, 1.0, 0.1]  # a later, lower minimum is not searched
    assert 2.5 > (1 + HELD_OUT_STOP) * 2.0
    # the best at 2x; the rise at 4x is within a decade of it, the one at 40x is not
    calls, alpha, grid = _scripted_held_out(scene, monkeypatch, (2, 4, 40, 80, 160), errors)
    assert calls == 4 and alpha == grid[0]


def test_held_out_searches_past_a_bump_to_a_later_minimum(scene, monkeypatch):
    bump = 1.0 + 0.5 * HELD_OUT_STOP
    errors = [1.0, bump, 0.5, 0.5 * (1 + 2 * HELD_OUT_STOP), 0.1]
    calls, alpha, grid = _scripted_held_out(scene, monkeypatch, (2, 4, 40, 80), errors)
    assert calls == 4 and alpha == grid[1]


def _guard_verdicts(monkeypatch, verdicts):
    """Replace the range guard's regions by ``verdicts`` (True: the whole view, False:
    none), one per call, in order; returns the list of calls."""
    from stereodeblur.deconv import intensity_range

    calls = []

    def scripted(image, **kwargs):
        calls.append(1)
        return np.full(image.shape[:2], verdicts[len(calls) - 1])

    monkeypatch.setattr(intensity_range, "unexplained_regions", scripted)
    return calls


@pytest.mark.parametrize("where", ["floor", "paper", "above"])
def test_a_motion_rejected_at_the_floor_or_the_papers_alpha_is_rejected_above_it(
    scene, monkeypatch, where
):
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    # the other view only: the neighbouring frames' weighing solves once more at a fixed alpha
    settings = DeblurSettings(
        **FAST, motion_source="sceneflow", alpha="held-out", observations="other-view"
    )
    auto = deblur_stereo_frame(
        scene, 1, settings=replace(settings, alpha="auto"), views=("left",)
    ).frames["left"]
    grid = (auto.alpha * 2, auto.alpha * 4)
    monkeypatch.setattr(alpha_module, "CROSS_VIEW_ALPHAS", grid)
    errors = iter([3.0, 2.0, 1.0])  # the largest alpha predicts best
    monkeypatch.setattr(frame_module, "prediction_error", lambda *a, border: next(errors))
    if where == "above":  # the floor is above the paper's alpha: one more solve there
        monkeypatch.setattr(frame_module, "PAPER_ALPHA", auto.alpha / 2)
        guard = _guard_verdicts(monkeypatch, [True])
    elif where == "paper":  # the guard rejects the motion at the paper's alpha only
        monkeypatch.setattr(frame_module, "PAPER_ALPHA", grid[0])
        guard = _guard_verdicts(monkeypatch, [False, True])
    else:  # at the floor, below the paper's alpha: no candidate above is guarded again
        monkeypatch.setattr(frame_module, "PAPER_ALPHA", grid[1])
        guard = _guard_verdicts(monkeypatch, [True])
    with pytest.warns(UserWarning, match="range guard"):
        chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",))
    chosen = chosen.frames["left"]
    assert len(guard) == (2 if where == "paper" else 1) and next(errors, None) is None
    assert chosen.alpha == grid[1] and chosen.unexplained.all()
    _guard_verdicts(monkeypatch, [True])  # a fixed alpha, rejected by its own guard
    with pytest.warns(UserWarning, match="range guard"):
        fixed = deblur_stereo_frame(
            scene, 1, settings=replace(settings, alpha=grid[1]), views=("left",)
        ).frames["left"]
    np.testing.assert_array_equal(chosen.image, fixed.image)


def test_held_out_searches_a_flat_error_curve_and_takes_the_alpha_nearest_the_papers(
    scene, monkeypatch
):
    tie, least = 1.0 + 0.5 * HELD_OUT_TIE, 1.0 - 0.2 * HELD_OUT_TIE
    errors = [1.0, tie, least, tie, 2.0]  # within the tie up to the paper's alpha
    calls, alpha, grid = _scripted_held_out(scene, monkeypatch, (2, 4, 8, 16), errors, paper=2)
    assert calls == 5 and alpha == grid[2]


def test_held_out_goes_below_its_floor_while_the_gates_error_falls(scene, monkeypatch):
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    settings = DeblurSettings(**GLOBAL, motion_source="sceneflow", alpha="held-out")
    auto = deblur_stereo_frame(
        scene, 1, settings=replace(settings, alpha="auto"), views=("left",)
    ).frames["left"]
    monkeypatch.setattr(alpha_module, "CROSS_VIEW_ALPHAS", (auto.alpha * 10, auto.alpha * 20))
    below = tuple(auto.alpha / k for k in (2, 4, 8, 16))
    gated = []

    def tried(floor, error, sigma):
        gated.append((floor, error))
        return below

    upwards = iter([1.0, 2.0])  # the floor beats the grid a decade above it
    downwards = iter([0.9, 0.5, 0.25, 0.3])  # the floor's, then down to a rise
    monkeypatch.setattr(frame_module, "below_floor", tried)
    for score in ("prediction_error", "held_out_error"):
        monkeypatch.setattr(frame_module, score, lambda *a, border: next(upwards))
    monkeypatch.setattr(frame_module, "observed_error", lambda *a, border: next(downwards))
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    assert gated == [(auto.alpha, 0.9)]
    assert chosen.alpha == below[1] and next(downwards, None) is None
    fixed = deblur_stereo_frame(
        scene, 1, settings=replace(settings, alpha=below[1]), views=("left",)
    ).frames["left"]
    np.testing.assert_array_equal(chosen.image, fixed.image)


def _floor_best(scene, monkeypatch, below):
    """``'held-out'`` on the left view (settings and ``'auto'``'s alpha returned) with one grid
    alpha above the floor, the floor predicting best, and ``below(auto_alpha)`` the noise
    gate's alphas."""
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    settings = DeblurSettings(**FAST, motion_source="sceneflow", alpha="held-out")
    auto = deblur_stereo_frame(
        scene, 1, settings=replace(settings, alpha="auto"), views=("left",)
    ).frames["left"]
    monkeypatch.setattr(alpha_module, "CROSS_VIEW_ALPHAS", (auto.alpha * 2,))
    monkeypatch.setattr(frame_module, "below_floor", lambda *args: below(auto.alpha))
    upwards = iter([1.0, 2.0])
    for score in ("prediction_error", "held_out_error"):
        monkeypatch.setattr(frame_module, score, lambda *a, border: next(upwards))
    return settings, auto.alpha


def test_held_out_stops_below_its_floor_where_the_own_frame_fits_no_better(scene, monkeypatch):
    from stereodeblur.pipeline import frame as frame_module

    settings, auto = _floor_best(scene, monkeypatch, lambda a: (a / 2, a / 4, a / 8))
    monkeypatch.setattr(frame_module, "PAPER_ALPHA", 1.0)  # no solve but the candidates'
    downwards = iter([0.9, 0.5, 0.25])  # the gate's error falls all the way
    fits = iter([5.0, 6.0, 4.0, 4.5])  # floor, grid, auto / 2 fits better, auto / 4 not
    monkeypatch.setattr(frame_module, "observed_error", lambda *a, border: next(downwards))
    monkeypatch.setattr(frame_module, "own_error", lambda *a, border: next(fits))
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    assert chosen.alpha == auto / 2
    assert next(downwards, None) is None and next(fits, None) is None


def test_held_out_stays_at_its_floor_where_the_gate_is_shut(scene, monkeypatch):
    settings, auto = _floor_best(scene, monkeypatch, lambda a: ())
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    assert chosen.alpha == auto


def test_held_out_with_the_true_motion_scores_the_observation_from_the_noise_rule_up(
    scene, monkeypatch
):
    from stereodeblur.deconv.noise import estimate_noise_sigma
    from stereodeblur.pipeline import frame as frame_module

    errors = []
    real = frame_module.observed_error

    def recorded(image, observation, *, border):
        errors.append(real(image, observation, border=border))
        return errors[-1]

    def unused(*args, **kwargs):
        raise AssertionError("the true motion's choice predicts through the observation")

    monkeypatch.setattr(frame_module, "observed_error", recorded)
    monkeypatch.setattr(frame_module, "prediction_error", unused)
    settings = DeblurSettings(**GLOBAL, motion_source="gt", alpha="held-out")
    chosen = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    auto = deblur_stereo_frame(scene, 1, settings=replace(settings, alpha="auto")).frames["left"]
    noise = alpha_from_sigma(estimate_noise_sigma(chosen.blurred))
    assert noise < auto.alpha  # the trust raised 'auto'; the true motion's choice starts below
    candidates = [noise, *(a for a in CROSS_VIEW_ALPHAS if a > noise)]
    _searched_as_held_out(errors, candidates[: len(errors)], len(candidates))
    assert chosen.alpha == candidates[choose(errors, "held-out", candidates)]
    fixed = deblur_stereo_frame(scene, 1, settings=replace(settings, alpha=chosen.alpha))
    np.testing.assert_array_equal(chosen.image, fixed.frames["left"].image)


def test_the_local_error_is_the_observations_error_around_each_pixel():
    image = _texture((40, 60))
    seen = np.ones((40, 60), np.float32)
    off = image + 0.1
    off[:4] += 1.0  # within the border: not counted
    flat = local_error(image, [Observation(_Identity(), off, seen)], window=3.0, border=4)
    np.testing.assert_allclose(flat[4:-4, 4:-4], 0.01, rtol=1e-9)  # the window's mean
    twice = local_error(image, [Observation(_Identity(), off, seen)] * 2, window=3.0, border=4)
    np.testing.assert_allclose(twice[4:-4, 4:-4], 0.02, rtol=1e-9)  # summed over them
    assert np.isnan(flat[0, 0])  # a corner's window counts too few pixels
    wrong = image.copy()
    wrong[:, 30:] += 0.1  # the right half predicted 0.1 off
    halves = local_error(image, [Observation(_Identity(), wrong, seen)], window=3.0, border=4)
    inside = halves[4:-4]
    assert np.all(inside[:, 4:16] < 1e-9) and np.all(np.abs(inside[:, 44:-4] - 0.01) < 1e-9)
    unseen = seen.copy()
    unseen[:, 30:] = 0.4 * HELD_OUT_MIN_WEIGHT / 0.5  # below the least weight: not counted
    hidden = local_error(image, [Observation(_Identity(), wrong, unseen)], window=3.0, border=4)
    assert np.all(hidden[4:-4, 4:30] < 1e-9)
    assert np.all(np.isnan(hidden[:, 45:]))  # too few counted pixels in the window
    assert np.all(hidden[4:-4, 30:33] < 1e-9)  # counted from the left half within the window


def test_the_local_scale_takes_the_best_candidate_around_each_pixel():
    alphas = (1e-4, 1e-3)
    small = np.zeros((40, 80))
    small[:, 40:] = 2.0  # the small alpha predicts the left half best, the large the right
    large = np.ones((40, 80))
    scale = local_scale(alphas, [small, large], 1e-3, window=2.0)
    assert scale.dtype == np.float32 and scale.shape == (40, 80)
    np.testing.assert_allclose(scale[:, :30], 0.1, rtol=1e-5)
    np.testing.assert_allclose(scale[:, 50:], 1.0, rtol=1e-5)
    assert np.all(np.diff(scale[:, 30:50], axis=1) >= 0)  # smoothed in log alpha between
    unscored = small.copy()
    unscored[:, :40] = np.nan  # no observation around these pixels: the chosen alpha
    scale = local_scale(alphas, [unscored, large], 1e-4, window=2.0)
    np.testing.assert_allclose(scale[:, :30], 1.0, rtol=1e-5)
    np.testing.assert_allclose(scale[:, 50:], 10.0, rtol=1e-5)


@dataclass(frozen=True)
class _Terms:
    alpha: float
    weights: np.ndarray
    alpha_scale: np.ndarray | None = None


def test_the_local_alpha_goes_below_the_chosen_one_only_where_the_motion_explains():
    sigma = LOCAL_ALPHA_NOISE  # a noisy frame: down to LOCAL_ALPHA_DOWN times less
    observed = _texture((40, 200))
    seen = np.ones(observed.shape, np.float32)
    terms = _Terms(1e-3, seen)
    explained = np.sqrt(HELD_OUT_NOISE_RATIO * 2.0 * sigma**2)  # the gate's error, per pixel
    chosen = observed + np.where(np.arange(200) < 100, 1.5, 0.5) * explained  # left: not
    runs = [
        SimpleNamespace(terms=terms, image=chosen),
        SimpleNamespace(terms=replace(terms, alpha=1e-4), image=observed),  # best everywhere
    ]

    def unused(alpha):
        raise AssertionError(f"no grid alpha is missing, got {alpha}")

    scorers = [Observation(_Identity(), observed, seen)] * 2  # the gate per observation
    scale = local_terms(terms, runs, unused, scorers, sigma, border=4).alpha_scale
    np.testing.assert_allclose(scale[4:-4, 4:30], 1.0, rtol=0.02)  # kept: the motion fails
    np.testing.assert_allclose(scale[4:-4, 170:-4], 0.1, rtol=0.02)  # explained: below
    quiet = local_terms(terms, runs, unused, scorers, 0.5 * sigma, border=4).alpha_scale
    np.testing.assert_allclose(quiet, 1.0, rtol=1e-6)  # a quiet frame never goes below


def test_local_alpha_acts_with_held_out_and_a_motion_that_predicts_the_other_view():
    assert local_alpha_acts(DeblurSettings())
    assert local_alpha_acts(DeblurSettings(local_alpha="always", motion_source="gt"))
    assert not local_alpha_acts(DeblurSettings(local_alpha="off"))
    assert not local_alpha_acts(DeblurSettings(alpha=1e-3))
    assert not local_alpha_acts(DeblurSettings(alpha="cross-view"))
    monocular = DeblurSettings(motion_source="initial-flow", kernels="displacement")
    assert not local_alpha_acts(monocular)
    for wrong in (True, 1, "on"):
        with pytest.raises(InputError, match="local_alpha must be one of off, noisy, always"):
            DeblurSettings(local_alpha=wrong)


def test_local_alpha_noisy_acts_from_the_noise_threshold_up():
    noisy, always = DeblurSettings(), DeblurSettings(local_alpha="always")
    assert DeblurSettings().local_alpha == "noisy"
    assert not local_alpha_here(noisy, LOCAL_ALPHA_NOISE * 0.99)
    assert local_alpha_here(noisy, LOCAL_ALPHA_NOISE)
    assert local_alpha_here(always, 0.0)
    assert not local_alpha_here(DeblurSettings(local_alpha="off"), 1.0)
    assert not local_alpha_here(DeblurSettings(alpha=1e-3), 1.0)


@pytest.mark.parametrize("noisy", [False, True])
def test_local_alpha_noisy_is_always_on_noisy_frames_and_off_on_quiet_ones(
    scene, monkeypatch, noisy
):
    from stereodeblur.pipeline import alpha as alpha_module

    monkeypatch.setattr(alpha_module, "LOCAL_ALPHA_NOISE", 0.0 if noisy else np.inf)
    frames = {
        mode: deblur_stereo_frame(
            scene, 1, settings=DeblurSettings(**FAST, local_alpha=mode), views=("left",)
        ).frames["left"]
        for mode in ("noisy", "always" if noisy else "off")
    }
    same = frames["always" if noisy else "off"]
    assert (frames["noisy"].alpha_scale is None) == (not noisy)
    np.testing.assert_array_equal(frames["noisy"].image, same.image)


@pytest.mark.parametrize("source", ["gt", "sceneflow"])
@pytest.mark.parametrize("noisy", [False, True])
def test_local_alpha_solves_the_chosen_alpha_with_the_map_of_its_candidates(
    scene, monkeypatch, source, noisy
):
    from stereodeblur.pipeline import alpha as alpha_module
    from stereodeblur.pipeline import frame as frame_module

    settings = DeblurSettings(**GLOBAL, motion_source=source, alpha="held-out")
    single = deblur_stereo_frame(scene, 1, settings=settings, views=("left",)).frames["left"]
    monkeypatch.setattr(alpha_module, "LOCAL_ALPHA_NOISE", 0.0 if noisy else np.inf)
    mapped, solves = [], []
    scale = np.linspace(0.5, 2.0, 64 * 48, dtype=np.float32).reshape(48, 64)

    def recorded_scale(alphas, errors, chosen, *, window):
        mapped.append((list(alphas), chosen))
        assert len(errors) == len(alphas) and window == LOCAL_ALPHA_WINDOW * 64
        return scale

    guarded = frame_module.guarded_solve

    def recorded_solve(blurred, operator, terms, *args):
        solves.append(terms)
        return guarded(blurred, operator, terms, *args)

    monkeypatch.setattr(alpha_module, "local_scale", recorded_scale)
    monkeypatch.setattr(frame_module, "guarded_solve", recorded_solve)
    local = replace(settings, local_alpha="always")
    frame = deblur_stereo_frame(scene, 1, settings=local, views=("left",)).frames["left"]
    assert frame.alpha == single.alpha and single.alpha_scale is None  # the same choice
    ((alphas, chosen),) = mapped
    assert chosen == single.alpha and single.alpha in alphas
    solved = {t.alpha for t in solves[:-1]}
    least = (single.alpha / LOCAL_ALPHA_DOWN if noisy else single.alpha) * (1 - 1e-9)
    assert set(alphas) == {a for a in solved if a >= least}  # every candidate in range
    below = {a for a in CROSS_VIEW_ALPHAS if least <= a < single.alpha}
    assert below <= set(alphas)  # the grid down to the least is solved for the map
    assert solves[-1].alpha == single.alpha and solves[-1].alpha_scale is scale
    assert frame.alpha_scale is scale
    assert not np.array_equal(frame.image, single.image)
