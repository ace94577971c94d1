"""Continuous refinement of the chosen planes and motions on the images.

After fusion every segment carries one proposal; segments that chose the same
proposal share it. Each proposal's 9 parameters (plane ``(a, b, c)`` of the
disparity, motion update ``delta = (v, omega)``, applied as ``M <- exp(delta) M``)
are refined by Levenberg-Marquardt on the robust photometric error of its
pixels in the three other views::

    E(theta) = sum_x sum_v rho(I_v(p_v(x; theta)) - I_lt(x))
               + sum_x sum_i prior_i (g_i(x; theta) - g_i(x; theta_0))^2

with ``p_v`` the positions in the right view at t, the left view at t + 1 and
the right view at t + 1 (:func:`proposals.predict`), ``rho`` a Cauchy
penalty, and ``g = (d0, x1, y1, d1 - d0)`` the predicted disparity, position
at t + 1 and disparity change, whose change from the fused proposal
``theta_0`` is penalised: weakly for the plane, so that the images decide it,
and more for the motion, so that it does not absorb what a plane cannot fit
(a non-planar surface would otherwise get a spurious motion that moves its
disparity at t + 1 towards the right view's evidence). Images are first normalised by
their local mean and contrast (a Gaussian window), which removes gain and bias
differences between the views. A step is kept only where it lowers a
proposal's energy.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

from .._threads import balanced_ranges, run_ranges
from ..geometry.camera import StereoCamera
from ..geometry.rigid import so3_exp
from .fusion import ProposalSet
from .prediction import predict

VALID_MARGIN = 4  # px: distance of a match from the invalid parts of an image, for use


def normalise_contrast(image: np.ndarray, *, sigma: float = 4.0, floor: float = 0.02) -> np.ndarray:
    """``(I - G*I) / sqrt(G*(I - G*I)^2 + floor^2)``, then a light smoothing, float64."""
    image = np.asarray(image, dtype=np.float64)
    centred = image - ndimage.gaussian_filter(image, sigma)
    spread = np.sqrt(ndimage.gaussian_filter(centred**2, sigma) + floor**2)
    return ndimage.gaussian_filter(centred / spread, 0.7)


@numba.njit(inline="always")
def _bilinear(image, gx, gy, x, y, out):
    """Value and gradient of ``image`` at ``(x, y)``; False when outside."""
    height, width = image.shape
    if not (x >= 0.0 and y >= 0.0 and x <= width - 1 and y <= height - 1):
        return False
    x0 = min(int(x), width - 2)
    y0 = min(int(y), height - 2)
    fx = x - x0
    fy = y - y0
    w00 = (1 - fx) * (1 - fy)
    w01 = fx * (1 - fy)
    w10 = (1 - fx) * fy
    w11 = fx * fy
    out[0] = (
        w00 * image[y0, x0]
        + w01 * image[y0, x0 + 1]
        + w10 * image[y0 + 1, x0]
        + w11 * image[y0 + 1, x0 + 1]
    )
    out[1] = (
        w00 * gx[y0, x0] + w01 * gx[y0, x0 + 1] + w10 * gx[y0 + 1, x0] + w11 * gx[y0 + 1, x0 + 1]
    )
    out[2] = (
        w00 * gy[y0, x0] + w01 * gy[y0, x0 + 1] + w10 * gy[y0 + 1, x0] + w11 * gy[y0 + 1, x0 + 1]
    )
    return True


@numba.njit(inline="always")
def _moved(abc, R, T, k, x, y, rx, ry, rz, fb):
    """Disparity ``d0`` at t of pixel (x, y) on plane k, inverse depth ``w`` and the moved
    point ``q = R r + T w`` (the point at t + 1 over its depth at t)."""
    d0 = abc[k, 0] * x + abc[k, 1] * y + abc[k, 2]
    w = d0 / fb
    q0 = R[k, 0, 0] * rx + R[k, 0, 1] * ry + R[k, 0, 2] * rz + T[k, 0] * w
    q1 = R[k, 1, 0] * rx + R[k, 1, 1] * ry + R[k, 1, 2] * rz + T[k, 1] * w
    q2 = R[k, 2, 0] * rx + R[k, 2, 1] * ry + R[k, 2, 2] * rz + T[k, 2] * w
    return d0, w, q0, q1, q2


@numba.njit(inline="always")
def _prior_residuals(base, abc0, R0, T0, K, k, x, y, rx, ry, rz, fb, d0, x1, y1, d1):
    """Change of (d0, x1, y1, d1 - d0) from the fused proposal's prediction, into ``base``."""
    e0, w0, p0, p1, p2 = _moved(abc0, R0, T0, k, x, y, rx, ry, rz, fb)
    if p2 > 1e-9:
        base[0] = d0 - e0
        base[1] = x1 - (K[0, 0] * p0 + K[0, 1] * p1 + K[0, 2] * p2) / p2
        base[2] = y1 - (K[1, 0] * p0 + K[1, 1] * p1 + K[1, 2] * p2) / p2
        base[3] = (d1 - d0) - (fb * w0 / p2 - e0)
    else:
        base[:] = 0.0


@numba.njit(inline="always")
def _position_jacobian(pos, K, T, k, x, y, w, q0, q1, q2, x1, y1, d1, fb):
    """Derivatives of (d0, x1, y1, d1) by the 9 parameters (plane, v, omega), into ``pos``."""
    # d(x1, y1, d1)/dq.
    a00 = K[0, 0] / q2
    a01 = K[0, 1] / q2
    a02 = (K[0, 2] - x1) / q2
    a11 = K[1, 1] / q2
    a12 = (K[1, 2] - y1) / q2
    a22 = -d1 / q2
    # dq/dw = T (through the plane), dd1/dw adds fb / q2.
    dx_dw = a00 * T[k, 0] + a01 * T[k, 1] + a02 * T[k, 2]
    dy_dw = a11 * T[k, 1] + a12 * T[k, 2]
    dd_dw = a22 * T[k, 2] + fb / q2
    for j in range(9):
        pos[0, j] = 0.0
    pos[0, 0] = x
    pos[0, 1] = y
    pos[0, 2] = 1.0
    for j in range(3):
        c = pos[0, j] / fb
        pos[1, j] = dx_dw * c
        pos[2, j] = dy_dw * c
        pos[3, j] = dd_dw * c
    # Motion: dq/d(v) = w I; dq/d(omega_k) = e_k x q.
    pos[1, 3] = a00 * w
    pos[1, 4] = a01 * w
    pos[1, 5] = a02 * w
    pos[2, 3] = 0.0
    pos[2, 4] = a11 * w
    pos[2, 5] = a12 * w
    pos[3, 3] = 0.0
    pos[3, 4] = 0.0
    pos[3, 5] = a22 * w
    # e_x x q = (0, -q2, q1); e_y x q = (q2, 0, -q0); e_z x q = (-q1, q0, 0)
    pos[1, 6] = -a01 * q2 + a02 * q1
    pos[1, 7] = a00 * q2 - a02 * q0
    pos[1, 8] = -a00 * q1 + a01 * q0
    pos[2, 6] = -a11 * q2 + a12 * q1
    pos[2, 7] = -a12 * q0
    pos[2, 8] = a11 * q0
    pos[3, 6] = a22 * q1
    pos[3, 7] = -a22 * q0
    pos[3, 8] = 0.0


@numba.njit(inline="always")
def _add_prior_system(JtJ, Jtr, k, prior, pos, base, jp):
    """Add the prior's rows (d0, x1, y1 and the disparity change d1 - d0) to group k."""
    for p in range(9):
        jp[0, p] = pos[0, p]
        jp[1, p] = pos[1, p]
        jp[2, p] = pos[2, p]
        jp[3, p] = pos[3, p] - pos[0, p]
    for i in range(4):
        for p in range(9):
            Jtr[k, p] += prior[k, i] * jp[i, p] * base[i]
            for m in range(p, 9):
                JtJ[k, p, m] += prior[k, i] * jp[i, p] * jp[i, m]


@numba.njit(inline="always")
def _view_position(v, x, y, d0, x1, y1, d1):
    """Position of the match in view v: right at t, left at t + 1, right at t + 1."""
    if v == 0:
        return x - d0, y
    if v == 1:
        return x1, y1
    return x1 - d1, y1


@numba.njit(inline="always")
def _position_derivative(v, pos, p):
    """Derivative of the match position in view v by parameter p."""
    if v == 0:
        return -pos[0, p], 0.0
    if v == 1:
        return pos[1, p], pos[2, p]
    return pos[1, p] - pos[3, p], pos[2, p]


@numba.njit(inline="always")
def _photometric(energy, JtJ, Jtr, k, reference, views, position, pos, scale, want_system, buf):
    """Add one pixel's robust photometric energy in the three other views to group k's and,
    with ``want_system``, its Gauss-Newton terms."""
    targets, grads_x, grads_y, target_valid = views
    x, y, d0, x1, y1, d1 = position
    sample, jr = buf
    for v in range(3):
        px, py = _view_position(v, x, y, d0, x1, y1, d1)
        if not _bilinear(targets[v], grads_x[v], grads_y[v], px, py, sample):
            energy[k] += 1.0
            continue
        if not target_valid[v, int(py + 0.5), int(px + 0.5)]:
            energy[k] += 1.0
            continue
        r = sample[0] - reference
        a = r / scale
        energy[k] += np.log1p(a * a)
        if not want_system:
            continue
        wt = 1.0 / (1.0 + a * a) / (scale * scale)
        for p in range(9):
            dpx, dpy = _position_derivative(v, pos, p)
            jr[p] = sample[1] * dpx + sample[2] * dpy
        for p in range(9):
            Jtr[k, p] += wt * jr[p] * r
            for m in range(p, 9):
                JtJ[k, p, m] += wt * jr[p] * jr[m]


_MIN_PIXELS = 20000
"""Fewer pixels than this per range are not worth a thread (:func:`_accumulate`)."""


def _accumulate(pixels, ref, views, ref_valid, current, fused, camera, scale, prior, want_system):
    """Energy per group and, if ``want_system``, its Gauss-Newton normal equations (9 params).

    ``pixels = (groups, xs, ys)`` sorted by group, ``views = (targets, grads_x, grads_y,
    target_valid)``, ``current`` and ``fused`` are ``(abc, R, T)``, ``camera = (K, K_inv,
    fx * baseline)``. Ranges of whole groups run in parallel; every group's sums run over
    its pixels in their order, so the result does not depend on the ranges.
    """
    groups = pixels[0]
    num_groups = len(current[0])
    energy = np.zeros(num_groups)
    JtJ = np.zeros((num_groups, 9, 9))
    Jtr = np.zeros((num_groups, 9))
    bounds = np.searchsorted(groups, np.arange(num_groups + 1))
    parts = max(1, min(2 * numba.get_num_threads(), len(groups) // _MIN_PIXELS))
    ranges = [(int(bounds[a]), int(bounds[b])) for a, b in balanced_ranges(bounds, parts)]
    arguments = (ref, views, ref_valid, current, fused, camera, scale, prior, want_system)
    run_ranges(_accumulate_range, ranges, pixels, *arguments, energy, JtJ, Jtr)
    lower = np.tril_indices(9, -1)
    JtJ[:, lower[0], lower[1]] = JtJ[:, lower[1], lower[0]]
    return energy, JtJ, Jtr


@numba.njit(cache=True, nogil=True)
def _accumulate_range(
    first,
    last,
    pixels,
    ref,
    views,
    ref_valid,
    current,
    fused,
    camera,
    scale,
    prior,
    want_system,
    energy,
    JtJ,
    Jtr,
):
    """:func:`_accumulate`'s sums over pixels ``first .. last - 1`` (whole groups), added to
    ``energy``, ``JtJ`` (upper triangle) and ``Jtr``."""
    groups, xs, ys = pixels
    abc, R, T = current
    abc0, R0, T0 = fused
    K, Kinv, fb = camera
    buf = (np.zeros(3), np.zeros(9))
    pos = np.zeros((4, 9))  # rows: d0, x1, y1, d1 derivatives
    jp = np.zeros((4, 9))
    base = np.zeros(4)
    for n in range(first, last):
        k = groups[n]
        x = xs[n]
        y = ys[n]
        if not ref_valid[int(y), int(x)]:
            continue
        rx = Kinv[0, 0] * x + Kinv[0, 1] * y + Kinv[0, 2]
        ry = Kinv[1, 0] * x + Kinv[1, 1] * y + Kinv[1, 2]
        rz = Kinv[2, 0] * x + Kinv[2, 1] * y + Kinv[2, 2]
        d0, w, q0, q1, q2 = _moved(abc, R, T, k, x, y, rx, ry, rz, fb)
        if d0 <= 0:
            continue
        if q2 <= 1e-9:
            continue
        x1 = (K[0, 0] * q0 + K[0, 1] * q1 + K[0, 2] * q2) / q2
        y1 = (K[1, 0] * q0 + K[1, 1] * q1 + K[1, 2] * q2) / q2
        d1 = fb * w / q2
        _prior_residuals(base, abc0, R0, T0, K, k, x, y, rx, ry, rz, fb, d0, x1, y1, d1)
        for i in range(4):
            energy[k] += prior[k, i] * base[i] * base[i]
        if want_system:
            _position_jacobian(pos, K, T, k, x, y, w, q0, q1, q2, x1, y1, d1, fb)
            _add_prior_system(JtJ, Jtr, k, prior, pos, base, jp)
        _photometric(
            energy,
            JtJ,
            Jtr,
            k,
            ref[int(y), int(x)],
            views,
            (x, y, d0, x1, y1, d1),
            pos,
            scale,
            want_system,
            buf,
        )


def refine_proposals(
    camera: StereoCamera,
    images: list[np.ndarray],
    groups: np.ndarray,
    proposals: ProposalSet,
    *,
    num_iterations: int = 6,
    step: int = 2,
    scale: float = 0.25,
    plane_prior: float = 0.1,
    motion_prior: float = 1.0,
    prior_share: float | None = None,
    valid: list[np.ndarray] | None = None,
) -> ProposalSet:
    """Refine every proposal on the pixels that chose it (Levenberg-Marquardt, 9 parameters).

    Parameters
    ----------
    camera : StereoCamera
    images : list of 4 ndarray, shape (H, W)
        Grey left t, right t, left t + 1, right t + 1.
    groups : ndarray of int, shape (H, W)
        Index of the proposal of every pixel.
    proposals : ProposalSet
    num_iterations : int
    step : int
        Use pixels on a ``step`` grid.
    scale : float
        Cauchy scale of the normalised photometric residuals.
    plane_prior : float
        Weight of the squared change of the disparity at t (pixels).
    motion_prior : float
        Weight of the squared change of the position at t + 1 and of the
        disparity change from t to t + 1 (pixels).
    prior_share : float, optional
        If given, a proposal used on more than this share of the (grid) pixels has
        its motion prior scaled down to add up to that share: a large region's
        images outweigh the motion it started from.
    valid : list of 4 ndarray of bool, shape (H, W), optional
        Pixels of each image that may be used (e.g. from :func:`cross_blur`);
        default all.

    Returns
    -------
    ProposalSet
    """
    num = len(proposals)
    if num == 0 or num_iterations <= 0:
        return proposals
    normed = [normalise_contrast(im) for im in images]
    grads = [np.gradient(im) for im in normed[1:]]
    targets = np.stack(normed[1:])
    gy = np.stack([g[0] for g in grads])
    gx = np.stack([g[1] for g in grads])
    height, width = groups.shape
    if valid is None:
        valid = [np.ones((height, width), dtype=bool)] * 4
    ref_valid = np.ascontiguousarray(valid[0], dtype=np.bool_)
    target_valid = np.ascontiguousarray(np.stack(valid[1:]), dtype=np.bool_)
    yy, xx = np.mgrid[0:height:step, 0:width:step]
    gs = groups[yy, xx].ravel().astype(np.int64)
    xs, ys = xx.ravel().astype(np.float64), yy.ravel().astype(np.float64)
    if not all(np.all(v) for v in valid):
        # A fixed set of pixels: those whose three matches start well inside the valid
        # parts (pixels entering or leaving them would make the energy jump).
        keep = _usable(camera, proposals, gs, xs, ys, ref_valid, target_valid, VALID_MARGIN)
        gs, xs, ys = gs[keep], xs[keep], ys[keep]
    order = np.argsort(gs, kind="stable")  # by group, each group's pixels in grid order
    gs, xs, ys = gs[order], xs[order], ys[order]
    fb = camera.fx * camera.baseline
    abc0, R0, T0 = proposals.abc.copy(), proposals.R.copy(), proposals.T.copy()
    abc, R, T = abc0.copy(), R0.copy(), T0.copy()
    K, Kinv = camera.K, camera.K_inv
    prior = np.tile([plane_prior, motion_prior, motion_prior, motion_prior], (num, 1))
    if prior_share is not None:
        counts = np.bincount(gs, minlength=num)
        budget = prior_share * len(gs)
        prior[:, 1:] *= np.minimum(1.0, budget / np.maximum(counts, 1))[:, None]

    pixels = (gs, xs, ys)
    views = (targets, gx, gy, target_valid)
    fused = (abc0, R0, T0)
    cam = (K, Kinv, float(fb))

    def run(a, r, t, want):
        return _accumulate(
            pixels, normed[0], views, ref_valid, (a, r, t), fused, cam, float(scale), prior, want
        )

    return ProposalSet(*_levenberg_marquardt(run, abc, R, T, num_iterations))


def _levenberg_marquardt(run, abc, R, T, num_iterations):
    """Damped Gauss-Newton steps per proposal, each kept only where it lowers the energy.

    ``run(abc, R, T, want_system)`` returns the energy per proposal and, if asked, the
    normal equations."""
    damping = np.full(len(abc), 1e-3)
    current, JtJ, Jtr = run(abc, R, T, True)
    for iteration in range(num_iterations):
        diag = np.einsum("gii->gi", JtJ)
        A = JtJ + np.eye(9) * (damping[:, None] * diag + 1e-9)[:, :, None]
        delta = -np.linalg.solve(A, Jtr[..., None])[..., 0]
        new_abc = abc + delta[:, :3]
        dR = so3_exp(delta[:, 6:])
        new_R = dR @ R
        new_T = np.einsum("gij,gj->gi", dR, T) + delta[:, 3:6]
        # The trial's normal equations are those of the next step where it is kept (each
        # proposal's sums involve its own parameters only).
        last = iteration == num_iterations - 1
        trial, trial_JtJ, trial_Jtr = run(new_abc, new_R, new_T, not last)
        better = trial < current
        abc = np.where(better[:, None], new_abc, abc)
        R = np.where(better[:, None, None], new_R, R)
        T = np.where(better[:, None], new_T, T)
        damping = np.where(better, damping * 0.3, damping * 10)
        current = np.where(better, trial, current)
        JtJ = np.where(better[:, None, None], trial_JtJ, JtJ)
        Jtr = np.where(better[:, None], trial_Jtr, Jtr)
    return abc, R, T


def _usable(camera, proposals, groups, x, y, ref_valid, target_valid, margin):
    """Reference pixels valid themselves whose three predicted matches lie ``margin``
    pixels inside the valid parts of the other images."""

    inner = [ndimage.binary_erosion(v, iterations=margin, border_value=0) for v in target_valid]
    d0, x1, y1, d1 = predict(
        camera, proposals.abc[groups], proposals.R[groups], proposals.T[groups], x, y
    )
    keep = ref_valid[y.astype(np.int64), x.astype(np.int64)].copy()
    height, width = ref_valid.shape
    for mask, px, py in zip(inner, (x - d0, x1, x1 - d1), (y, y1, y1), strict=True):
        ok = np.isfinite(px) & np.isfinite(py)
        ix = np.clip(np.rint(np.where(ok, px, -1)), -1, width).astype(np.int64)
        iy = np.clip(np.rint(np.where(ok, py, -1)), -1, height).astype(np.int64)
        ok &= (ix >= 0) & (iy >= 0) & (ix < width) & (iy < height)
        inside = np.zeros_like(ok)
        inside[ok] = mask[iy[ok], ix[ok]]
        keep &= inside
    return keep
