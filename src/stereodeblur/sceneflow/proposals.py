"""Plane and rigid-motion proposals, fitted robustly per group of pixels.

A proposal is a plane and a rigid motion. Planes are held as left-view disparity
coefficients ``(a, b, c)``, ``d0 = a x + b y + c`` at frame t (see
:mod:`stereodeblur.geometry.plane`); motions as rotation ``R`` and translation
``T`` acting on left-camera points, ``Q = R P + T``, from frame t to t + 1.

Every fit runs on all groups at once (a group is a segment, a region of
segments, or the whole image): per-pixel terms are summed per group with
``bincount`` and the small normal equations are solved in a batch.

* Planes: RANSAC over random pixel triples of each group, then iteratively
  reweighted least squares (Cauchy weights) on the disparities.
* Motions: weighted Kabsch on the 3D correspondences (points from the plane at t,
  flow and disparity at t + 1 for the point at t + 1), then Gauss-Newton on the
  image-space residuals ``(x1, y1, d1)`` (position and disparity at t + 1) with
  Cauchy weights, whose scale anneals from coarse to fine. Image-space residuals
  weigh far points correctly, unlike 3D distances. The disparity at t + 1 that
  a motion must reproduce is the plane's disparity at t plus the *observed
  change* of disparity (matched at t + 1 minus matched at t), so that a plane
  fitted slightly off the matches does not turn into a spurious motion (a
  static scene stays static).
* The dominant motion (the camera's own motion in a mostly static scene):
  hypotheses from the segments' motions, scored by the pixels they explain,
  the best refined on its inliers over the whole image.
"""

from __future__ import annotations

import numba
import numpy as np

from ..geometry.camera import StereoCamera
from ..geometry.rigid import so3_exp

MIN_PLANE_PIXELS = 8
MIN_MOTION_PIXELS = 12


# --------------------------------------------------------------------------- the model


def rays(camera: StereoCamera, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Viewing rays ``K^-1 (x, y, 1)`` of left-view pixels, shape (..., 3)."""
    ones = np.ones_like(np.asarray(x, dtype=np.float64))
    return np.stack([x, y, ones], axis=-1) @ camera.K_inv.T


def predict(
    camera: StereoCamera,
    abc: np.ndarray,
    R: np.ndarray,
    T: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Disparity at t and position and disparity at t + 1 of left-view pixels.

    Parameters
    ----------
    camera : StereoCamera
    abc : ndarray, shape (..., 3)
        Plane disparity coefficients, broadcast against ``x``.
    R, T : ndarray, shapes (..., 3, 3) and (..., 3)
        Motion of each pixel's proposal.
    x, y : ndarray
        Pixels at frame t.

    Returns
    -------
    d0, x1, y1, d1 : ndarray
        ``d0`` the disparity at t, ``(x1, y1)`` the left-view position and ``d1``
        the disparity at t + 1. Non-finite where the point is not in front of
        the camera at t or at t + 1. The right-view positions are ``x - d0``
        at t and ``x1 - d1`` at t + 1.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    abc = np.asarray(abc, dtype=np.float64)
    d0 = abc[..., 0] * x + abc[..., 1] * y + abc[..., 2]
    fb = camera.fx * camera.baseline
    w = d0 / fb  # inverse depth at t
    # Q / Z = R r + T w: the moved point scaled by the inverse depth at t.
    q = np.einsum("...ij,...j->...i", R, rays(camera, x, y)) + T * w[..., None]
    qz = q[..., 2]
    ok = (d0 > 0) & (qz > 0)
    qz_safe = np.where(ok, qz, 1.0)
    p = q @ camera.K.T
    x1 = np.where(ok, p[..., 0] / qz_safe, np.nan)
    y1 = np.where(ok, p[..., 1] / qz_safe, np.nan)
    d1 = np.where(ok, fb * w / qz_safe, np.nan)
    return d0, x1, y1, d1


def _group_sums(groups: np.ndarray, num_groups: int, values: np.ndarray) -> np.ndarray:
    """Sum the trailing-axis-free values ``(N, ...)`` per group, shape (G, ...)."""
    shape = values.shape[1:]
    flat = values.reshape(len(values), int(np.prod(shape)))
    out = np.empty((num_groups, flat.shape[1]))
    for k in range(flat.shape[1]):
        out[:, k] = np.bincount(groups, flat[:, k], num_groups)
    return out.reshape((num_groups,) + shape)


def _grouped(groups: np.ndarray, num_groups: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(groups, kind="stable")
    bounds = np.searchsorted(groups[order], np.arange(num_groups + 1))
    return order, bounds


# --------------------------------------------------------------------------- planes


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
    order, bounds = _grouped(groups, num_groups)
    # Group centres: fit in centred coordinates for conditioning.
    cnt = np.maximum(counts, 1)
    cx = np.bincount(groups, x, num_groups) / cnt
    cy = np.bincount(groups, y, num_groups) / cnt
    xc, yc = x - cx[groups], y - cy[groups]

    # Median disparity per group: the constant hypothesis.
    ds = d[order]
    gs = groups[order]
    sort2 = np.lexsort((ds, gs))
    mid = bounds[:-1] + np.maximum(counts - 1, 0) // 2
    median = np.where(counts > 0, ds[sort2][np.minimum(mid, len(ds) - 1)], 0.0)

    # RANSAC hypotheses from random triples (in centred coordinates).
    H = num_hypotheses
    members = np.flatnonzero(ok)
    hyp = np.zeros((num_groups, H + 1, 3))
    hyp[:, 0, 2] = median
    valid_h = np.zeros((num_groups, H + 1), dtype=bool)
    valid_h[:, 0] = counts > 0
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
        valid_h[members, 1:] = good
    resid = np.abs(
        hyp[groups, :, 0] * xc[:, None]
        + hyp[groups, :, 1] * yc[:, None]
        + hyp[groups, :, 2]
        - d[:, None]
    )  # (N, H+1)
    inl = (resid < inlier_threshold).astype(np.float64)
    score = np.stack([np.bincount(groups, inl[:, h], num_groups) for h in range(H + 1)], axis=1)
    score[~valid_h] = -1
    best = np.argmax(score, axis=1)
    cur = hyp[np.arange(num_groups), best]

    # IRLS with Cauchy weights.
    extent = np.maximum(
        np.bincount(groups, xc * xc + yc * yc, num_groups) / cnt, 1.0
    )  # mean squared radius
    for _ in range(num_iterations):
        r = cur[groups, 0] * xc + cur[groups, 1] * yc + cur[groups, 2] - d
        w = 1.0 / (1.0 + (r / scale) ** 2)
        w = np.where(np.abs(r) < 8 * inlier_threshold, w, 0.0)
        m = _group_sums(
            groups,
            num_groups,
            np.stack(
                [
                    w * xc * xc,
                    w * xc * yc,
                    w * xc,
                    w * yc * yc,
                    w * yc,
                    w,
                    w * xc * d,
                    w * yc * d,
                    w * d,
                ],
                axis=1,
            ),
        )
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
        cur = np.where(solvable[:, None], sol, cur)
    # Back to image coordinates: d = a (x - cx) + b (y - cy) + c.
    abc = np.stack([cur[:, 0], cur[:, 1], cur[:, 2] - cur[:, 0] * cx - cur[:, 1] * cy], axis=1)
    abc[~ok] = 0.0
    return abc, ok


# --------------------------------------------------------------------------- motions


def _kabsch(groups, num_groups, P, Q, w):
    """Weighted Kabsch per group: R, T minimising sum w |R P + T - Q|^2."""
    wsum = np.maximum(np.bincount(groups, w, num_groups), 1e-12)
    pm = _group_sums(groups, num_groups, P * w[:, None]) / wsum[:, None]
    qm = _group_sums(groups, num_groups, Q * w[:, None]) / wsum[:, None]
    Pc, Qc = P - pm[groups], Q - qm[groups]
    C = _group_sums(groups, num_groups, (Pc[:, :, None] * Qc[:, None, :]) * w[:, None, None])
    U, _, Vt = np.linalg.svd(C)
    det = np.linalg.det(np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2))
    S = np.zeros((num_groups, 3, 3))
    S[:, 0, 0] = S[:, 1, 1] = 1.0
    S[:, 2, 2] = np.where(det < 0, -1.0, 1.0)
    R = np.swapaxes(Vt, 1, 2) @ S @ np.swapaxes(U, 1, 2)
    T = qm - np.einsum("gij,gj->gi", R, pm)
    return R, T


def correspondences(
    camera: StereoCamera,
    flow: np.ndarray,
    disparity_next: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Observed left-view position ``(x1, y1)`` and disparity ``d1`` at t + 1 of pixels.

    ``(x1, y1) = (x, y) + flow``; NaN where the flow leaves the image.
    ``d1`` is ``disparity_next`` sampled bilinearly at ``(x1, y1)``, NaN where
    unknown (any of the four neighbours is a hole).
    """
    from scipy import ndimage

    height, width = flow.shape[:2]
    x1 = x + flow[y, x, 0]
    y1 = y + flow[y, x, 1]
    inside = (x1 >= 0) & (x1 <= width - 1) & (y1 >= 0) & (y1 <= height - 1)
    x1 = np.where(inside, x1, np.nan)
    y1 = np.where(inside, y1, np.nan)
    d1 = ndimage.map_coordinates(
        np.asarray(disparity_next, dtype=np.float64),
        [np.nan_to_num(y1, nan=-10.0), np.nan_to_num(x1, nan=-10.0)],
        order=1,
        mode="constant",
        cval=np.nan,
    )
    d1 = np.where(inside & (d1 > 0), d1, np.nan)
    return x1, y1, d1


def fit_motions(
    camera: StereoCamera,
    groups: np.ndarray,
    num_groups: int,
    x: np.ndarray,
    y: np.ndarray,
    d0: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
    d1: np.ndarray,
    *,
    init: tuple[np.ndarray, np.ndarray] | None = None,
    scales: tuple[float, ...] = (4.0, 2.0, 1.0, 0.5),
    iterations_per_scale: int = 2,
    cutoff: float | None = None,
    damping: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust rigid motion per group from pixels with planes and observed correspondences.

    Parameters
    ----------
    camera : StereoCamera
    groups : ndarray of int, shape (N,)
    x, y, d0 : ndarray, shape (N,)
        Pixels at t and their disparity from the group's plane (must be > 0).
    x1, y1, d1 : ndarray, shape (N,)
        Observed position and disparity at t + 1, NaN where unknown.
    init : (R, T), optional
        Starting motions, shapes (G, 3, 3) and (G, 3); default: weighted Kabsch
        on the pixels with a known ``d1``.
    scales : tuple of float
        Cauchy scales (pixels) of the successive Gauss-Newton stages.
    iterations_per_scale : int
    cutoff : float, optional
        Pixels whose residual norm exceeds ``cutoff`` times the scale get zero
        weight (default: no cut-off, plain Cauchy weights of the residual norm).
    damping : float
        Levenberg-Marquardt damping relative to the normal matrix's diagonal.

    Returns
    -------
    R : ndarray, shape (G, 3, 3)
    T : ndarray, shape (G, 3)
    ok : ndarray of bool, shape (G,)
        Groups with at least ``MIN_MOTION_PIXELS`` usable observations.
    """
    groups = np.asarray(groups, dtype=np.int64)
    fb = camera.fx * camera.baseline
    K = camera.K
    has_xy = np.isfinite(x1) & np.isfinite(y1) & (d0 > 0)
    has_d = has_xy & np.isfinite(d1)
    ok = np.bincount(groups, has_xy, num_groups) >= MIN_MOTION_PIXELS
    r = rays(camera, x, y)
    w0 = np.where(d0 > 0, d0 / fb, 0.0)
    if init is None:
        # Weighted Kabsch in 3D with weights ~ 1/Z^2 (depth noise grows with Z^2).
        sel = has_d
        g = groups[sel]
        Z0 = fb / d0[sel]
        P = r[sel] * Z0[:, None]
        Zq = fb / d1[sel]
        Q = rays(camera, x1[sel], y1[sel]) * Zq[:, None]
        wk = (d0[sel] / fb) ** 2
        R, T = _kabsch(g, num_groups, P, Q, wk)
        few = np.bincount(g, minlength=num_groups) < MIN_MOTION_PIXELS
        R[few] = np.eye(3)
        T[few] = 0.0
    else:
        R, T = (np.array(a, dtype=np.float64) for a in init)
    sel = np.flatnonzero(has_xy)
    g = groups[sel]
    rs = np.ascontiguousarray(r[sel])
    ws = w0[sel]
    xo, yo = x1[sel], y1[sel]
    do = np.where(has_d[sel], d1[sel], np.nan)
    for scale in scales:
        for _ in range(iterations_per_scale):
            JtJ, Jtr = _motion_normal_equations(
                g,
                num_groups,
                rs,
                ws,
                xo,
                yo,
                do,
                R,
                T,
                K,
                fb,
                float(scale),
                np.inf if cutoff is None else float(cutoff),
            )
            diag = np.einsum("gii->gi", JtJ)
            JtJ = JtJ + np.eye(6) * (damping * diag + 1e-12)[:, :, None]
            solvable = ok & (np.einsum("gii->g", JtJ) > 1e-9)
            JtJ[~solvable] = np.eye(6)
            Jtr[~solvable] = 0.0
            delta = -np.linalg.solve(JtJ, Jtr[..., None])[..., 0]
            # Left-multiplicative update: M <- exp(delta) M.
            dR = so3_exp(delta[:, 3:].astype(np.float64))
            R = dR @ R
            T = np.einsum("gij,gj->gi", dR, T) + delta[:, :3]
    R = np.where(ok[:, None, None], R, np.eye(3))
    T = np.where(ok[:, None], T, 0.0)
    return R, T, ok


@numba.njit(cache=True, nogil=True)
def _motion_normal_equations(g, num_groups, rays, w, xo, yo, do, R, T, K, fb, scale, cutoff):
    """Gauss-Newton normal equations per group for the motion update, each pixel weighted
    by the Cauchy function of its residual norm (zero beyond ``cutoff`` scales)."""
    JtJ = np.zeros((num_groups, 6, 6))
    Jtr = np.zeros((num_groups, 6))
    J = np.zeros((3, 6))
    dq = np.zeros((3, 3))
    res = np.zeros(3)
    for n in range(len(g)):
        k = g[n]
        q0 = R[k, 0, 0] * rays[n, 0] + R[k, 0, 1] * rays[n, 1] + R[k, 0, 2] * rays[n, 2]
        q1 = R[k, 1, 0] * rays[n, 0] + R[k, 1, 1] * rays[n, 1] + R[k, 1, 2] * rays[n, 2]
        q2 = R[k, 2, 0] * rays[n, 0] + R[k, 2, 1] * rays[n, 1] + R[k, 2, 2] * rays[n, 2]
        q0 += T[k, 0] * w[n]
        q1 += T[k, 1] * w[n]
        q2 += T[k, 2] * w[n]
        if q2 <= 1e-9:
            continue
        px = (K[0, 0] * q0 + K[0, 1] * q1 + K[0, 2] * q2) / q2
        py = (K[1, 0] * q0 + K[1, 1] * q1 + K[1, 2] * q2) / q2
        pd = fb * w[n] / q2
        res[0] = px - xo[n]
        res[1] = py - yo[n]
        has_d = not np.isnan(do[n])
        res[2] = pd - do[n] if has_d else 0.0
        # d prediction / d q.
        for j in range(3):
            dq[0, j] = K[0, j] / q2
            dq[1, j] = K[1, j] / q2
            dq[2, j] = 0.0
        dq[0, 2] -= px / q2
        dq[1, 2] -= py / q2
        dq[2, 2] = -pd / q2
        # d q / d delta = [w I, -[q]_x]; the columns of -[q]_x are e_k x q:
        # (0, -q2, q1), (q2, 0, -q0), (-q1, q0, 0).
        for i in range(3):
            J[i, 0] = dq[i, 0] * w[n]
            J[i, 1] = dq[i, 1] * w[n]
            J[i, 2] = dq[i, 2] * w[n]
            J[i, 3] = -dq[i, 1] * q2 + dq[i, 2] * q1
            J[i, 4] = dq[i, 0] * q2 - dq[i, 2] * q0
            J[i, 5] = -dq[i, 0] * q1 + dq[i, 1] * q0
        # One robust weight per pixel, from its whole residual: a pixel is an outlier
        # as a whole (another motion), not one coordinate at a time.
        a2 = (res[0] * res[0] + res[1] * res[1] + res[2] * res[2]) / (scale * scale)
        if a2 >= cutoff * cutoff:
            continue
        wt = 1.0 / (1.0 + a2)
        for i in range(3):
            if i == 2 and not has_d:
                continue
            for p in range(6):
                Jtr[k, p] += wt * J[i, p] * res[i]
                for m in range(p, 6):
                    JtJ[k, p, m] += wt * J[i, p] * J[i, m]
    for k in range(num_groups):
        for p in range(6):
            for m in range(p):
                JtJ[k, p, m] = JtJ[k, m, p]
    return JtJ, Jtr


def motion_residuals(
    camera: StereoCamera,
    abc: np.ndarray,
    R: np.ndarray,
    T: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
    d1: np.ndarray,
) -> np.ndarray:
    """Image-space residual norm at t + 1 of per-pixel proposals against observations.

    ``sqrt((x1' - x1)^2 + (y1' - y1)^2 + (d1' - d1)^2)`` with the disparity term
    left out where ``d1`` is unknown; inf where the prediction is undefined.
    """
    _, px, py, pd = predict(camera, abc, R, T, x, y)
    e2 = (px - x1) ** 2 + (py - y1) ** 2
    e2 = e2 + np.where(np.isfinite(d1), (pd - d1) ** 2, 0.0)
    return np.where(np.isfinite(e2), np.sqrt(np.abs(e2)), np.inf)


def dominant_motion(
    camera: StereoCamera,
    abc: np.ndarray,
    R_segments: np.ndarray,
    T_segments: np.ndarray,
    candidates: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
    change: np.ndarray,
    *,
    rng: np.random.Generator,
    num_hypotheses: int = 48,
    num_samples: int = 4000,
    inlier_threshold: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The motion that explains the most pixels, refined on its inliers.

    Parameters
    ----------
    camera : StereoCamera
    abc : ndarray, shape (N, 3)
        Each pixel's plane (from its segment).
    R_segments, T_segments : ndarray, shapes (L, 3, 3), (L, 3)
        Segment motions, the hypotheses.
    candidates : ndarray of int
        Segments whose motion may serve as a hypothesis.
    x, y, x1, y1 : ndarray, shape (N,)
        Pixels and their observed positions at t + 1.
    change : ndarray, shape (N,)
        Observed disparity change from t to t + 1 (NaN where unknown); the
        disparity at t + 1 compared with is the plane's disparity plus this change.
    rng : numpy.random.Generator

    Returns
    -------
    R, T : ndarray
        The dominant motion.
    inlier_fraction : float
        Fraction of the pixels with a known correspondence that it explains.
    """
    d0_all = abc[:, 0] * x + abc[:, 1] * y + abc[:, 2]
    d1 = d0_all + change
    usable = np.isfinite(x1) & np.isfinite(y1) & (d0_all > 0)
    idx = np.flatnonzero(usable)
    if len(idx) < MIN_MOTION_PIXELS or len(candidates) == 0:
        return np.eye(3), np.zeros(3), 0.0
    sample = rng.choice(idx, size=min(num_samples, len(idx)), replace=False)
    hyps = rng.choice(candidates, size=min(num_hypotheses, len(candidates)), replace=False)
    # Score every hypothesis on the sample, plus the identity (a static scene).
    Rh = np.concatenate([R_segments[hyps], np.eye(3)[None]])
    Th = np.concatenate([T_segments[hyps], np.zeros((1, 3))])
    xs, ys = x[sample], y[sample]
    res = motion_residuals(
        camera,
        abc[sample][None],
        Rh[:, None],
        Th[:, None],
        xs[None],
        ys[None],
        x1[sample][None],
        y1[sample][None],
        d1[sample][None],
    )  # (Hyp, S)
    score = (res < inlier_threshold).sum(axis=1)
    best = int(np.argmax(score))
    R, T = Rh[best][None], Th[best][None]
    d0 = abc[idx, 0] * x[idx] + abc[idx, 1] * y[idx] + abc[idx, 2]
    zeros = np.zeros(len(idx), dtype=np.int64)
    # Refine on the inliers only (residual < inlier_threshold): Cauchy at half the
    # threshold, zero weight beyond it, so that other motions do not pull.
    R, T, _ = fit_motions(
        camera,
        zeros,
        1,
        x[idx],
        y[idx],
        d0,
        x1[idx],
        y1[idx],
        d1[idx],
        init=(R, T),
        scales=(inlier_threshold / 2,),
        iterations_per_scale=3,
        cutoff=2.0,
    )
    res = motion_residuals(camera, abc[idx], R[0], T[0], x[idx], y[idx], x1[idx], y1[idx], d1[idx])
    return R[0], T[0], float(np.mean(res < inlier_threshold))


def global_proposals(
    camera: StereoCamera,
    abc: np.ndarray,
    R: np.ndarray,
    T: np.ndarray,
    hypotheses: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    d: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
    change: np.ndarray,
    *,
    rng: np.random.Generator,
    max_count: int = 8,
    min_fraction: float = 0.02,
    num_hypotheses: int = 64,
    num_samples: int = 4000,
    disparity_threshold: float = 1.0,
    motion_threshold: float = 1.5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Planes with motions that explain large parts of the image, by sequential RANSAC.

    Each round scores segment proposals (plane and motion) by the pixels whose
    observed disparity at t and correspondence at t + 1 they predict within the
    thresholds, refits the best on all its inliers (plane by IRLS, motion by
    Gauss-Newton) and removes those pixels. A planar scene is one such proposal;
    large walls, the ground or a moving object are others.

    Parameters
    ----------
    camera : StereoCamera
    abc, R, T : ndarray, shapes (L, 3), (L, 3, 3), (L, 3)
        Segment proposals.
    hypotheses : ndarray of int
        Segments whose proposals may seed a round.
    x, y : ndarray, shape (N,)
        Pixels.
    d : ndarray, shape (N,)
        Observed disparity at t (NaN where unknown).
    x1, y1 : ndarray, shape (N,)
        Observed position at t + 1 (NaN where unknown).
    change : ndarray, shape (N,)
        Observed disparity change t -> t + 1 (NaN where unknown).
    rng : numpy.random.Generator
    max_count : int
        At most this many proposals.
    min_fraction : float
        Stop when the best proposal explains fewer than this fraction of the pixels.

    Returns
    -------
    abc, R, T : ndarray, shapes (K, 3), (K, 3, 3), (K, 3)
    """
    usable = np.isfinite(d) & np.isfinite(x1) & np.isfinite(y1)
    total = max(int(usable.sum()), 1)
    active = usable.copy()
    out_abc, out_R, out_T = [], [], []
    hypotheses = np.asarray(hypotheses, dtype=np.int64)

    def inliers(a, Rm, Tm, idx):
        d0, px, py, pd = predict(camera, a, Rm, Tm, x[idx], y[idx])
        e2 = (px - x1[idx]) ** 2 + (py - y1[idx]) ** 2
        dd = pd - d0 - change[idx]
        e2 = e2 + np.where(np.isfinite(dd), dd**2, 0.0)
        good = (np.abs(d0 - d[idx]) < disparity_threshold) & (e2 < motion_threshold**2)
        return good & np.isfinite(e2)

    for _ in range(max_count):
        idx = np.flatnonzero(active)
        if len(idx) < max(MIN_MOTION_PIXELS, min_fraction * total) or len(hypotheses) == 0:
            break
        sample = rng.choice(idx, size=min(num_samples, len(idx)), replace=False)
        hyp = rng.choice(hypotheses, size=min(num_hypotheses, len(hypotheses)), replace=False)
        good = inliers(abc[hyp][:, None], R[hyp][:, None], T[hyp][:, None], sample[None])
        best = hyp[int(np.argmax(good.sum(axis=1)))]
        a, Rm, Tm = abc[best], R[best], T[best]
        for _ in range(2):
            members = idx[inliers(a, Rm, Tm, idx)]
            if len(members) < MIN_MOTION_PIXELS:
                break
            zeros = np.zeros(len(members), dtype=np.int64)
            fitted, ok = fit_planes(
                zeros, 1, x[members], y[members], d[members], rng=rng, num_hypotheses=8
            )
            if ok[0]:
                a = fitted[0]
            d0 = a[0] * x[members] + a[1] * y[members] + a[2]
            Rn, Tn, mok = fit_motions(
                camera,
                zeros,
                1,
                x[members],
                y[members],
                d0,
                x1[members],
                y1[members],
                d0 + change[members],
                init=(Rm[None], Tm[None]),
                scales=(1.0, 0.5),
                iterations_per_scale=2,
            )
            if mok[0]:
                Rm, Tm = Rn[0], Tn[0]
        members = idx[inliers(a, Rm, Tm, idx)]
        if len(members) < min_fraction * total:
            break
        out_abc.append(a)
        out_R.append(Rm)
        out_T.append(Tm)
        active[members] = False
    if not out_abc:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return np.array(out_abc), np.array(out_R), np.array(out_T)
