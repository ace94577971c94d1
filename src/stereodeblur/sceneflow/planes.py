"""Robust planes of the disparity per group of pixels: RANSAC, then Cauchy-weighted IRLS.

Planes are left-view disparity coefficients ``(a, b, c)``, ``d = a x + b y + c``
(:mod:`stereodeblur.geometry.plane`); every group is fitted at once.
"""

from __future__ import annotations

import numba
import numpy as np

from .prediction import grouped

MIN_PLANE_PIXELS = 8


def fit_planes(
    groups: np.ndarray,
    num_groups: int,
    x: np.ndarray,
    y: np.ndarray,
    d: np.ndarray,
    *,
    rng: np.random.Generator,
    num_hypotheses: int = 24,
    inlier_threshold: float = 1.0,
    num_iterations: int = 4,
    scale: float = 0.5,
    ridge: float = 1e-3,
) -> tuple[np.ndarray, np.ndarray]:
    """Robust plane ``d = a x + b y + c`` per group: RANSAC, then Cauchy-weighted IRLS.

    Parameters
    ----------
    groups : ndarray of int, shape (N,)
        Group of every observation, in ``[0, num_groups)``.
    x, y, d : ndarray, shape (N,)
        Pixels and their (finite) disparities.
    rng : numpy.random.Generator
    num_hypotheses : int
        Random pixel triples per group (plus one constant plane at the median).
    inlier_threshold : float
        RANSAC inlier residual in pixels.
    num_iterations : int
        IRLS rounds after RANSAC.
    scale : float
        Cauchy scale of the IRLS weights in pixels.
    ridge : float
        Small penalty on the slopes ``(a, b)`` (per pixel squared, relative to
        the group's extent), so that collinear pixels give a stable plane.

    Returns
    -------
    abc : ndarray, shape (G, 3)
    ok : ndarray of bool, shape (G,)
        Groups with at least ``MIN_PLANE_PIXELS`` observations.
    """
    groups = np.asarray(groups, dtype=np.int64)
    x, y, d = (np.asarray(v, dtype=np.float64) for v in (x, y, d))
    counts = np.bincount(groups, minlength=num_groups)
    ok = counts >= MIN_PLANE_PIXELS
    abc = np.zeros((num_groups, 3))
    if len(d) == 0:
        return abc, ok
    # Group centres: fit in centred coordinates for conditioning.
    cnt = np.maximum(counts, 1)
    cx = np.bincount(groups, x, num_groups) / cnt
    cy = np.bincount(groups, y, num_groups) / cnt
    xc, yc = x - cx[groups], y - cy[groups]
    hyp, valid = _hypotheses(groups, num_groups, xc, yc, d, ok, rng, num_hypotheses)
    inliers = _count_inliers(groups, num_groups, hyp, xc, yc, d, inlier_threshold)
    inliers[~valid] = -1
    best = np.argmax(inliers, axis=1)
    cur = hyp[np.arange(num_groups), best]
    extent = np.maximum(np.bincount(groups, xc * xc + yc * yc, num_groups) / cnt, 1.0)
    for _ in range(num_iterations):
        cur = _irls_step(
            groups,
            num_groups,
            cur,
            ok,
            xc,
            yc,
            d,
            extent,
            scale=scale,
            cutoff=8 * inlier_threshold,
            ridge=ridge,
        )
    # Back to image coordinates: d = a (x - cx) + b (y - cy) + c.
    abc = np.stack([cur[:, 0], cur[:, 1], cur[:, 2] - cur[:, 0] * cx - cur[:, 1] * cy], axis=1)
    abc[~ok] = 0.0
    return abc, ok


def _hypotheses(groups, num_groups, xc, yc, d, ok, rng, num_hypotheses):
    """Per group the constant plane at the median disparity and ``num_hypotheses`` planes
    through random pixel triples (centred coordinates); which of them are defined."""
    order, bounds = grouped(groups, num_groups)
    counts = np.diff(bounds)
    # Median disparity per group: the constant hypothesis.
    ds = d[order]
    gs = groups[order]
    sort2 = np.lexsort((ds, gs))
    mid = bounds[:-1] + np.maximum(counts - 1, 0) // 2
    median = np.where(counts > 0, ds[sort2][np.minimum(mid, len(ds) - 1)], 0.0)
    H = num_hypotheses
    members = np.flatnonzero(ok)
    hyp = np.zeros((num_groups, H + 1, 3))
    hyp[:, 0, 2] = median
    valid = np.zeros((num_groups, H + 1), dtype=bool)
    valid[:, 0] = counts > 0
    if len(members):
        pick = bounds[members][:, None, None] + (
            rng.random((len(members), H, 3)) * counts[members][:, None, None]
        ).astype(np.int64)
        idx = order[pick]  # (M, H, 3)
        A = np.stack([xc[idx], yc[idx], np.ones(idx.shape)], axis=-1)  # (M, H, 3, 3)
        det = np.linalg.det(A)
        good = np.abs(det) > 1e-6
        A_safe = np.where(good[..., None, None], A, np.eye(3))
        sol = np.linalg.solve(A_safe, d[idx][..., None])[..., 0]
        hyp[members, 1:] = sol
        valid[members, 1:] = good
    return hyp, valid


def _count_inliers(groups, num_groups, hyp, xc, yc, d, threshold):
    """Pixels of each group within ``threshold`` of each of its hypotheses, shape (G, H)."""
    return _inlier_counts(
        groups, np.ascontiguousarray(hyp), xc, yc, d, float(threshold), int(num_groups)
    )


@numba.njit(cache=True, nogil=True)
def _inlier_counts(groups, hyp, xc, yc, d, threshold, num_groups):
    num = hyp.shape[1]
    counts = np.zeros((num_groups, num))
    for n in range(len(groups)):
        k = groups[n]
        for h in range(num):
            r = abs(hyp[k, h, 0] * xc[n] + hyp[k, h, 1] * yc[n] + hyp[k, h, 2] - d[n])
            if r < threshold:
                counts[k, h] += 1.0
    return counts


def _irls_step(groups, num_groups, cur, ok, xc, yc, d, extent, *, scale, cutoff, ridge):
    """One Cauchy-weighted least-squares update of the planes ``cur`` (centred coordinates)."""
    m = _weighted_moments(groups, num_groups, cur, xc, yc, d, float(scale), float(cutoff))
    wsum = m[:, 5]
    lam = ridge * np.maximum(wsum, 1e-9) / extent
    N = np.empty((num_groups, 3, 3))
    N[:, 0, 0] = m[:, 0] + lam
    N[:, 0, 1] = N[:, 1, 0] = m[:, 1]
    N[:, 0, 2] = N[:, 2, 0] = m[:, 2]
    N[:, 1, 1] = m[:, 3] + lam
    N[:, 1, 2] = N[:, 2, 1] = m[:, 4]
    N[:, 2, 2] = wsum + 1e-9
    rhs = m[:, 6:9]
    solvable = ok & (wsum > 3)
    N[~solvable] = np.eye(3)
    sol = np.linalg.solve(N, rhs[..., None])[..., 0]
    return np.where(solvable[:, None], sol, cur)


@numba.njit(cache=True, nogil=True)
def _weighted_moments(groups, num_groups, cur, xc, yc, d, scale, cutoff):
    """Per group the sums of ``w (xc^2, xc yc, xc, yc^2, yc, 1, xc d, yc d, d)`` with the
    Cauchy weights ``w`` of the residuals to ``cur`` (0 from ``cutoff`` on)."""
    m = np.zeros((num_groups, 9))
    for n in range(len(groups)):
        k = groups[n]
        r = cur[k, 0] * xc[n] + cur[k, 1] * yc[n] + cur[k, 2] - d[n]
        a = r / scale
        w = 1.0 / (1.0 + a * a) if abs(r) < cutoff else 0.0
        m[k, 0] += w * xc[n] * xc[n]
        m[k, 1] += w * xc[n] * yc[n]
        m[k, 2] += w * xc[n]
        m[k, 3] += w * yc[n] * yc[n]
        m[k, 4] += w * yc[n]
        m[k, 5] += w
        m[k, 6] += w * xc[n] * d[n]
        m[k, 7] += w * yc[n] * d[n]
        m[k, 8] += w * d[n]
    return m
