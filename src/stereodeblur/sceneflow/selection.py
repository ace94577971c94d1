"""Stage 5 of the estimator: every segment chooses a proposal, then regions are refitted.

Each segment picks its own, a neighbour's or a global proposal by the 4-view census
cost plus a truncated smoothness term (weaker across contrast edges), by
alpha-expansion over the segment adjacency graph (:mod:`fusion`). Regions of
segments that picked the same proposal are then refitted as one and offered again
to their neighbours (``settings.num_region_rounds`` times).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components

from ..geometry.camera import StereoCamera
from .candidates import FitPixels, SegmentProposals, candidate_table
from .census import leave_costs_near
from .data_term import data_costs, sample_pixels
from .fusion import ProposalSet, alpha_expansion, pairwise_tables
from .motions import fit_motions
from .planes import fit_planes
from .settings import SceneFlowSettings
from .superpixels import SegmentGraph

__all__ = ["Selection", "edge_weights", "select_proposals"]


@dataclass(frozen=True)
class Selection:
    """The proposals (the segments' and the regions') and the one each segment chose."""

    proposals: ProposalSet
    chosen: np.ndarray


def select_proposals(
    camera: StereoCamera,
    codes: tuple[np.ndarray, ...],
    gray: np.ndarray,
    graph: SegmentGraph,
    pixels: FitPixels,
    start: SegmentProposals,
    settings: SceneFlowSettings,
    *,
    seed: int,
    rng: np.random.Generator,
    after_round: Callable[[int], None] | None = None,
    other_side: tuple[np.ndarray, np.ndarray] | None = None,
) -> Selection:
    """Fuse the proposals, then refit and fuse again region by region.

    ``gray`` is the left frame at t (for the contrast edges); ``after_round(k)`` is
    called after fusion round k (0: the first fusion, then one per region round);
    ``other_side``: the census codes of left and right on the other side of t
    (:func:`~.data_term.data_costs`).
    """
    samples = sample_pixels(graph, pixels.step)
    weights = edge_weights(graph, gray, settings)
    near, reach = _dominant_leaving(codes, pixels, settings)

    def fuse(cands, props, init, seed_offset, dominant_ids):
        dominant = None if near is None else np.isin(np.arange(len(props)), dominant_ids)
        D = data_costs(
            camera,
            codes,
            *samples,
            cands,
            props,
            outside_cost=settings.outside_cost,
            dominant=dominant,
            leave_near=near,
            reach=reach,
            other_side=other_side,
        )
        V = pairwise_tables(
            camera,
            graph,
            cands,
            props,
            smoothness=settings.smoothness,
            truncation=settings.truncation,
            edge_weights=weights,
        )
        result = alpha_expansion(
            D, V, graph.edges, cands, init, num_sweeps=settings.num_sweeps, seed=seed + seed_offset
        )
        return cands[np.arange(graph.num_segments), result.choice]

    L = graph.num_segments
    props = start.proposals
    chosen = fuse(start.candidates, props, np.zeros(L, dtype=np.int64), 0, start.global_ids)
    if after_round is not None:
        after_round(0)
    for round_index in range(settings.num_region_rounds):
        region_props, region = _region_proposals(
            camera, graph, pixels, props, chosen, settings, rng
        )
        offset = len(props)
        props = props.concat(region_props)
        big = _largest_regions(graph, region, settings)
        candidates = _region_candidates(graph, start, chosen, region, offset, offset + big)
        init = np.argmax(candidates == chosen[:, None], axis=1)
        dominant_ids = np.concatenate([offset + big, start.global_ids])
        chosen = fuse(candidates, props, init, 1 + round_index, dominant_ids)
        if after_round is not None:
            after_round(1 + round_index)
    return Selection(props, chosen)


def edge_weights(graph: SegmentGraph, gray: np.ndarray, settings: SceneFlowSettings) -> np.ndarray:
    """Smoothness weight per edge: 1 between similar segments, down to ``edge_floor``
    across a contrast edge (difference of the segments' mean grey values, scale
    ``edge_contrast``)."""
    floor, contrast = settings.edge_floor, settings.edge_contrast
    flat = graph.labels.ravel()
    mean = np.bincount(flat, gray.ravel(), graph.num_segments) / np.maximum(graph.sizes, 1)
    diff = mean[graph.edges[:, 0]] - mean[graph.edges[:, 1]]
    return floor + (1 - floor) * np.exp(-((diff / contrast) ** 2))


def _regions(graph: SegmentGraph, proposal_of_segment: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of segments that chose the same proposal."""
    import scipy.sparse as sp

    e = graph.edges
    same = proposal_of_segment[e[:, 0]] == proposal_of_segment[e[:, 1]]
    n = graph.num_segments
    A = sp.csr_matrix((np.ones(same.sum()), (e[same, 0], e[same, 1])), shape=(n, n))
    return connected_components(A, directed=False)


def _region_proposals(camera, graph, pixels, props, chosen, settings, rng):
    """One plane and motion per region, refitted on all its pixels from the proposal its
    segments chose (kept where the refit fails); the region of every segment."""
    p = pixels
    L = graph.num_segments
    num_regions, region = _regions(graph, chosen)
    representative = np.empty(num_regions, dtype=np.int64)
    representative[region] = np.arange(L)
    base = chosen[representative]
    has_d = p.has_disparity
    rseg = region[p.segment]
    rabc, rok = fit_planes(
        rseg[has_d],
        num_regions,
        p.x[has_d],
        p.y[has_d],
        p.disparity[has_d],
        rng=rng,
        num_hypotheses=settings.plane_hypotheses,
        inlier_threshold=settings.plane_threshold,
    )
    rabc = np.where(rok[:, None], rabc, props.abc[base])
    rd0 = rabc[rseg, 0] * p.x + rabc[rseg, 1] * p.y + rabc[rseg, 2]
    good = rd0 > 0
    Rr, Tr, mok = fit_motions(
        camera,
        rseg[good],
        num_regions,
        p.x[good],
        p.y[good],
        rd0[good],
        p.x1[good],
        p.y1[good],
        rd0[good] + p.change[good],
        init=(props.R[base], props.T[base]),
        scales=(1.0, 0.5),
        iterations_per_scale=2,
        cutoff=3.0,
    )
    Rr = np.where(mok[:, None, None], Rr, props.R[base])
    Tr = np.where(mok[:, None], Tr, props.T[base])
    return ProposalSet(rabc, Rr, Tr), region


def _largest_regions(graph, region, settings) -> np.ndarray:
    """The regions offered to every segment: the ``max_regions`` largest of at least
    ``min_region_fraction`` of the image."""
    height, width = graph.labels.shape
    num_regions = int(region.max()) + 1
    area = np.bincount(region, graph.sizes, num_regions)
    big = np.argsort(-area)[: settings.max_regions]
    return big[area[big] >= settings.min_region_fraction * height * width]


def _dominant_leaving(codes, pixels: FitPixels, settings: SceneFlowSettings):
    """``(leave_near, reach)`` for :func:`~.data_term.data_costs` (the dominant motions' cost of
    leaving the view and how far); ``(None, 0.0)`` if ``settings.dominant_leave_window`` is 0."""
    if settings.dominant_leave_window <= 0:
        return None, 0.0
    lt, _, lt1, _ = codes
    p = pixels
    near = leave_costs_near(lt, lt1, p.ix, p.iy, p.x1, p.y1, settings.dominant_leave_window)
    length = np.hypot(p.x1 - p.x, p.y1 - p.y)
    length = length[np.isfinite(length)]
    reach = settings.dominant_leave_reach * (np.percentile(length, 95) if length.size else 0.0)
    return near, float(reach)


def _region_candidates(graph, start, chosen, region, offset, big):
    """Each segment's candidates in a region round: its choice, its own and its
    neighbours' regions (``offset`` plus the region), its own two proposals, the largest
    regions ``big`` (proposal indices) and the global ones."""
    lists = []
    for s in range(graph.num_segments):
        near = np.concatenate([[s], start.neighbours[s]])
        lists.append(
            np.unique(
                np.concatenate(
                    [
                        [chosen[s]],
                        offset + region[near],
                        2 * s + np.arange(2),
                        big,
                        start.global_ids,
                    ]
                )
            )
        )
    return candidate_table(lists)
