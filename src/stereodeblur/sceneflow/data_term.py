"""The fusion's data term: the census cost of every candidate proposal on every segment.

``D_s(p)`` (:mod:`fusion`'s energy): each (sampled) pixel of segment ``s`` in the left view at
t is matched in the right view at t, the left view at t + 1 and the right view at t + 1 at the
positions the plane and motion of ``p`` predict (:func:`prediction.predict`), costs per view in
[0, 1] (:mod:`census`); where a position leaves the image, what a wrong match would cost there
(:func:`census.wrong_match_cost`: near 0 in clean flat regions, about 0.5 in texture and in
noise), so that leaving the view is neither favoured nor penalised, also where noise makes every
match cost as much as a wrong one; where the point would lie behind a camera, the larger of that
and ``outside_cost`` per view; summed over the pixels of ``s`` (samples scaled to the full pixel
count). Optionally a position that leaves a view at t + 1 is matched on the frame on the other
side of t instead (``other_side``).
"""

from __future__ import annotations

import numba
import numpy as np

from .._threads import balanced_ranges, run_ranges
from ..geometry.camera import StereoCamera
from .census import census_cost_at, leave_cost, wrong_match_cost
from .fusion import ProposalSet
from .superpixels import SegmentGraph

__all__ = ["OTHER_SIDE_MARGIN", "data_costs", "sample_pixels"]

# Why: docs/defaults.md#other-side
OTHER_SIDE_MARGIN = 0.1
"""Census cost by which a match on the other side must undercut the cost of leaving the view to
replace it (:func:`data_costs`), so that near-zero differences of cost in flat regions do not
count."""

_MIN_WORK = 100000
"""Fewer candidate samples than this per range are not worth a thread (:func:`data_costs`)."""


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
                x1, y1 = _project(K, qx, qy, qz)
                d1 = fb * w / qz
                left = census_cost_at(code, lt1, x1, y1)
                right = census_cost_at(code, rt1, x1 - d1, y1)
                if left < 0 or right < 0:
                    near = leave_near[y, x] if dominant[p] else leave
                    # The other side: Q = R^T (P - T), scaled by the inverse depth w; NaN
                    # (never in view) where not asked for or behind the camera.
                    xo = yo = do = np.nan
                    if use_other:
                        ax, ay, az = rx - T[p, 0] * w, ry - T[p, 1] * w, rz - T[p, 2] * w
                        ox = R[p, 0, 0] * ax + R[p, 1, 0] * ay + R[p, 2, 0] * az
                        oy = R[p, 0, 1] * ax + R[p, 1, 1] * ay + R[p, 2, 1] * az
                        oz = R[p, 0, 2] * ax + R[p, 1, 2] * ay + R[p, 2, 2] * az
                        if oz > 1e-12:
                            xo, yo = _project(K, ox, oy, oz)
                            do = fb * w / oz
                    if left < 0:
                        left = _leaving(code, lt1, x1, y1, lo, xo, yo, leave, near, reach)
                    if right < 0:
                        right = _leaving(
                            code, rt1, x1 - d1, y1, ro, xo - do, yo, leave, near, reach
                        )
                total += left + right
            out[s, i] = total


@numba.njit(cache=True, nogil=True, inline="always")
def _project(K, qx, qy, qz):
    """Pixel ``(x, y)`` of the camera point ``(qx, qy, qz)``, ``qz > 0``."""
    return (
        (K[0, 0] * qx + K[0, 1] * qy + K[0, 2] * qz) / qz,
        (K[1, 0] * qx + K[1, 1] * qy + K[1, 2] * qz) / qz,
    )


@numba.njit(cache=True, nogil=True, inline="always")
def _leaving(code, target, x, y, other, xo, yo, leave, near, reach):
    """Cost of a sample whose position ``(x, y)`` leaves ``target``
    (:func:`census.leave_cost`), or of its match at ``(xo, yo)`` on the ``other`` side where
    that is lower by more than :data:`OTHER_SIDE_MARGIN`."""
    cost = leave_cost(target, x, y, leave, near, reach)
    c = census_cost_at(code, other, xo, yo)
    return c if 0 <= c < cost - OTHER_SIDE_MARGIN else cost
