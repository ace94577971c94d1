import itertools

import numpy as np
import pytest

from stereodeblur.sceneflow.fusion import alpha_expansion, energy


def _chain_problem(num_nodes, num_labels, seed):
    """Random unary costs, Potts-like truncated-L1 metric on label values, on a chain + chords."""
    rng = np.random.default_rng(seed)
    D = rng.uniform(0, 10, (num_nodes, num_labels))
    edges = [(i, i + 1) for i in range(num_nodes - 1)] + [(0, num_nodes - 1), (1, 4)]
    edges = np.array(sorted({tuple(sorted(e)) for e in edges}), dtype=np.int64)
    values = rng.uniform(0, 5, num_labels)  # each label's "position"
    weights = rng.uniform(0.5, 3, len(edges))
    metric = np.minimum(np.abs(values[:, None] - values[None, :]), 2.0)
    V = weights[:, None, None] * metric[None]
    candidates = np.tile(np.arange(num_labels), (num_nodes, 1))
    return D, V, edges, candidates


def _brute_force(D, V, edges):
    best = np.inf
    for labelling in itertools.product(range(D.shape[1]), repeat=D.shape[0]):
        best = min(best, energy(D, V, edges, np.array(labelling)))
    return best


def test_two_labels_give_the_global_optimum():
    for seed in range(5):
        D, V, edges, cands = _chain_problem(8, 2, seed)
        result = alpha_expansion(D, V, edges, cands, np.zeros(8, dtype=np.int64), seed=seed)
        assert result.energy == pytest.approx(_brute_force(D, V, edges))


def test_multi_label_result_is_within_the_expansion_bound_and_a_local_minimum():
    for seed in range(3):
        D, V, edges, cands = _chain_problem(7, 3, seed)
        init = np.zeros(7, dtype=np.int64)
        result = alpha_expansion(D, V, edges, cands, init, seed=seed)
        assert all(
            a >= b - 1e-9 for a, b in zip(result.history[:-1], result.history[1:], strict=True)
        )
        assert result.energy == pytest.approx(energy(D, V, edges, result.choice))
        optimum = _brute_force(D, V, edges)
        metric = V / np.maximum(V.max(axis=(1, 2), keepdims=True), 1e-12)
        positive = metric[metric > 0]
        bound = 2 * metric.max() / positive.min()
        assert optimum - 1e-9 <= result.energy <= bound * optimum + 1e-9
        # No single expansion move improves the result.
        for alpha in range(3):
            for subset in itertools.product([0, 1], repeat=7):
                trial = np.where(np.array(subset) == 1, alpha, result.choice)
                assert energy(D, V, edges, trial) >= result.energy - 1e-9


def test_labels_outside_a_segments_candidates_are_never_chosen():
    D, V, edges, cands = _chain_problem(6, 3, 0)
    cands = cands.copy()
    cands[2] = [0, -1, -1]  # segment 2 may only take label 0
    D = np.where(cands >= 0, D, np.inf)
    D[2, 0] = 100.0  # expensive, but the only option
    result = alpha_expansion(D, V, edges, cands, np.zeros(6, dtype=np.int64))
    assert result.choice[2] == 0
    assert np.all(cands[np.arange(6), result.choice] >= 0)


def test_init_on_an_empty_slot_is_rejected():
    D, V, edges, cands = _chain_problem(4, 2, 0)
    cands = cands.copy()
    cands[1, 1] = -1
    with pytest.raises(ValueError, match="init"):
        alpha_expansion(D, V, edges, cands, np.array([0, 1, 0, 0]))


def _one_segment_graph(shape):
    from stereodeblur.sceneflow.superpixels import segment_graph

    return segment_graph(np.zeros(shape, dtype=np.int32))


def _noisy_static_and_far():
    """Flat grey plus independent noise in every view (40 x 56), one segment, and two
    proposals: static, and far to the side (every pixel carried 45-100 px out of the view).
    Returns the camera, codes, graph, samples and proposals."""
    from stereodeblur.geometry import StereoCamera
    from stereodeblur.sceneflow.census import census_transform
    from stereodeblur.sceneflow.data_term import sample_pixels
    from stereodeblur.sceneflow.fusion import ProposalSet

    shape = (40, 56)
    rng = np.random.default_rng(3)
    codes = tuple(
        census_transform(np.clip(0.3 + 0.02 * rng.standard_normal(shape), 0, 1)) for _ in range(4)
    )
    camera = StereoCamera([[50.0, 0, 27.5], [0, 50.0, 19.5], [0, 0, 1]], 0.1)
    graph = _one_segment_graph(shape)
    R = np.tile(np.eye(3), (2, 1, 1))
    T = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    props = ProposalSet(np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 2.0]]), R, T)
    return camera, codes, graph, sample_pixels(graph, 1), props


def test_leaving_the_view_is_not_cheaper_than_matching_noise():
    # Every match costs as much as a wrong one, so a motion that carries all pixels out of
    # the image must not win.
    from stereodeblur.sceneflow.data_term import data_costs

    camera, codes, graph, samples, props = _noisy_static_and_far()
    D = data_costs(camera, codes, *samples, np.array([[0, 1]]), props)
    stay, leave = D[0]
    assert stay > 0.3 * 3 * graph.sizes[0]  # noise: matches are poor
    assert leave >= 0.9 * stay


def test_leaving_the_view_is_free_in_a_clean_flat_region():
    from stereodeblur.geometry import StereoCamera
    from stereodeblur.sceneflow.census import census_transform
    from stereodeblur.sceneflow.data_term import data_costs, sample_pixels
    from stereodeblur.sceneflow.fusion import ProposalSet

    shape = (40, 56)
    codes = tuple(census_transform(np.full(shape, 0.4)) for _ in range(4))
    camera = StereoCamera([[50.0, 0, 27.5], [0, 50.0, 19.5], [0, 0, 1]], 0.1)
    graph = _one_segment_graph(shape)
    samples, bounds, factor = sample_pixels(graph, 1)
    R = np.tile(np.eye(3), (2, 1, 1))
    T = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    props = ProposalSet(np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 2.0]]), R, T)
    D = data_costs(camera, codes, samples, bounds, factor, np.array([[0, 1]]), props)
    assert D[0, 0] == pytest.approx(0.0) and D[0, 1] == pytest.approx(0.0)


def test_a_dominant_motion_leaves_the_view_at_the_near_cost_within_its_reach():
    from stereodeblur.sceneflow.census import wrong_match_cost
    from stereodeblur.sceneflow.data_term import data_costs

    camera, codes, graph, samples, props = _noisy_static_and_far()
    candidates = np.array([[0, 1]])
    today = data_costs(camera, codes, *samples, candidates, props)
    near = np.full(graph.labels.shape, 0.05)

    def costs(dominant, reach):
        flags = np.array(dominant)
        return data_costs(
            camera, codes, *samples, candidates, props, dominant=flags, leave_near=near, reach=reach
        )

    np.testing.assert_array_equal(costs([False, False], 200.0), today)
    np.testing.assert_array_equal(costs([False, True], 40.0), today)  # all beyond its reach
    stay, leave = costs([True, True], 200.0)[0]
    assert stay <= today[0, 0]  # only its samples at the left edge leave the right view
    # Both views at t + 1 of every sample: the near cost instead of a wrong match's.
    assert leave == pytest.approx(today[0, 1] - 2 * (wrong_match_cost(codes[0]) - 0.05).sum())
    assert leave < 0.5 * today[0, 1]


def test_the_cost_of_leaving_near_is_the_local_mean_of_the_initial_matches():
    from stereodeblur.sceneflow.census import (
        census_transform,
        leave_costs_near,
        wrong_match_cost,
    )

    rng = np.random.default_rng(0)
    image = rng.random((30, 40))
    lt, lt1 = census_transform(image), census_transform(np.roll(image, 2, axis=1))
    y, x = (a.ravel() for a in np.mgrid[0:30, 0:40])
    x1, y1 = (x + 2).astype(float), y.astype(float)  # the true shift: perfect matches
    near = leave_costs_near(lt, lt1, x, y, x1, y1, 4.0)
    assert near.shape == (30, 40)
    assert np.all(near <= wrong_match_cost(lt) + 1e-12)
    assert near[5:25, 5:30].max() < 0.05 < wrong_match_cost(lt)[5:25, 5:30].min()
    x1[:] = np.nan  # no initial match anywhere: a wrong match's cost
    np.testing.assert_array_equal(
        leave_costs_near(lt, lt1, x, y, x1, y1, 4.0), wrong_match_cost(lt)
    )


def _sliding_texture(shift=8, disparity=2, shape=(32, 48)):
    """Random texture sliding ``shift`` px to the right per frame at a constant disparity:
    census codes of left and right at t, t + 1 and t - 1, the camera and two proposals
    (the true motion, and no motion)."""
    from stereodeblur.geometry import StereoCamera
    from stereodeblur.sceneflow.census import census_transform
    from stereodeblur.sceneflow.fusion import ProposalSet

    height, width = shape
    rng = np.random.default_rng(5)
    texture = rng.uniform(0.1, 0.9, (height, width + 2 * shift + disparity))

    def view(frame, right):  # frame 0: t, 1: t + 1, -1: t - 1
        start = shift - frame * shift + (disparity if right else 0)
        return census_transform(texture[:, start : start + width])

    codes = {f: (view(f, False), view(f, True)) for f in (0, 1, -1)}
    camera = StereoCamera([[50.0, 0, 23.5], [0, 50.0, 15.5], [0, 0, 1]], 0.1)
    # d0 = 2 px: inverse depth w = 2 / (50 * 0.1) = 0.4; T_x = 0.4 moves a point 50 T_x w = 8 px.
    T = np.array([[shift / (50.0 * disparity / 5.0), 0.0, 0.0], [0.0, 0.0, 0.0]])
    props = ProposalSet(
        np.tile([0.0, 0.0, float(disparity)], (2, 1)), np.tile(np.eye(3), (2, 1, 1)), T
    )
    return camera, codes, props


def test_what_leaves_the_view_at_t1_is_matched_on_the_other_side():
    from stereodeblur.sceneflow.census import wrong_match_cost
    from stereodeblur.sceneflow.data_term import data_costs, sample_pixels

    camera, codes, props = _sliding_texture()
    graph = _one_segment_graph(codes[0][0].shape)
    samples = sample_pixels(graph, 1)
    four = (*codes[0], *codes[1])
    candidates = np.array([[0, 1]])
    today = data_costs(camera, four, *samples, candidates, props)
    other = data_costs(camera, four, *samples, candidates, props, other_side=codes[-1])
    # No motion: nothing leaves the view, nothing changes.
    assert other[0, 1] == today[0, 1]
    # The true motion carries the last 8 columns out of both views at t + 1; at t - 1 they
    # are in view and match, instead of costing a wrong match each (but for the 3 columns
    # whose census the image border replicates).
    leaving = wrong_match_cost(codes[0][0])[:, -8:].sum()
    assert today[0, 0] - other[0, 0] > 0.6 * 2 * leaving
    assert other[0, 0] < 0.4 * today[0, 0] and other[0, 0] < 0.1 * other[0, 1]
