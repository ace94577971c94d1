"""Proposals that explain large parts of the image: the dominant motion and global planes.

A proposal is a plane and a rigid motion (:mod:`prediction` states the
conventions). Per-segment proposals come from :func:`planes.fit_planes` and
:func:`motions.fit_motions` (re-exported here). The disparity at t + 1 that a
motion must reproduce is the plane's disparity at t plus the *observed change* of
disparity (matched at t + 1 minus matched at t), so that a plane fitted slightly
off the matches does not turn into a spurious motion (a static scene stays static).

* The dominant motion (the camera's own motion in a mostly static scene):
  hypotheses from the segments' motions, scored by the pixels they explain,
  the best refined on its inliers over the whole image.
* Global proposals: sequential RANSAC over the segments' proposals; each a plane
  with its motion that explains a large part of the image, refitted on its pixels.
"""

from __future__ import annotations

import numpy as np

from ..geometry.camera import StereoCamera
from .motions import MIN_MOTION_PIXELS, fit_motions
from .planes import MIN_PLANE_PIXELS, fit_planes
from .prediction import correspondences, motion_residuals, predict, rays

__all__ = [
    "MIN_MOTION_PIXELS",
    "MIN_PLANE_PIXELS",
    "correspondences",
    "dominant_motion",
    "fit_motions",
    "fit_planes",
    "global_proposals",
    "motion_residuals",
    "predict",
    "rays",
]


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

    obs = (x, y, d, x1, y1, change)
    thresholds = (disparity_threshold, motion_threshold)
    for _ in range(max_count):
        idx = np.flatnonzero(active)
        if len(idx) < max(MIN_MOTION_PIXELS, min_fraction * total) or len(hypotheses) == 0:
            break
        sample = rng.choice(idx, size=min(num_samples, len(idx)), replace=False)
        hyp = rng.choice(hypotheses, size=min(num_hypotheses, len(hypotheses)), replace=False)
        good = _explained(
            camera,
            abc[hyp][:, None],
            R[hyp][:, None],
            T[hyp][:, None],
            sample[None],
            obs,
            thresholds,
        )
        best = hyp[int(np.argmax(good.sum(axis=1)))]
        a, Rm, Tm = _refit(camera, abc[best], R[best], T[best], idx, obs, thresholds, rng)
        members = idx[_explained(camera, a, Rm, Tm, idx, obs, thresholds)]
        if len(members) < min_fraction * total:
            break
        out_abc.append(a)
        out_R.append(Rm)
        out_T.append(Tm)
        active[members] = False
    if not out_abc:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return np.array(out_abc), np.array(out_R), np.array(out_T)


def _explained(camera, abc, R, T, idx, obs, thresholds):
    """Which pixels ``idx`` a proposal predicts within the disparity and motion thresholds."""
    x, y, d, x1, y1, change = obs
    disparity_threshold, motion_threshold = thresholds
    d0, px, py, pd = predict(camera, abc, R, T, x[idx], y[idx])
    e2 = (px - x1[idx]) ** 2 + (py - y1[idx]) ** 2
    dd = pd - d0 - change[idx]
    e2 = e2 + np.where(np.isfinite(dd), dd**2, 0.0)
    good = (np.abs(d0 - d[idx]) < disparity_threshold) & (e2 < motion_threshold**2)
    return good & np.isfinite(e2)


def _refit(camera, a, Rm, Tm, idx, obs, thresholds, rng):
    """Twice: refit the plane (IRLS) and the motion (Gauss-Newton) on the pixels explained."""
    x, y, d, x1, y1, change = obs
    for _ in range(2):
        members = idx[_explained(camera, a, Rm, Tm, idx, obs, thresholds)]
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
    return a, Rm, Tm
