"""Stage 4 of the estimator: the proposals every segment may choose from.

Per segment a robust plane fitted to the initial disparities and a robust rigid
motion fitted to the initial correspondences (:mod:`planes`, :mod:`motions`); the
dominant motion (the camera's own motion) with every segment's plane; and global
proposals (:func:`proposals.global_proposals`). Each segment's candidates are its
own and its neighbours' proposals and the global ones. Conventions as in
:mod:`prediction`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import StereoCamera
from .fusion import ProposalSet
from .initial import InitialMatches
from .motions import fit_motions
from .planes import fit_planes
from .prediction import correspondences
from .proposals import dominant_motion, global_proposals
from .settings import SceneFlowSettings
from .superpixels import SegmentGraph

__all__ = [
    "FitPixels",
    "SegmentProposals",
    "candidate_table",
    "fit_pixels",
    "keep_in_front",
    "neighbour_lists",
    "segment_proposals",
]


@dataclass(frozen=True)
class FitPixels:
    """The pixels the fits and data costs use, with their initial correspondences.

    Pixels on a ``step`` grid (2 from ``settings.grid_from_pixels`` pixels on, else 1),
    plus every pixel of segments the grid misses. ``ix, iy`` integer positions;
    ``x, y`` the same as float64; ``segment`` their segments; ``disparity`` the
    observed disparity at t and ``has_disparity`` where it is known; ``x1, y1`` the
    observed position at t + 1 and ``change`` the observed disparity change from t to
    t + 1 (NaN where unknown).
    """

    step: int
    ix: np.ndarray
    iy: np.ndarray
    x: np.ndarray
    y: np.ndarray
    segment: np.ndarray
    disparity: np.ndarray
    has_disparity: np.ndarray
    x1: np.ndarray
    y1: np.ndarray
    change: np.ndarray


def fit_pixels(
    camera: StereoCamera,
    graph: SegmentGraph,
    matches: InitialMatches,
    settings: SceneFlowSettings,
) -> FitPixels:
    """The pixels fits use and what the initial matches say about them."""
    height, width = graph.labels.shape
    step = 2 if height * width >= settings.grid_from_pixels else 1
    yy, xx = np.mgrid[0:height, 0:width]
    flat = graph.labels.ravel()
    grid = ((xx % step == 0) & (yy % step == 0)).ravel()
    grid |= np.bincount(flat[grid], minlength=graph.num_segments)[flat] == 0
    pick = np.flatnonzero(grid)
    ix, iy = xx.ravel()[pick], yy.ravel()[pick]
    d_obs = matches.disparity.ravel()[pick].astype(np.float64)
    x1, y1, d1 = correspondences(camera, matches.flow, matches.disparity_next, ix, iy)
    return FitPixels(
        step=step,
        ix=ix,
        iy=iy,
        x=ix.astype(np.float64),
        y=iy.astype(np.float64),
        segment=flat[pick].astype(np.int64),
        disparity=d_obs,
        has_disparity=np.isfinite(d_obs),
        x1=x1,
        y1=y1,
        change=d1 - d_obs,
    )


@dataclass(frozen=True)
class SegmentProposals:
    """The proposals and each segment's candidates among them.

    Proposal ``2 s`` is segment s's own plane and motion, ``2 s + 1`` its plane with
    the dominant motion; then the global proposals (``global_ids``). ``candidates``
    (L, C) lists each segment's candidates, -1 padded; ``neighbours`` each segment's
    neighbours, longest shared border first. ``dominant_inliers`` is the share of the
    pixels the dominant motion explains.
    """

    proposals: ProposalSet
    candidates: np.ndarray
    neighbours: tuple[np.ndarray, ...]
    global_ids: np.ndarray
    dominant_inliers: float
    messages: tuple[str, ...] = ()


def segment_proposals(
    camera: StereoCamera,
    graph: SegmentGraph,
    pixels: FitPixels,
    settings: SceneFlowSettings,
    rng: np.random.Generator,
) -> SegmentProposals:
    """Per-segment, dominant and global proposals and the candidate lists."""
    abc, plane_ok, messages = _segment_planes(graph, pixels, settings, rng)
    p = pixels
    L = graph.num_segments
    d0 = abc[p.segment, 0] * p.x + abc[p.segment, 1] * p.y + abc[p.segment, 2]
    R_seg, T_seg, motion_ok = fit_motions(
        camera, p.segment, L, p.x, p.y, d0, p.x1, p.y1, d0 + p.change
    )
    R_dom, T_dom, dom_fraction = dominant_motion(
        camera,
        abc[p.segment],
        R_seg,
        T_seg,
        np.flatnonzero(motion_ok),
        p.x,
        p.y,
        p.x1,
        p.y1,
        p.change,
        rng=rng,
        num_hypotheses=settings.dominant_hypotheses,
        num_samples=settings.dominant_samples,
    )
    R_seg[~motion_ok] = R_dom
    T_seg[~motion_ok] = T_dom
    inside = np.isfinite(p.x1)
    if inside.mean() < 0.05:
        messages.append(
            f"the optical flow keeps only {100 * inside.mean():.1f}% of the pixels in view: "
            "frames t and t+1 barely overlap"
        )
    g_abc, g_R, g_T = global_proposals(
        camera,
        abc,
        R_seg,
        T_seg,
        np.flatnonzero(plane_ok & motion_ok),
        p.x,
        p.y,
        p.disparity,
        p.x1,
        p.y1,
        p.change,
        rng=rng,
        max_count=settings.max_global,
        min_fraction=settings.min_global_fraction,
        num_hypotheses=settings.global_hypotheses,
        num_samples=settings.global_samples,
        disparity_threshold=settings.global_disparity_threshold,
        motion_threshold=settings.global_motion_threshold,
    )
    props = ProposalSet(
        np.repeat(abc, 2, axis=0),
        np.stack([R_seg, np.broadcast_to(R_dom, R_seg.shape)], axis=1).reshape(-1, 3, 3),
        np.stack([T_seg, np.broadcast_to(T_dom, T_seg.shape)], axis=1).reshape(-1, 3),
    ).concat(ProposalSet(g_abc, g_R, g_T))
    global_ids = 2 * L + np.arange(len(g_abc))
    neighbours = neighbour_lists(graph, settings.max_neighbours)
    lists = []
    for s in range(L):
        near = np.concatenate([[s], neighbours[s]])
        lists.append(np.concatenate([2 * near, 2 * near + 1, global_ids]))
    return SegmentProposals(
        proposals=props,
        candidates=candidate_table(lists),
        neighbours=tuple(neighbours),
        global_ids=global_ids,
        dominant_inliers=dom_fraction,
        messages=tuple(messages),
    )


def _segment_planes(graph, pixels, settings, rng):
    """Every segment's plane (a fit, the nearest fitted segment's, or a fallback), kept
    in front of the camera; which segments have their own fit; messages."""
    p = pixels
    has_d = p.has_disparity
    L = graph.num_segments
    abc, plane_ok = fit_planes(
        p.segment[has_d],
        L,
        p.x[has_d],
        p.y[has_d],
        p.disparity[has_d],
        rng=rng,
        num_hypotheses=settings.plane_hypotheses,
        inlier_threshold=settings.plane_threshold,
    )
    messages = []
    if not plane_ok.any():
        known = p.disparity[has_d]
        fallback = float(np.median(known)) if known.size else settings.fallback_disparity
        level = max(fallback, settings.min_disparity)
        if not known.size:
            messages.append(
                "no disparity could be matched: every segment gets a fronto-parallel plane at "
                f"{level:g} px"
            )
        abc = np.tile([0.0, 0.0, level], (L, 1))
    else:
        abc = _fill_planes(graph, abc, plane_ok)
    return keep_in_front(abc, graph, settings.min_disparity), plane_ok, messages


def candidate_table(lists: list[np.ndarray]) -> np.ndarray:
    """Candidate lists as one (L, C) table, -1 padded."""
    width = max(1, max((len(c) for c in lists), default=1))
    table = -np.ones((len(lists), width), dtype=np.int64)
    for s, c in enumerate(lists):
        table[s, : len(c)] = c
    return table


def neighbour_lists(graph: SegmentGraph, limit: int) -> list[np.ndarray]:
    """Up to ``limit`` neighbours of every segment, longest shared border first."""
    e = graph.edges
    both = np.concatenate([e, e[:, ::-1]])
    length = np.concatenate([graph.boundary_length, graph.boundary_length])
    order = np.lexsort((-length, both[:, 0]))
    both = both[order]
    starts = np.searchsorted(both[:, 0], np.arange(graph.num_segments + 1))
    return [both[starts[s] : starts[s + 1], 1][:limit] for s in range(graph.num_segments)]


def _fill_planes(graph: SegmentGraph, abc: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Planes of segments without a fit: the nearest fitted segment's (by centroid)."""
    if ok.all() or not ok.any():
        return abc
    from scipy.spatial import cKDTree

    tree = cKDTree(graph.centroids[ok])
    _, nearest = tree.query(graph.centroids[~ok])
    out = abc.copy()
    out[~ok] = abc[np.flatnonzero(ok)[nearest]]
    return out


def keep_in_front(abc: np.ndarray, graph: SegmentGraph, min_disparity: float) -> np.ndarray:
    """Planes whose disparity drops below ``min_disparity`` on their segment replaced by
    the constant plane at their mean disparity (at least ``min_disparity``)."""
    height, width = graph.labels.shape
    yy, xx = np.mgrid[0:height, 0:width]
    x, y = xx.ravel().astype(np.float64), yy.ravel().astype(np.float64)
    seg = graph.labels.ravel()
    d = abc[seg, 0] * x + abc[seg, 1] * y + abc[seg, 2]
    low = np.full(graph.num_segments, np.inf)
    np.minimum.at(low, seg, d)
    mean = np.bincount(seg, d, graph.num_segments) / np.maximum(graph.sizes, 1)
    bad = low < min_disparity
    out = abc.copy()
    out[bad] = np.stack(
        [np.zeros(bad.sum()), np.zeros(bad.sum()), np.maximum(mean[bad], min_disparity)], axis=1
    )
    return out
