"""Piecewise-rigid scene flow from two blurred stereo frames, in the spirit of PRSF.

Vogel, Schindler & Roth (IJCV 2015) model the scene as planar segments moving
rigidly; the paper (Sec. 3) takes its planes, motions and occlusions from it.
This estimator follows the same model in stages:

1. census descriptors of the four images (:mod:`census`), robust to blur and gain,
   with "similar" bands relative to the brightness (dark texture counts) and
   above the estimated sensor noise (noise does not pass for texture);
2. initial disparity at t and t + 1 by semi-global matching and initial optical
   flow (left view, t -> t + 1, and back) by DIS (:mod:`initial`);
3. SLIC superpixels of the left view at t, about 1200 at 640x480
   (:mod:`superpixels`);
4. proposals (:mod:`proposals`): per segment a robust plane fit to the
   disparities and a robust rigid-motion fit to the correspondences; the
   dominant motion (the camera's own motion) with every segment's plane; and
   global proposals (sequential RANSAC over the segments' proposals: a plane
   with its motion that explains a large part of the image, refitted on all its
   pixels);
5. fusion (:mod:`fusion`): each segment picks its own, a neighbour's or a
   global proposal by the 4-view census cost plus a truncated smoothness term
   (weaker across contrast edges), by alpha-expansion over the segment
   adjacency graph; regions of segments that picked the same proposal are then
   refitted as one and offered again to their neighbours (twice);
6. continuous refinement of every chosen plane and motion (9 parameters, shared
   by the segments that chose it) on the images (:mod:`refine`); if the exposure
   is given and the blur's length changes strongly between the frames (a fast
   approach), once more on images whose blur has been balanced (each frame
   blurred by the other frame's predicted motion, :func:`refine.cross_blur`);
7. occlusion, out-of-view and motion-boundary masks (:mod:`occlusion`).

Fits and the data term use pixels on a 2-pixel grid from 200,000 pixels on.
On a 2-core machine a 640x480 frame pair takes about 5 s of CPU time.
Matching blurred frames directly has a limit: under strong blur that changes
between the frames (a near plane approaching fast), the estimate is biased
(planar benchmark ``fast_approach`` at 640x480: 0.8 px mean endpoint error,
against 0.01 px on the sharp frames); balancing the blur (needs ``exposure``)
brings it to 0.33 px.

Conventions are the package's: left reference view at frame t, pixel centres at
integer coordinates, planes ``P^T n = 1`` in left-camera coordinates at t,
twists from t to t + 1. Input images are float in [0, 1], grey or RGB.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..geometry.camera import Exposure, StereoCamera
from ..geometry.plane import plane_from_disparity_coefficients
from .blur_balance import blur_length_change, cross_blur
from .census import census_cost, census_descriptors
from .fusion import ProposalSet, alpha_expansion, data_costs, pairwise_tables, sample_pixels
from .initial import initial_disparity, initial_optical_flow, to_gray, to_gray_u8
from .model import SceneFlow
from .occlusion import occlusion_masks
from .proposals import (
    correspondences,
    dominant_motion,
    fit_motions,
    fit_planes,
    global_proposals,
    predict,
)
from .refine import refine_proposals
from .superpixels import SegmentGraph, default_num_segments, segment_graph, slic_segments

MIN_DISPARITY = 0.05  # px: planes are kept in front of the camera over their segment
FALLBACK_DISPARITY = 1.0  # px: plane used where no disparity is known anywhere
MAX_NEIGHBOURS = 8  # neighbours whose proposals a segment may take (longest borders)
MAX_GLOBAL = 6  # largest regions offered to every segment in the region rounds
NUM_REGION_ROUNDS = 2
MATCH_COST = 0.3  # census cost (fraction of differing neighbours) of a good match
MIN_MATCHED = 0.1  # warn when fewer pixels than this match in a view
CENSUS_THRESHOLD = 0.008  # census "similar" band at a quarter of full scale (clean images)
CENSUS_NOISE_FACTOR = 1.0  # ... at least the std of the noise of a pixel difference
CENSUS_DENOISE = 1.5  # px: Gaussian smoothing before the census of noisy images
EDGE_FLOOR = 0.25  # smoothness weight across a strong contrast edge
EDGE_CONTRAST = 0.1  # mean grey difference (of [0, 1]) that counts as an edge
# Balancing the blur doubles it (weaker data), so it is done only where the blur's length
# changes strongly from t to t + 1 (relative to the longer blur, at least 1 px) ...
BLUR_CHANGE = 0.15
BLUR_CHANGE_SHARE = 0.5  # ... on at least this share of the pixels
BALANCED_PRIOR = 0.0  # prior weights of the refinement on blur-balanced images


class SceneFlowWarning(UserWarning):
    """The input gives the scene flow little to work with (textureless, no overlap, ...)."""


@dataclass(frozen=True)
class SceneFlowEstimate:
    """Estimated scene flow and the initial correspondences it started from.

    Parameters
    ----------
    sceneflow : SceneFlow
        Segments of the left view at t with planes, motions and occlusion.
    initial_flow : ndarray, shape (H, W, 2), float32
        DIS optical flow of the left view, t -> t + 1 (the paper's "initial optical flow").
    initial_disparity : ndarray, shape (H, W), float32
        Semi-global matching disparity at t, NaN in holes.
    initial_disparity_next : ndarray, shape (H, W), float32
        Semi-global matching disparity at t + 1 (in frame t + 1's pixels), NaN in holes.
    warnings : tuple of str
        Messages about degenerate input (also issued as :class:`SceneFlowWarning`).
    timings : dict
        Seconds per stage.
    diagnostics : dict
        ``matched_right_t``, ``matched_left_t1``, ``matched_right_t1``: share of the
        pixels whose census cost at the predicted position is below ``MATCH_COST``;
        ``dominant_inliers``: share of the pixels the dominant motion explains;
        ``num_proposals``: distinct plane+motion proposals in the result;
        ``num_global``: global proposals found.
    """

    sceneflow: SceneFlow
    initial_flow: np.ndarray
    initial_disparity: np.ndarray
    initial_disparity_next: np.ndarray
    warnings: tuple[str, ...] = ()
    timings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- helpers


def _check_images(images) -> tuple[int, int]:
    names = ("left_t", "right_t", "left_t1", "right_t1")
    shape = None
    for name, image in zip(names, images, strict=True):
        a = np.asarray(image)
        if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (1, 3)):
            raise InputError(f"{name} must have shape (H, W) or (H, W, 3), got {a.shape}")
        if a.shape[0] < 8 or a.shape[1] < 8:
            raise InputError(f"{name} is too small for scene flow: {a.shape[:2]} (need >= 8x8)")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise InputError(f"{name} has shape {a.shape}, left_t has {shape}")
        if a.dtype.kind not in "fui" or not np.all(np.isfinite(a)):
            raise InputError(f"{name} must hold finite numbers, got dtype {a.dtype}")
    return int(shape[0]), int(shape[1])


class _Progress:
    def __init__(self, callback: Callable[[str, float], None] | None, stages: list[str]):
        self.callback = callback
        self.stages = stages
        self.timings: dict[str, float] = {}
        self._t = time.perf_counter()

    def done(self, stage: str) -> None:
        now = time.perf_counter()
        self.timings[stage] = self.timings.get(stage, 0.0) + now - self._t
        self._t = now
        if self.callback is not None:
            i = self.stages.index(stage) + 1 if stage in self.stages else len(self.stages)
            self.callback(stage, i / len(self.stages))


_STAGES = [
    "census",
    "initial",
    "superpixels",
    "proposals",
    "fusion",
    "regions",
    "refine",
    "occlusion",
]


def _candidate_table(lists: list[np.ndarray]) -> np.ndarray:
    width = max(1, max((len(c) for c in lists), default=1))
    table = -np.ones((len(lists), width), dtype=np.int64)
    for s, c in enumerate(lists):
        table[s, : len(c)] = c
    return table


def _neighbour_lists(graph: SegmentGraph, limit: int) -> list[np.ndarray]:
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


def _keep_in_front(abc: np.ndarray, graph: SegmentGraph, x: np.ndarray, y: np.ndarray):
    """Replace planes whose disparity drops below MIN_DISPARITY on their segment by a constant."""
    seg = graph.labels.ravel()
    d = abc[seg, 0] * x + abc[seg, 1] * y + abc[seg, 2]
    low = np.full(graph.num_segments, np.inf)
    np.minimum.at(low, seg, d)
    mean = np.bincount(seg, d, graph.num_segments) / np.maximum(graph.sizes, 1)
    bad = low < MIN_DISPARITY
    out = abc.copy()
    out[bad] = np.stack(
        [np.zeros(bad.sum()), np.zeros(bad.sum()), np.maximum(mean[bad], MIN_DISPARITY)], axis=1
    )
    return out


def _matched_fractions(camera, codes, labels, seg_abc, final, chosen_local, step):
    """Share of (grid) pixels whose census cost in each other view is below MATCH_COST."""
    height, width = labels.shape
    yy, xx = np.mgrid[0:height:step, 0:width:step]
    x, y = xx.ravel(), yy.ravel()
    seg = labels[y, x]
    k = chosen_local[seg]
    d0, x1, y1, d1 = predict(camera, seg_abc[seg], final.R[k], final.T[k], x, y)
    lt, rt, lt1, rt1 = codes
    out = {}
    for name, target, xt, yt in (
        ("right_t", rt, x - d0, y),
        ("left_t1", lt1, x1, y1),
        ("right_t1", rt1, x1 - d1, y1),
    ):
        cost = census_cost(lt, target, x, y, np.nan_to_num(xt, nan=-1.0), yt)
        inside = np.isfinite(cost)
        out[name] = float(np.mean(cost[inside] < MATCH_COST)) if inside.any() else 0.0
    return out


def _edge_weights(graph: SegmentGraph, gray: np.ndarray) -> np.ndarray:
    """Smoothness weight per edge: 1 between similar segments, down to EDGE_FLOOR across
    a contrast edge (difference of the segments' mean grey values, scale EDGE_CONTRAST)."""
    flat = graph.labels.ravel()
    mean = np.bincount(flat, gray.ravel(), graph.num_segments) / np.maximum(graph.sizes, 1)
    diff = mean[graph.edges[:, 0]] - mean[graph.edges[:, 1]]
    return EDGE_FLOOR + (1 - EDGE_FLOOR) * np.exp(-((diff / EDGE_CONTRAST) ** 2))


def _regions(graph: SegmentGraph, proposal_of_segment: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of segments that chose the same proposal."""
    import scipy.sparse as sp

    e = graph.edges
    same = proposal_of_segment[e[:, 0]] == proposal_of_segment[e[:, 1]]
    n = graph.num_segments
    A = sp.csr_matrix((np.ones(same.sum()), (e[same, 0], e[same, 1])), shape=(n, n))
    return connected_components(A, directed=False)


# --------------------------------------------------------------------------- estimator


def estimate_scene_flow(
    left_t: np.ndarray,
    right_t: np.ndarray,
    left_t1: np.ndarray,
    right_t1: np.ndarray,
    camera: StereoCamera,
    *,
    num_segments: int | None = None,
    seed: int = 0,
    exposure: Exposure | None = None,
    progress: Callable[[str, float], None] | None = None,
    debug_dir: str | Path | None = None,
) -> SceneFlowEstimate:
    """Estimate a piecewise-rigid scene flow of the left view from frame t to t + 1.

    Parameters
    ----------
    left_t, right_t, left_t1, right_t1 : ndarray, shape (H, W) or (H, W, 3)
        Rectified (possibly motion-blurred) frames t and t + 1, float in [0, 1].
    camera : StereoCamera
    num_segments : int, optional
        Number of superpixels; default about 1200 at 640x480, scaled with the
        image area (paper, supplement B).
    seed : int
        Seed of the random choices (RANSAC samples, expansion order).
    exposure : Exposure, optional
        Frame rate and exposure time. If given and the estimated blur changes
        between the frames (a fast approach), the refinement is repeated on
        images whose blur has been balanced (:func:`refine.cross_blur`).
    progress : callable, optional
        Called as ``progress(stage, fraction_done)`` after every stage.
    debug_dir : path, optional
        Folder for debug pictures (segments, disparity, flow, occlusion).

    Returns
    -------
    SceneFlowEstimate
        Degenerate input (textureless, black, identical or unrelated frames)
        still gives a finite result; each problem is listed in ``warnings`` and
        issued as a :class:`SceneFlowWarning`.
    """
    height, width = _check_images((left_t, right_t, left_t1, right_t1))
    if not isinstance(camera, StereoCamera):
        raise InputError(f"camera must be a StereoCamera, got {type(camera).__name__}")
    if num_segments is None:
        num_segments = default_num_segments((height, width))
    num_segments = int(num_segments)
    if num_segments < 1:
        raise InputError(f"num_segments must be >= 1, got {num_segments}")
    rng = np.random.default_rng(seed)
    messages: list[str] = []
    prog = _Progress(progress, _STAGES)

    # 1. Grey images with a common gain (dark inputs use the full 8-bit range) and census.
    grays = [
        to_gray(np.asarray(im, dtype=np.float32)) for im in (left_t, right_t, left_t1, right_t1)
    ]
    top = max(float(np.percentile(g, 99.5)) for g in grays)
    gain = 1.0 / top if top > 1e-3 else 1.0
    gain = min(gain, 16.0)
    u8 = [to_gray_u8(g, scale=gain) for g in grays]  # for OpenCV
    normed = [np.clip(g * np.float32(gain), 0.0, 1.0) for g in grays]
    # Census "similar" bands relative to the brightness (dark texture counts) and above
    # the sensor noise (estimated on each image); noisy images are smoothed first.
    codes = tuple(
        census_descriptors(
            g,
            threshold=CENSUS_THRESHOLD,
            noise_factor=CENSUS_NOISE_FACTOR,
            denoise=CENSUS_DENOISE,
        )
        for g in normed
    )
    contrast = [float(np.std(g)) for g in normed]
    contrast_ok = min(contrast) >= 2.0 / 255.0
    if not contrast_ok:
        messages.append(
            "input frames are (nearly) textureless (grey-level std "
            f"{min(contrast) * 255:.2f}/255): planes and motions are guesses"
        )
    if np.array_equal(u8[0], u8[2]) and np.array_equal(u8[1], u8[3]):
        messages.append("frames t and t+1 are identical: the estimated motion is zero")
    if np.array_equal(u8[0], u8[1]):
        messages.append("left and right views are identical: zero disparity, depth unknown")
    prog.done("census")

    # 2. Initial correspondences.
    disp0 = initial_disparity(u8[0], u8[1])
    disp1 = initial_disparity(u8[2], u8[3])
    flow = initial_optical_flow(u8[0], u8[2])
    flow_back = initial_optical_flow(u8[2], u8[0], finest_scale=1)  # for occlusion only
    valid_fraction = float(np.mean(np.isfinite(disp0)))
    if valid_fraction < 0.05:
        messages.append(
            f"stereo matching found a disparity for only {100 * valid_fraction:.1f}% of the "
            "pixels at frame t"
        )
    prog.done("initial")

    # 3. Superpixels and their graph.
    seg_image = np.asarray(left_t, dtype=np.float64)
    if seg_image.ndim == 3 and seg_image.shape[2] == 3:
        seg_image = np.clip(seg_image * gain, 0, 1)
    else:
        seg_image = normed[0].astype(np.float64)
    labels = slic_segments(seg_image, num_segments)
    graph = segment_graph(labels)
    L = graph.num_segments
    prog.done("superpixels")

    # 4. Proposals: per-segment planes and motions, the dominant motion, global proposals.
    step = 2 if height * width >= 200_000 else 1
    yy, xx = np.mgrid[0:height, 0:width]
    x_all = xx.ravel().astype(np.float64)
    y_all = yy.ravel().astype(np.float64)
    grid = ((xx % step == 0) & (yy % step == 0)).ravel()
    # Fits use pixels on a `step` grid (plus every pixel of segments the grid misses).
    grid |= np.bincount(labels.ravel()[grid], minlength=L)[labels.ravel()] == 0
    pick = np.flatnonzero(grid)
    x, y = x_all[pick], y_all[pick]
    seg = labels.ravel()[pick].astype(np.int64)
    d_obs = disp0.ravel()[pick].astype(np.float64)
    has_d = np.isfinite(d_obs)
    abc, plane_ok = fit_planes(seg[has_d], L, x[has_d], y[has_d], d_obs[has_d], rng=rng)
    if not plane_ok.any():
        known = d_obs[has_d]
        level = max(float(np.median(known)) if known.size else FALLBACK_DISPARITY, MIN_DISPARITY)
        if not known.size:
            messages.append(
                "no disparity could be matched: every segment gets a fronto-parallel plane at "
                f"{level:g} px"
            )
        abc = np.tile([0.0, 0.0, level], (L, 1))
    else:
        abc = _fill_planes(graph, abc, plane_ok)
    abc = _keep_in_front(abc, graph, x_all, y_all)
    x1o, y1o, d1o = correspondences(camera, flow, disp1, xx.ravel()[pick], yy.ravel()[pick])
    change = d1o - d_obs  # observed disparity change t -> t + 1, NaN where unknown
    d0 = abc[seg, 0] * x + abc[seg, 1] * y + abc[seg, 2]
    R_seg, T_seg, motion_ok = fit_motions(camera, seg, L, x, y, d0, x1o, y1o, d0 + change)
    R_dom, T_dom, dom_fraction = dominant_motion(
        camera,
        abc[seg],
        R_seg,
        T_seg,
        np.flatnonzero(motion_ok),
        x,
        y,
        x1o,
        y1o,
        change,
        rng=rng,
    )
    R_seg[~motion_ok] = R_dom
    T_seg[~motion_ok] = T_dom
    inside = np.isfinite(x1o)
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
        x,
        y,
        d_obs,
        x1o,
        y1o,
        change,
        rng=rng,
    )
    # Proposal 2s: segment s's own plane and motion; 2s + 1: its plane with the dominant
    # motion; then the global proposals.
    props = ProposalSet(
        np.repeat(abc, 2, axis=0),
        np.stack([R_seg, np.broadcast_to(R_dom, R_seg.shape)], axis=1).reshape(-1, 3, 3),
        np.stack([T_seg, np.broadcast_to(T_dom, T_seg.shape)], axis=1).reshape(-1, 3),
    ).concat(ProposalSet(g_abc, g_R, g_T))
    global_ids = 2 * L + np.arange(len(g_abc))
    neighbours = _neighbour_lists(graph, MAX_NEIGHBOURS)
    lists = []
    for s in range(L):
        near = np.concatenate([[s], neighbours[s]])
        lists.append(np.concatenate([2 * near, 2 * near + 1, global_ids]))
    candidates = _candidate_table(lists)
    prog.done("proposals")

    # 5. Fusion by alpha-expansion.
    samples, sample_bounds, factor = sample_pixels(graph, step)

    edge_weights = _edge_weights(graph, normed[0])

    def fuse(cands, props, init, seed_offset):
        D = data_costs(camera, codes, samples, sample_bounds, factor, cands, props)
        V = pairwise_tables(camera, graph, cands, props, edge_weights=edge_weights)
        result = alpha_expansion(D, V, graph.edges, cands, init, seed=seed + seed_offset)
        return cands[np.arange(L), result.choice], D, result

    chosen, D1, fusion1 = fuse(candidates, props, np.zeros(L, dtype=np.int64), 0)
    prog.done("fusion")

    # Regions of segments that chose the same proposal: refit as one, offer again.
    for round_index in range(NUM_REGION_ROUNDS):
        num_regions, region = _regions(graph, chosen)
        representative = np.empty(num_regions, dtype=np.int64)
        representative[region] = np.arange(L)
        base = chosen[representative]
        rabc, rok = fit_planes(
            region[seg][has_d], num_regions, x[has_d], y[has_d], d_obs[has_d], rng=rng
        )
        rabc = np.where(rok[:, None], rabc, props.abc[base])
        rd0 = rabc[region[seg], 0] * x + rabc[region[seg], 1] * y + rabc[region[seg], 2]
        good = rd0 > 0
        Rr, Tr, mok = fit_motions(
            camera,
            region[seg][good],
            num_regions,
            x[good],
            y[good],
            rd0[good],
            x1o[good],
            y1o[good],
            rd0[good] + change[good],
            init=(props.R[base], props.T[base]),
            scales=(1.0, 0.5),
            iterations_per_scale=2,
            cutoff=3.0,
        )
        Rr = np.where(mok[:, None, None], Rr, props.R[base])
        Tr = np.where(mok[:, None], Tr, props.T[base])
        offset = len(props)
        props = props.concat(ProposalSet(rabc, Rr, Tr))
        area = np.bincount(region, graph.sizes, num_regions)
        big = np.argsort(-area)[:MAX_GLOBAL]
        big = offset + big[area[big] >= 0.02 * height * width]
        lists = []
        for s in range(L):
            near = np.concatenate([[s], neighbours[s]])
            lists.append(
                np.unique(
                    np.concatenate(
                        [[chosen[s]], offset + region[near], 2 * s + np.arange(2), big, global_ids]
                    )
                )
            )
        candidates = _candidate_table(lists)
        init = np.argmax(candidates == chosen[:, None], axis=1)
        chosen, _, _ = fuse(candidates, props, init, 1 + round_index)
    prog.done("regions")

    # 6. Continuous refinement of the chosen proposals.
    used, chosen_local = np.unique(chosen, return_inverse=True)
    final = ProposalSet(props.abc[used], props.R[used], props.T[used])
    groups = chosen_local[labels]
    final = refine_proposals(camera, normed, groups, final)
    if exposure is not None and exposure.duty_cycle > 0:
        blur_change = blur_length_change(
            camera, groups, final, duty_cycle=exposure.duty_cycle, relative=True
        )
        if np.mean(np.abs(blur_change) > BLUR_CHANGE) >= BLUR_CHANGE_SHARE:
            # Differently blurred frames bias the match: give all four the same blur
            # and refine again, now led by the images alone.
            # (Unclipped: blurring commutes with a gain, not with clipping.)
            balanced, valid = cross_blur(
                camera,
                [g * np.float32(gain) for g in grays],
                groups,
                final,
                duty_cycle=exposure.duty_cycle,
            )
            final = refine_proposals(
                camera,
                balanced,
                groups,
                final,
                plane_prior=BALANCED_PRIOR,
                motion_prior=BALANCED_PRIOR,
                valid=valid,
            )
    seg_abc = _keep_in_front(final.abc[chosen_local], graph, x_all, y_all)
    twists = final.twists()[chosen_local]
    normals = plane_from_disparity_coefficients(camera, seg_abc)
    prog.done("refine")

    # How well the result explains the images: share of pixels with a good census match.
    matched = _matched_fractions(camera, codes, labels, seg_abc, final, chosen_local, step)
    if contrast_ok and matched["right_t"] < MIN_MATCHED:
        messages.append(
            f"only {100 * matched['right_t']:.0f}% of the pixels match between the left and "
            "right views at frame t: the views may not overlap or not be rectified"
        )
    if contrast_ok and matched["left_t1"] < MIN_MATCHED:
        messages.append(
            f"only {100 * matched['left_t1']:.0f}% of the pixels match between frames t and "
            "t+1: the frames may not overlap"
        )

    # 7. Occlusion.
    provisional = SceneFlow(camera, labels, normals, twists, np.zeros((height, width), bool))
    sf_disp = provisional.disparity()
    sf_flow = provisional.flow()
    sf_next = provisional.disparity_next()
    masks = occlusion_masks(
        sf_disp, sf_flow, sf_next, labels, backward_flow=flow_back, initial_flow=flow
    )
    occlusion = masks.combined
    sceneflow = SceneFlow(camera, labels, normals, twists, occlusion)
    prog.done("occlusion")

    for message in messages:
        warnings.warn(message, SceneFlowWarning, stacklevel=2)
    if debug_dir is not None:
        _write_debug(Path(debug_dir), seg_image, sceneflow, sf_disp, sf_flow, flow, disp0, masks)
    return SceneFlowEstimate(
        sceneflow=sceneflow,
        initial_flow=flow,
        initial_disparity=disp0,
        initial_disparity_next=disp1,
        warnings=tuple(messages),
        timings=dict(prog.timings),
        diagnostics={
            **{f"matched_{k}": v for k, v in matched.items()},
            "dominant_inliers": dom_fraction,
            "num_proposals": len(used),
            "num_global": len(g_abc),
        },
    )


def _write_debug(folder, image, sceneflow, disparity, flow, initial_flow, initial_disp, masks):
    from ..io.formats import write_png
    from ..viz import disparity_to_color, flow_to_color, mask_to_image, segment_overlay

    folder.mkdir(parents=True, exist_ok=True)
    finite = np.concatenate(
        [disparity[np.isfinite(disparity)], initial_disp[np.isfinite(initial_disp)]]
    )
    top = float(np.percentile(finite, 99)) if finite.size else 1.0
    max_flow = float(max(np.percentile(np.linalg.norm(flow, axis=-1), 99), 1e-3))
    pictures = {
        "segments.png": segment_overlay(image, sceneflow.labels),
        "disparity.png": disparity_to_color(disparity, max_disparity=top),
        "initial_disparity.png": disparity_to_color(initial_disp, max_disparity=top),
        "flow.png": flow_to_color(flow, max_flow=max_flow),
        "initial_flow.png": flow_to_color(initial_flow, max_flow=max_flow),
        "occlusion.png": mask_to_image(masks.combined),
    }
    for name, rgb in pictures.items():
        write_png(folder / name, rgb.astype(np.float32) / 255.0, bit_depth=8)
