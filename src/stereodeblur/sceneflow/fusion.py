"""Proposal fusion: every segment picks one plane+motion proposal by graph cuts.

Energy (over the labelling ``f``: segment -> proposal)::

    E(f) = sum_s D_s(f_s) + sum_(s,t) V_st(f_s, f_t)

* ``D_s(p)``: the census cost of proposal ``p`` on segment ``s``
  (:func:`~.data_term.data_costs`).
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

from ..geometry.camera import StereoCamera
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
