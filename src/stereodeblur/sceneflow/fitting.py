"""Least-squares fits of planes to disparities and rigid motions to 3D correspondences.

Planes are fitted in disparity space, where a 3D plane is the affine function
``d = a x + b y + c`` of the left-view pixel (see :mod:`stereodeblur.geometry.plane`).
Rigid motions ``Q = R P + T`` are fitted by the weighted Kabsch / Umeyama method
without scale, or to the projections of ``R P + T`` (:func:`fit_rigid_to_projections`).
The ``robust_*`` variants trim outliers by iterated refits on the points whose residual
is within a multiple of the median residual.
"""

from __future__ import annotations

import numpy as np


def fit_plane_disparity(x: np.ndarray, y: np.ndarray, d: np.ndarray, weights=None) -> np.ndarray:
    """Weighted least-squares ``(a, b, c)`` with ``d ~ a x + b y + c``.

    Needs at least 3 non-collinear points; fewer give a constant fit ``(0, 0, mean d)``.
    """
    x, y, d = (np.asarray(v, dtype=np.float64).ravel() for v in (x, y, d))
    w = np.ones_like(d) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if d.size == 0:
        raise ValueError("cannot fit a plane to zero points")
    if d.size < 3:
        return np.array([0.0, 0.0, float(np.average(d, weights=w))])
    xm, ym = np.average(x, weights=w), np.average(y, weights=w)
    A = np.stack([x - xm, y - ym, np.ones_like(x)], axis=1) * np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(A, d * np.sqrt(w), rcond=1e-9)
    a, b, c = coef
    return np.array([a, b, c - a * xm - b * ym])


def fit_rigid(P: np.ndarray, Q: np.ndarray, weights=None) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation minimising ``sum w |R P + T - Q|^2`` (Kabsch, no scale)."""
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
    w = np.ones(len(P)) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if len(P) == 0:
        raise ValueError("cannot fit a rigid motion to zero points")
    w = w / w.sum()
    pm, qm = w @ P, w @ Q
    C = (P - pm).T @ ((Q - qm) * w[:, None])
    U, _, Vt = np.linalg.svd(C)
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ S @ U.T
    return R, qm - R @ pm


def robust_fit_plane_disparity(
    x, y, d, *, num_rounds: int = 3, scale: float = 3.0, floor: float = 0.25
):
    """Plane fit that drops points with residual > max(scale * median residual, floor) px."""
    x, y, d = (np.asarray(v, dtype=np.float64).ravel() for v in (x, y, d))
    keep = np.ones(d.size, dtype=bool)
    abc = fit_plane_disparity(x, y, d)
    for _ in range(num_rounds):
        r = np.abs(abc[0] * x + abc[1] * y + abc[2] - d)
        new = r <= max(scale * np.median(r), floor)
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
        abc = fit_plane_disparity(x[keep], y[keep], d[keep])
    return abc


def robust_fit_rigid(P, Q, *, num_rounds: int = 3, scale: float = 3.0, floor: float = 1e-3):
    """Rigid fit that drops pairs with residual > max(scale * median residual, floor)."""
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    Q = np.asarray(Q, dtype=np.float64).reshape(-1, 3)
    keep = np.ones(len(P), dtype=bool)
    R, T = fit_rigid(P, Q)
    for _ in range(num_rounds):
        r = np.linalg.norm(P @ R.T + T - Q, axis=1)
        new = r <= max(scale * np.median(r), floor)
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
        R, T = fit_rigid(P[keep], Q[keep])
    return R, T


def fit_rigid_to_projections(
    P: np.ndarray, xy: np.ndarray, K: np.ndarray, *, start=None
) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and translation whose ``K (R P + T)`` projects the points ``P`` (n, 3) to
    the pixels ``xy`` (n, 2): Levenberg-Marquardt on the reprojection error from ``start``
    ``(R, T)``, or from OpenCV's SQPnP (n >= 3) without one (from rest where SQPnP refuses
    points too close together).

    A small, nearly planar patch has two poses that project it almost alike (a tilt of the
    plane for a shift in depth); SQPnP may return either, a ``start`` near one keeps it.
    """
    import cv2

    P = np.ascontiguousarray(P, dtype=np.float64).reshape(-1, 3)
    xy = np.ascontiguousarray(xy, dtype=np.float64).reshape(-1, 2)
    K = np.asarray(K, dtype=np.float64)
    if len(P) < 3:
        raise ValueError(f"a rigid motion needs at least 3 projected points, got {len(P)}")
    if start is None:
        try:
            _, rvec, tvec = cv2.solvePnP(P, xy, K, None, flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:  # points nearly coincide (SQPnP's variance check): start at rest
            rvec, tvec = np.zeros((3, 1)), np.zeros((3, 1))
    else:
        rvec, tvec = cv2.Rodrigues(np.asarray(start[0], np.float64))[0], np.array(start[1], float)
    rvec, tvec = cv2.solvePnPRefineLM(P, xy, K, None, rvec, tvec.reshape(3, 1))
    return cv2.Rodrigues(rvec)[0], tvec.ravel()
