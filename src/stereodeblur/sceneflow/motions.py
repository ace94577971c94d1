"""Robust rigid motions per group of pixels from planes and observed correspondences.

Weighted Kabsch on the 3D correspondences (points from the plane at t, flow and
disparity at t + 1 for the point at t + 1), then Gauss-Newton on the image-space
residuals ``(x1, y1, d1)`` (position and disparity at t + 1) with Cauchy weights,
whose scale anneals from coarse to fine. Image-space residuals weigh far points
correctly, unlike 3D distances. Motions are ``Q = R P + T`` on left-camera points
from frame t to t + 1; updates are left-multiplicative, ``M <- exp(delta) M``.
"""

from __future__ import annotations

import numba
import numpy as np

from ..geometry.camera import StereoCamera
from ..geometry.rigid import so3_exp
from .prediction import group_sums, rays

MIN_MOTION_PIXELS = 12


def _kabsch(groups, num_groups, P, Q, w):
    """Weighted Kabsch per group: R, T minimising sum w |R P + T - Q|^2."""
    wsum = np.maximum(np.bincount(groups, w, num_groups), 1e-12)
    pm = group_sums(groups, num_groups, P * w[:, None]) / wsum[:, None]
    qm = group_sums(groups, num_groups, Q * w[:, None]) / wsum[:, None]
    Pc, Qc = P - pm[groups], Q - qm[groups]
    C = group_sums(groups, num_groups, (Pc[:, :, None] * Qc[:, None, :]) * w[:, None, None])
    U, _, Vt = np.linalg.svd(C)
    det = np.linalg.det(np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2))
    S = np.zeros((num_groups, 3, 3))
    S[:, 0, 0] = S[:, 1, 1] = 1.0
    S[:, 2, 2] = np.where(det < 0, -1.0, 1.0)
    R = np.swapaxes(Vt, 1, 2) @ S @ np.swapaxes(U, 1, 2)
    T = qm - np.einsum("gij,gj->gi", R, pm)
    return R, T


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
    has_xy = np.isfinite(x1) & np.isfinite(y1) & (d0 > 0)
    has_d = has_xy & np.isfinite(d1)
    ok = np.bincount(groups, has_xy, num_groups) >= MIN_MOTION_PIXELS
    r = rays(camera, x, y)
    w0 = np.where(d0 > 0, d0 / fb, 0.0)
    if init is None:
        R, T = _kabsch_start(camera, groups, num_groups, r, d0, x1, y1, d1, has_d)
    else:
        R, T = (np.array(a, dtype=np.float64) for a in init)
    sel = np.flatnonzero(has_xy)
    pixels = (
        groups[sel],
        np.ascontiguousarray(r[sel]),
        w0[sel],
        x1[sel],
        y1[sel],
        np.where(has_d[sel], d1[sel], np.nan),
    )
    for scale in scales:
        for _ in range(iterations_per_scale):
            R, T = _gauss_newton_step(
                camera, pixels, num_groups, R, T, ok, scale=scale, cutoff=cutoff, damping=damping
            )
    R = np.where(ok[:, None, None], R, np.eye(3))
    T = np.where(ok[:, None], T, 0.0)
    return R, T, ok


def _kabsch_start(camera, groups, num_groups, r, d0, x1, y1, d1, has_d):
    """Weighted Kabsch in 3D on the pixels with a known ``d1``, weights ~ 1/Z^2 (depth
    noise grows with Z^2); the identity for groups with too few of them."""
    fb = camera.fx * camera.baseline
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
    return R, T


def _gauss_newton_step(camera, pixels, num_groups, R, T, ok, *, scale, cutoff, damping):
    """One damped Gauss-Newton update ``M <- exp(delta) M`` of every group's motion.

    ``pixels`` is ``(groups, rays, inverse depths, x1, y1, d1)`` of the usable pixels."""
    g, rs, ws, xo, yo, do = pixels
    fb = camera.fx * camera.baseline
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
        camera.K,
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
    dR = so3_exp(delta[:, 3:].astype(np.float64))
    return dR @ R, np.einsum("gij,gj->gi", dR, T) + delta[:, :3]


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
