"""Proposal fusion: every segment picks one plane+motion proposal by graph cuts.

Energy (over the labelling ``f``: segment -> proposal)::

    E(f) = sum_s D_s(f_s) + sum_(s,t) V_st(f_s, f_t)

* ``D_s(p)``: the 4-view census cost of proposal ``p`` on segment ``s``: each
  (sampled) pixel of ``s`` in the left view at t is matched in the right view at
  t, the left view at t + 1 and the right view at t + 1 at the positions the
  plane and motion predict (see :func:`proposals.predict`), costs per view in
  [0, 1] (:mod:`census`); where a position leaves the image, what a wrong match
  would cost there (:func:`census.wrong_match_cost`: near 0 in clean flat
  regions, about 0.5 in texture and in noise), so that leaving the view is
  neither favoured nor penalised, also where noise makes every match cost as
  much as a wrong one; where the point would lie behind a camera, the larger of
  that and ``outside_cost`` per view; summed over the pixels of ``s`` (samples
  scaled to the full pixel count).
* ``V_st(p, q) = smoothness * w_st * length_st * min(truncation, dist_st(p, q))``
  (defaults ``smoothness = 2`` per boundary pixel and pixel, ``truncation = 4``
  px; ``w_st`` an optional edge weight in (0, 1]), with
  ``dist_st`` the mean over sample points on the shared boundary of the L1
  difference of ``(d0, x1, y1, d1)`` (disparity at t, position and disparity at
  t + 1) predicted by ``p`` and by ``q``. ``dist_st`` is an L1 distance between
  the predictions of the two proposals, a truncated metric is a metric, so
  ``V_st`` is a metric on proposals.

Each segment may only take proposals from its candidate list (its own, its
neighbours', global ones). The energy is minimised by alpha-expansion (Boykov,
Veksler & Zabih 2001) with exact max-flow moves (PyMaxflow); for a metric ``V``
every expansion move is submodular and solved exactly, and the local minimum
reached is within a factor ``2 max V / min V`` (ratio of the largest to the
smallest non-zero pairwise cost) of the global optimum over the labellings that
respect the candidate lists.
Expansions of labels whose candidate regions do not touch are independent; they
are solved together in one max-flow ("batches"), which changes nothing in the
result of each move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .._threads import balanced_ranges, run_ranges
from ..geometry.camera import StereoCamera
from .census import census_cost_at, census_cost_or_leave, wrong_match_cost
from .prediction import predict
from .superpixels import SegmentGraph


@dataclass(frozen=True)
class ProposalSet:
    """Plane+motion proposals: disparity coefficients ``abc`` (M, 3), motions ``R`` (M, 3, 3)
    and ``T`` (M, 3)."""

    abc: np.ndarray
    R: np.ndarray
    T: np.ndarray

    def __len__(self) -> int:
        return len(self.abc)

    def concat(self, other: ProposalSet) -> ProposalSet:
        return ProposalSet(
            np.concatenate([self.abc, other.abc]),
            np.concatenate([self.R, other.R]),
            np.concatenate([self.T, other.T]),
        )

    def twists(self) -> np.ndarray:
        """The motions as twists ``(v, omega)``, shape (M, 6) (non-finite entries as 0)."""
        from ..geometry.rigid import se3_log

        M = np.tile(np.eye(4), (len(self), 1, 1))
        M[:, :3, :3] = self.R
        M[:, :3, 3] = self.T
        return np.nan_to_num(se3_log(M))


# --------------------------------------------------------------------------- data term


def sample_pixels(graph: SegmentGraph, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels on a ``step`` grid, grouped by segment; every segment keeps at least one pixel.

    Returns the flat pixel indices, per-segment bounds (L + 1,) and the factor
    per segment that scales a sum over its samples to its full size.
    """
    width = graph.labels.shape[1]
    order, bounds = graph.order, graph.bounds
    y, x = np.divmod(order, width)
    on_grid = (x % step == 0) & (y % step == 0)
    seg = np.repeat(np.arange(graph.num_segments), np.diff(bounds))
    has = np.bincount(seg[on_grid], minlength=graph.num_segments) > 0
    keep = on_grid | ~has[seg]
    samples = order[keep]
    sample_bounds = np.searchsorted(seg[keep], np.arange(graph.num_segments + 1))
    factor = np.diff(bounds) / np.maximum(np.diff(sample_bounds), 1)
    return samples.astype(np.int64), sample_bounds.astype(np.int64), factor


def data_costs(
    camera: StereoCamera,
    codes: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    samples: np.ndarray,
    sample_bounds: np.ndarray,
    factor: np.ndarray,
    candidates: np.ndarray,
    proposals: ProposalSet,
    *,
    outside_cost: float = 0.4,
    dominant: np.ndarray | None = None,
    leave_near: np.ndarray | None = None,
    reach: float = 0.0,
    other_side: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """``D[s, i]``: census cost of candidate ``candidates[s, i]`` on segment ``s``.

    Parameters
    ----------
    camera : StereoCamera
    codes : tuple of 4 ndarray
        Census descriptors of left t, right t, left t + 1, right t + 1.
    samples, sample_bounds, factor
        From :func:`sample_pixels`.
    candidates : ndarray of int, shape (L, C)
        Proposal indices, -1 for an empty slot.
    proposals : ProposalSet
    outside_cost : float
        Least cost per view of a prediction behind a camera (impossible).
    dominant, leave_near, reach : optional
        Proposals (bool per proposal) that leave the view at ``leave_near`` (per pixel,
        :func:`census.leave_costs_near`) instead of a wrong match's cost, where their position
        at t + 1 lies at most ``reach`` px outside the image.
    other_side : tuple of 2 ndarray, optional
        Census descriptors of left and right at the frame on the other side of t (t - 1 when
        the motion leads to t + 1). A sample whose position at t + 1 leaves a view is matched
        there, under the inverse motion (the motion taken as constant over the three frames),
        and that match replaces the cost of leaving where it is lower by more than
        :data:`OTHER_SIDE_MARGIN`: what leaves the view at t + 1 was in view at t - 1.

    Returns
    -------
    ndarray, shape (L, C)
        Costs, ``inf`` in empty slots.
    """
    lt, rt, lt1, rt1 = codes
    out = np.zeros(candidates.shape)
    # Segments in parallel, in ranges of about equal work (samples times candidates).
    work = np.diff(sample_bounds) * np.count_nonzero(candidates >= 0, axis=1)
    work_bounds = np.concatenate([[0], np.cumsum(work)])
    parts = max(1, min(2 * numba.get_num_threads(), int(work_bounds[-1]) // _MIN_WORK))
    motion = (proposals.abc, proposals.R, proposals.T)
    cam = (camera.K, camera.K_inv, camera.fx * camera.baseline)
    leave = wrong_match_cost(lt)
    if dominant is None:
        dominant, leave_near = np.zeros(len(proposals), dtype=np.bool_), leave
    leaving = (leave, leave_near, dominant, float(reach))
    arguments = (samples, sample_bounds, candidates, motion, cam, float(outside_cost), out)
    ranges = balanced_ranges(work_bounds, parts)
    other = (lt, rt, False) if other_side is None else (*other_side, True)
    run_ranges(_data_costs, ranges, leaving, (lt, rt, lt1, rt1), other, *arguments)
    return np.where(candidates >= 0, out * factor[:, None], np.inf)


OTHER_SIDE_MARGIN = 0.1
"""Census cost by which a match on the other side must undercut the cost of leaving the view to
replace it (:func:`data_costs`): without it family_1048 (a nearly textureless frame whose two
global motions differ by 2 % in cost) took the wrong one (results/README.md, "What leaves the
view at t + 1 was in view at t - 1"); 0.1 not tuned further."""

_MIN_WORK = 100000
"""Fewer candidate samples than this per range are not worth a thread (:func:`data_costs`)."""


@numba.njit(cache=True, nogil=True)
def _data_costs(
    first, last, leaving, codes, other, samples, bounds, candidates, motion, cam, outside, out
):
    """``out[s, i]`` for segments ``first .. last - 1`` (see :func:`data_costs`)."""
    leave_costs, leave_near, dominant, reach = leaving
    lt, rt, lt1, rt1 = codes
    lo, ro, use_other = other
    abc, R, T = motion
    K, Kinv, fb = cam
    width_c = candidates.shape[1]
    width = lt.shape[1]
    for s in range(first, last):
        for i in range(width_c):
            p = candidates[s, i]
            if p < 0:
                continue
            total = 0.0
            for k in range(bounds[s], bounds[s + 1]):
                flat = samples[k]
                y = flat // width
                x = flat - y * width
                code = lt[y, x]
                # Leaving the image costs what a wrong match would cost here.
                leave = leave_costs[y, x]
                impossible = max(leave, outside)
                d0 = abc[p, 0] * x + abc[p, 1] * y + abc[p, 2]
                if d0 <= 0.0:
                    total += 3.0 * impossible
                    continue
                c = census_cost_at(code, rt, x - d0, float(y))
                total += leave if c < 0 else c
                w = d0 / fb
                rx = Kinv[0, 0] * x + Kinv[0, 1] * y + Kinv[0, 2]
                ry = Kinv[1, 0] * x + Kinv[1, 1] * y + Kinv[1, 2]
                rz = Kinv[2, 0] * x + Kinv[2, 1] * y + Kinv[2, 2]
                qx = R[p, 0, 0] * rx + R[p, 0, 1] * ry + R[p, 0, 2] * rz + T[p, 0] * w
                qy = R[p, 1, 0] * rx + R[p, 1, 1] * ry + R[p, 1, 2] * rz + T[p, 1] * w
                qz = R[p, 2, 0] * rx + R[p, 2, 1] * ry + R[p, 2, 2] * rz + T[p, 2] * w
                if qz <= 1e-12:
                    total += 2.0 * impossible
                    continue
                x1 = (K[0, 0] * qx + K[0, 1] * qy + K[0, 2] * qz) / qz
                y1 = (K[1, 0] * qx + K[1, 1] * qy + K[1, 2] * qz) / qz
                d1 = fb * w / qz
                near = leave_near[y, x] if dominant[p] else leave
                left = census_cost_at(code, lt1, x1, y1)
                right = census_cost_at(code, rt1, x1 - d1, y1)
                left_out, right_out = left < 0, right < 0
                if left_out:
                    left = census_cost_or_leave(code, lt1, x1, y1, leave, near, reach)
                if right_out:
                    right = census_cost_or_leave(code, rt1, x1 - d1, y1, leave, near, reach)
                if use_other and (left_out or right_out):
                    # The other side: Q = R^T (P - T), scaled by the inverse depth w. A match
                    # there replaces the cost of leaving where it is cheaper by the margin.
                    ax, ay, az = rx - T[p, 0] * w, ry - T[p, 1] * w, rz - T[p, 2] * w
                    ox = R[p, 0, 0] * ax + R[p, 1, 0] * ay + R[p, 2, 0] * az
                    oy = R[p, 0, 1] * ax + R[p, 1, 1] * ay + R[p, 2, 1] * az
                    oz = R[p, 0, 2] * ax + R[p, 1, 2] * ay + R[p, 2, 2] * az
                    if oz > 1e-12:
                        xo = (K[0, 0] * ox + K[0, 1] * oy + K[0, 2] * oz) / oz
                        yo = (K[1, 0] * ox + K[1, 1] * oy + K[1, 2] * oz) / oz
                        if left_out:
                            c = census_cost_at(code, lo, xo, yo)
                            left = c if 0 <= c < left - OTHER_SIDE_MARGIN else left
                        if right_out:
                            c = census_cost_at(code, ro, xo - fb * w / oz, yo)
                            right = c if 0 <= c < right - OTHER_SIDE_MARGIN else right
                total += left + right
            out[s, i] = total


# --------------------------------------------------------------------------- smoothness


def pairwise_tables(
    camera: StereoCamera,
    graph: SegmentGraph,
    candidates: np.ndarray,
    proposals: ProposalSet,
    *,
    smoothness: float = 2.0,
    truncation: float = 4.0,
    edge_weights: np.ndarray | None = None,
) -> np.ndarray:
    """``V[e, i, j]``: smoothness cost of edge ``e = (s, t)`` with ``s`` on its candidate ``i``
    and ``t`` on its candidate ``j``, shape (E, C, C).

    ``edge_weights`` (E,), optional, scale each edge's cost (e.g. lower across
    image edges, where depth and motion discontinuities are likely).
    """
    E = len(graph.edges)
    C = candidates.shape[1]
    if E == 0:
        return np.zeros((0, C, C))
    pts = graph.boundary_points  # (E, K, 2)
    out = np.empty((E, C, C), dtype=np.float64)
    chunk = max(1, 200_000 // (C * C * pts.shape[1]))
    for start in range(0, E, chunk):
        sl = slice(start, min(E, start + chunk))
        preds = []
        for side in (0, 1):
            seg = graph.edges[sl, side]
            cand = candidates[seg]  # (e, C)
            safe = np.maximum(cand, 0)
            x = pts[sl, None, :, 0]
            y = pts[sl, None, :, 1]
            d0, x1, y1, d1 = predict(
                camera,
                proposals.abc[safe][:, :, None, :],
                proposals.R[safe][:, :, None],
                proposals.T[safe][:, :, None],
                x,
                y,
            )
            g = np.stack([d0, x1, y1, d1], axis=-1)  # (e, C, K, 4)
            g = np.where(np.isfinite(g), g, 1e6)
            preds.append(g)
        out[sl] = _truncated_distances(preds[0], preds[1], float(truncation))
    weight = smoothness * graph.boundary_length
    if edge_weights is not None:
        weight = weight * np.asarray(edge_weights, dtype=np.float64)
    return out * weight[:, None, None]


@numba.njit(cache=True, nogil=True)
def _truncated_distances(a, b, truncation):
    """``min(truncation, mean_k sum_f |a[e, i, k, f] - b[e, j, k, f]|)``, shape (E, C, C)."""
    num, C, K, F = a.shape
    out = np.empty((num, C, C))
    for e in range(num):
        for i in range(C):
            for j in range(C):
                total = 0.0
                for k in range(K):
                    s = 0.0
                    for f in range(F):
                        s += abs(a[e, i, k, f] - b[e, j, k, f])
                    total += s
                out[e, i, j] = min(total / K, truncation)
    return out


# --------------------------------------------------------------------------- alpha-expansion


@dataclass(frozen=True)
class FusionResult:
    """Local index of the chosen candidate per segment, the energy, and its history."""

    choice: np.ndarray
    energy: float
    history: tuple[float, ...]


def energy(D: np.ndarray, V: np.ndarray, edges: np.ndarray, choice: np.ndarray) -> float:
    """``E(f) = sum_s D[s, f_s] + sum_e V[e, f_s, f_t]`` for local candidate indices."""
    seg = np.arange(len(choice))
    unary = D[seg, choice].sum()
    if len(edges) == 0:
        return float(unary)
    pair = V[np.arange(len(edges)), choice[edges[:, 0]], choice[edges[:, 1]]].sum()
    return float(unary + pair)


def _label_regions(candidates: np.ndarray):
    """Segments and local slots of every distinct proposal in ``candidates``."""
    seg, slot = np.nonzero(candidates >= 0)
    labels = candidates[seg, slot]
    order = np.lexsort((seg, labels))
    labels, seg, slot = labels[order], seg[order], slot[order]
    uniq, starts = np.unique(labels, return_index=True)
    bounds = np.append(starts, len(labels)).astype(np.int64)
    return uniq, bounds, seg.astype(np.int64), slot.astype(np.int64)


@numba.njit(cache=True)
def _make_batches(label_order, bounds, seg, nbr_ptr, nbr_idx, num_segments):
    """Greedy batches of labels whose regions (and their neighbourhoods) do not touch."""
    num_labels = len(label_order)
    batch = -np.ones(num_labels, dtype=np.int64)
    closed = -np.ones(num_segments, dtype=np.int64)
    remaining = num_labels
    b = 0
    while remaining > 0:
        for li in label_order:
            if batch[li] >= 0:
                continue
            free = True
            for k in range(bounds[li], bounds[li + 1]):
                if closed[seg[k]] == b:
                    free = False
                    break
            if not free:
                continue
            batch[li] = b
            remaining -= 1
            for k in range(bounds[li], bounds[li + 1]):
                s = seg[k]
                closed[s] = b
                for m in range(nbr_ptr[s], nbr_ptr[s + 1]):
                    closed[nbr_idx[m]] = b
        b += 1
    return batch, b


@numba.njit(cache=True)
def _build_move(batch_labels, bounds, seg, slot, choice, D, V, edges, num_segments):
    """Unary and pairwise terms of the expansion moves of one batch of labels.

    Variable ``x_s = 1`` means "segment s switches to its region's label".
    Returns node segments, their switch slots, unary costs (x=0, x=1) and the
    pairwise edges (node i, node j, cost of (0,1), cost of (1,0)) after the
    standard reparametrisation of submodular terms.
    """
    node_of = -np.ones(num_segments, dtype=np.int64)
    target = -np.ones(num_segments, dtype=np.int64)
    count = 0
    for li in batch_labels:
        count += bounds[li + 1] - bounds[li]
    nodes = np.empty(count, dtype=np.int64)
    n = 0
    for li in batch_labels:
        for k in range(bounds[li], bounds[li + 1]):
            s = seg[k]
            node_of[s] = n
            target[s] = slot[k]
            nodes[n] = s
            n += 1
    u0 = np.zeros(n)
    u1 = np.zeros(n)
    for i in range(n):
        s = nodes[i]
        u0[i] = D[s, choice[s]]
        u1[i] = D[s, target[s]]
    ei = np.empty(len(edges), dtype=np.int64)
    ej = np.empty(len(edges), dtype=np.int64)
    cap = np.empty(len(edges))
    rcap = np.empty(len(edges))
    m = 0
    for e in range(len(edges)):
        s = edges[e, 0]
        t = edges[e, 1]
        ns = node_of[s]
        nt = node_of[t]
        if ns < 0 and nt < 0:
            continue
        a = V[e, choice[s], choice[t]]
        if ns >= 0 and nt >= 0:
            b = V[e, choice[s], target[t]]  # x_s = 0, x_t = 1
            c = V[e, target[s], choice[t]]  # x_s = 1, x_t = 0
            d = V[e, target[s], target[t]]
            # E = a + (c - a) x_s + (d - c) x_t + (b + c - a - d) (1 - x_s) x_t
            u1[ns] += c - a
            u1[nt] += d - c
            w = b + c - a - d
            if w < 0:
                w = 0.0  # only rounding can make a metric's move non-submodular
            ei[m] = ns
            ej[m] = nt
            cap[m] = w
            rcap[m] = 0.0
            m += 1
        elif ns >= 0:
            u0[ns] += a
            u1[ns] += V[e, target[s], choice[t]]
        else:
            u0[nt] += a
            u1[nt] += V[e, choice[s], target[t]]
    return nodes, target, u0, u1, ei[:m], ej[:m], cap[:m], rcap[:m]


def alpha_expansion(
    D: np.ndarray,
    V: np.ndarray,
    edges: np.ndarray,
    candidates: np.ndarray,
    init: np.ndarray,
    *,
    num_sweeps: int = 4,
    seed: int = 0,
) -> FusionResult:
    """Minimise ``sum_s D[s, f_s] + sum_e V[e, f_s, f_t]`` by alpha-expansion.

    Parameters
    ----------
    D : ndarray, shape (L, C)
        Unary costs per segment and candidate slot (``inf`` in empty slots).
    V : ndarray, shape (E, C, C)
        Pairwise costs per edge and candidate slots of its two segments; must be
        a metric on the proposals (zero for equal proposals).
    edges : ndarray of int, shape (E, 2)
    candidates : ndarray of int, shape (L, C)
        Global proposal index per slot, -1 for empty slots.
    init : ndarray of int, shape (L,)
        Starting slot per segment (must be a non-empty slot).
    num_sweeps : int
        Maximum passes over all labels; stops early when a pass changes nothing.
    seed : int
        Seed of the order in which labels are expanded.

    Returns
    -------
    FusionResult
    """
    import maxflow

    num_segments = D.shape[0]
    finite = np.isfinite(D)
    big = (np.abs(D[finite]).max() if finite.any() else 1.0) * 10 + 1.0
    Dq = np.where(finite, D, big)
    choice = np.asarray(init, dtype=np.int64).copy()
    if np.any(candidates[np.arange(num_segments), choice] < 0):
        raise ValueError("init must pick a non-empty candidate slot for every segment")
    uniq, bounds, seg, slot = _label_regions(candidates)
    both = np.concatenate([edges, edges[:, ::-1]]) if len(edges) else np.zeros((0, 2), np.int64)
    both = both[np.argsort(both[:, 0], kind="stable")]
    nbr_ptr = np.searchsorted(both[:, 0], np.arange(num_segments + 1)).astype(np.int64)
    nbr_idx = both[:, 1].astype(np.int64)
    rng = np.random.default_rng(seed)
    edges64 = np.ascontiguousarray(edges, dtype=np.int64)
    current = energy(Dq, V, edges64, choice)
    history = [current]
    for _ in range(num_sweeps):
        order = rng.permutation(len(uniq)).astype(np.int64)
        batch, num_batches = _make_batches(order, bounds, seg, nbr_ptr, nbr_idx, num_segments)
        batch_order = np.argsort(batch, kind="stable")
        batch_bounds = np.searchsorted(batch[batch_order], np.arange(num_batches + 1))
        for b in range(num_batches):
            labels_b = batch_order[batch_bounds[b] : batch_bounds[b + 1]].astype(np.int64)
            nodes, target, u0, u1, ei, ej, cap, rcap = _build_move(
                labels_b, bounds, seg, slot, choice, Dq, V, edges64, num_segments
            )
            n = len(nodes)
            if n == 0:
                continue
            # Unary: cost of x=1 goes on the source edge (cut when on the sink side).
            base = np.minimum(u0, u1)
            g = maxflow.Graph[float](n, len(ei))
            ids = g.add_nodes(n)
            g.add_grid_tedges(ids, u1 - base, u0 - base)
            if len(ei):
                g.add_edges(ei, ej, cap, rcap)
            g.maxflow()
            switch = g.get_grid_segments(ids)  # True: sink side, x = 1
            segs = nodes[switch]
            choice[segs] = target[segs]
        new = energy(Dq, V, edges64, choice)
        history.append(new)
        if new >= current - 1e-9 * max(1.0, abs(current)):
            current = new
            break
        current = new
    return FusionResult(choice=choice, energy=current, history=tuple(history))
