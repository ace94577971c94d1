"""The kernels that run in ranges of whole segments give the same result for any ranges."""

import numpy as np

from stereodeblur.geometry import StereoCamera, se3_exp
from stereodeblur.geometry.plane import disparity_coefficients
from stereodeblur.sceneflow import data_term, refine
from stereodeblur.sceneflow.census import census_transform
from stereodeblur.sceneflow.data_term import data_costs, sample_pixels
from stereodeblur.sceneflow.fusion import ProposalSet
from stereodeblur.sceneflow.superpixels import segment_graph

from .scenes import CAMERA, SIZE, frames, render_views

NORMAL = np.array([0.1, -0.06, 0.5])
TWIST = np.array([0.05, -0.03, -0.08, 0.01, 0.015, -0.01])


def _grid(shape, rows, cols):
    y = np.arange(shape[0]) * rows // shape[0]
    x = np.arange(shape[1]) * cols // shape[1]
    return (y[:, None] * cols + x[None, :]).astype(np.int64)


def _proposals(num, seed):
    """Perturbations of the true plane and motion."""
    rng = np.random.default_rng(seed)
    M = se3_exp(TWIST)
    abc = disparity_coefficients(CAMERA, NORMAL) + rng.normal(0, [0.003, 0.003, 0.3], (num, 3))
    R = np.stack([se3_exp(rng.normal(0, 0.002, 6))[:3, :3] @ M[:3, :3] for _ in range(num)])
    T = M[:3, 3] + rng.normal(0, 0.004, (num, 3))
    return ProposalSet(abc, R, T)


def test_refinement_does_not_depend_on_the_ranges(monkeypatch):
    images = list(frames(render_views(NORMAL, TWIST, num_instants=5)))
    groups = _grid(SIZE, 3, 4)
    groups[groups == 5] = 2  # a group of two parts, and a group with no pixels
    start = _proposals(12, 0)
    monkeypatch.setattr(refine, "_MIN_PIXELS", 10**9)
    whole = refine.refine_proposals(CAMERA, images, groups, start, num_iterations=3)
    monkeypatch.setattr(refine, "_MIN_PIXELS", 1)
    split = refine.refine_proposals(CAMERA, images, groups, start, num_iterations=3)
    for name in ("abc", "R", "T"):
        np.testing.assert_array_equal(getattr(split, name), getattr(whole, name))
    assert not np.array_equal(whole.abc, start.abc)


def test_data_costs_do_not_depend_on_the_ranges(monkeypatch):
    shape = (40, 56)
    rng = np.random.default_rng(3)
    base = rng.random(shape)
    codes = tuple(
        census_transform(np.clip(np.roll(base, k, axis=1) + 0.02 * rng.random(shape), 0, 1))
        for k in range(4)
    )
    camera = StereoCamera([[50.0, 0, 27.5], [0, 50.0, 19.5], [0, 0, 1]], 0.1)
    graph = segment_graph(_grid(shape, 4, 5).astype(np.int32))
    samples, bounds, factor = sample_pixels(graph, 1)
    num = 6
    props = ProposalSet(
        np.column_stack([rng.normal(0, 0.01, (num, 2)), rng.uniform(0.5, 3.0, num)]),
        np.tile(np.eye(3), (num, 1, 1)),
        rng.normal(0, 0.05, (num, 3)),
    )
    candidates = rng.integers(-1, num, (graph.num_segments, 4))
    args = (camera, codes, samples, bounds, factor, candidates, props)
    monkeypatch.setattr(data_term, "_MIN_WORK", 10**12)
    whole = data_costs(*args)
    monkeypatch.setattr(data_term, "_MIN_WORK", 1)
    np.testing.assert_array_equal(data_costs(*args), whole)
    assert np.all(np.isinf(whole[candidates < 0])) and np.all(np.isfinite(whole[candidates >= 0]))
