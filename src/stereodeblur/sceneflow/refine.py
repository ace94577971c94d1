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

from ..geometry.camera import StereoCamera
from ..geometry.rigid import so3_exp
from .fusion import ProposalSet

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


@numba.njit(cache=True, nogil=True)
def _accumulate(
    groups,
    xs,
    ys,
    ref,
    targets,
    grads_x,
    grads_y,
    ref_valid,
    target_valid,
    abc,
    R,
    T,
    abc0,
    R0,
    T0,
    K,
    Kinv,
    fb,
    scale,
    prior,
    num_groups,
    want_system,
):
    """Energy per group and, if ``want_system``, its Gauss-Newton normal equations (9 params)."""
    energy = np.zeros(num_groups)
    JtJ = np.zeros((num_groups, 9, 9))
    Jtr = np.zeros((num_groups, 9))
    sample = np.zeros(3)
    pos = np.zeros((4, 9))  # rows: d0, x1, y1, d1 derivatives
    jp = np.zeros((4, 9))
    jr = np.zeros(9)
    base = np.zeros(4)
    for n in range(len(groups)):
        k = groups[n]
        x = xs[n]
        y = ys[n]
        if not ref_valid[int(y), int(x)]:
            continue
        rx = Kinv[0, 0] * x + Kinv[0, 1] * y + Kinv[0, 2]
        ry = Kinv[1, 0] * x + Kinv[1, 1] * y + Kinv[1, 2]
        rz = Kinv[2, 0] * x + Kinv[2, 1] * y + Kinv[2, 2]
        # Current prediction and its Jacobian.
        d0 = abc[k, 0] * x + abc[k, 1] * y + abc[k, 2]
        if d0 <= 0:
            continue
        w = d0 / fb
        q0 = R[k, 0, 0] * rx + R[k, 0, 1] * ry + R[k, 0, 2] * rz + T[k, 0] * w
        q1 = R[k, 1, 0] * rx + R[k, 1, 1] * ry + R[k, 1, 2] * rz + T[k, 1] * w
        q2 = R[k, 2, 0] * rx + R[k, 2, 1] * ry + R[k, 2, 2] * rz + T[k, 2] * w
        if q2 <= 1e-9:
            continue
        x1 = (K[0, 0] * q0 + K[0, 1] * q1 + K[0, 2] * q2) / q2
        y1 = (K[1, 0] * q0 + K[1, 1] * q1 + K[1, 2] * q2) / q2
        d1 = fb * w / q2
        # Prior reference: the fused proposal's prediction.
        e0 = abc0[k, 0] * x + abc0[k, 1] * y + abc0[k, 2]
        w0 = e0 / fb
        p0 = R0[k, 0, 0] * rx + R0[k, 0, 1] * ry + R0[k, 0, 2] * rz + T0[k, 0] * w0
        p1 = R0[k, 1, 0] * rx + R0[k, 1, 1] * ry + R0[k, 1, 2] * rz + T0[k, 1] * w0
        p2 = R0[k, 2, 0] * rx + R0[k, 2, 1] * ry + R0[k, 2, 2] * rz + T0[k, 2] * w0
        if p2 > 1e-9:
            base[0] = d0 - e0
            base[1] = x1 - (K[0, 0] * p0 + K[0, 1] * p1 + K[0, 2] * p2) / p2
            base[2] = y1 - (K[1, 0] * p0 + K[1, 1] * p1 + K[1, 2] * p2) / p2
            base[3] = (d1 - d0) - (fb * w0 / p2 - e0)
        else:
            base[:] = 0.0
        for i in range(4):
            energy[k] += prior[i] * base[i] * base[i]
        if want_system:
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
            # The prior's rows: d0, x1, y1 and the disparity change d1 - d0.
            for p in range(9):
                jp[0, p] = pos[0, p]
                jp[1, p] = pos[1, p]
                jp[2, p] = pos[2, p]
                jp[3, p] = pos[3, p] - pos[0, p]
            for i in range(4):
                for p in range(9):
                    Jtr[k, p] += prior[i] * jp[i, p] * base[i]
                    for m in range(p, 9):
                        JtJ[k, p, m] += prior[i] * jp[i, p] * jp[i, m]
        reference = ref[int(y), int(x)]
        for v in range(3):
            if v == 0:
                px = x - d0
                py = y
            elif v == 1:
                px = x1
                py = y1
            else:
                px = x1 - d1
                py = y1
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
                if v == 0:
                    dpx = -pos[0, p]
                    dpy = 0.0
                elif v == 1:
                    dpx = pos[1, p]
                    dpy = pos[2, p]
                else:
                    dpx = pos[1, p] - pos[3, p]
                    dpy = pos[2, p]
                jr[p] = sample[1] * dpx + sample[2] * dpy
            for p in range(9):
                Jtr[k, p] += wt * jr[p] * r
                for m in range(p, 9):
                    JtJ[k, p, m] += wt * jr[p] * jr[m]
    for k in range(num_groups):
        for p in range(9):
            for m in range(p):
                JtJ[k, p, m] = JtJ[k, m, p]
    return energy, JtJ, Jtr


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
    fb = camera.fx * camera.baseline
    abc0, R0, T0 = proposals.abc.copy(), proposals.R.copy(), proposals.T.copy()
    abc, R, T = abc0.copy(), R0.copy(), T0.copy()
    K, Kinv = camera.K, camera.K_inv
    damping = np.full(num, 1e-3)
    prior = np.array([plane_prior, motion_prior, motion_prior, motion_prior], dtype=np.float64)

    def run(a, r, t, want):
        return _accumulate(
            gs,
            xs,
            ys,
            normed[0],
            targets,
            gx,
            gy,
            ref_valid,
            target_valid,
            a,
            r,
            t,
            abc0,
            R0,
            T0,
            K,
            Kinv,
            fb,
            float(scale),
            prior,
            num,
            want,
        )

    current, JtJ, Jtr = run(abc, R, T, True)
    for _ in range(num_iterations):
        diag = np.einsum("gii->gi", JtJ)
        A = JtJ + np.eye(9) * (damping[:, None] * diag + 1e-9)[:, :, None]
        delta = -np.linalg.solve(A, Jtr[..., None])[..., 0]
        new_abc = abc + delta[:, :3]
        dR = so3_exp(delta[:, 6:])
        new_R = dR @ R
        new_T = np.einsum("gij,gj->gi", dR, T) + delta[:, 3:6]
        trial, _, _ = run(new_abc, new_R, new_T, False)
        better = trial < current
        abc = np.where(better[:, None], new_abc, abc)
        R = np.where(better[:, None, None], new_R, R)
        T = np.where(better[:, None], new_T, T)
        damping = np.where(better, damping * 0.3, damping * 10)
        current, JtJ, Jtr = run(abc, R, T, True)
    return ProposalSet(abc, R, T)


# --------------------------------------------------------------------------- blur balance


@numba.njit(cache=True, nogil=True)
def _average_along(image, group_map, homographies):
    """Mean of ``image`` at ``H_s x`` over the instants s of each pixel's group; validity."""
    height, width = image.shape
    num_samples = homographies.shape[1]
    out = np.zeros((height, width), dtype=np.float32)
    valid = np.ones((height, width), dtype=np.bool_)
    for y in range(height):
        for x in range(width):
            k = group_map[y, x]
            total = 0.0
            for s in range(num_samples):
                H = homographies[k, s]
                z = H[2, 0] * x + H[2, 1] * y + H[2, 2]
                if z <= 1e-12:
                    valid[y, x] = False
                    break
                px = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / z
                py = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / z
                if not (px >= 0.0 and py >= 0.0 and px <= width - 1 and py <= height - 1):
                    valid[y, x] = False
                    break
                x0 = min(int(px), width - 2)
                y0 = min(int(py), height - 2)
                fx = px - x0
                fy = py - y0
                total += (1 - fy) * ((1 - fx) * image[y0, x0] + fx * image[y0, x0 + 1]) + fy * (
                    (1 - fx) * image[y0 + 1, x0] + fx * image[y0 + 1, x0 + 1]
                )
            out[y, x] = total / num_samples if valid[y, x] else image[y, x]
    return out, valid


def _splat_groups(groups: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Group map of another image: each reference pixel's group at its rounded position
    there, holes filled from the nearest assigned pixel."""
    height, width = groups.shape
    ix = np.rint(px).astype(np.int64)
    iy = np.rint(py).astype(np.int64)
    ok = np.isfinite(px) & np.isfinite(py) & (ix >= 0) & (iy >= 0) & (ix < width) & (iy < height)
    ok &= (np.abs(px) < 1e9) & (np.abs(py) < 1e9)
    out = np.full((height, width), -1, dtype=np.int64)
    out[iy[ok], ix[ok]] = groups[ok]
    if (out < 0).all():
        return groups.astype(np.int64)
    hole = out < 0
    if hole.any():
        _, (ny, nx) = ndimage.distance_transform_edt(hole, return_indices=True)
        out = out[ny, nx]
    return out


def cross_blur(
    camera: StereoCamera,
    images: list[np.ndarray],
    groups: np.ndarray,
    proposals: ProposalSet,
    *,
    duty_cycle: float,
    num_samples: int | None = None,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Give the four frames the same blur: each frame t image blurred by frame t + 1's motion
    and vice versa, as predicted by the proposals.

    Frame t shows the sharp image blurred along the motion during its exposure,
    frame t + 1 along the (different) motion during its own; a fast approach makes
    the second blur longer. Matching such images directly is biased. Blurring each
    image once more with the other frame's blur (mapped into its own pixels by
    the proposal's plane and motion) gives, to first order, both the same blur::

        C_t(x)    = mean_s' B_t(G_{1+s'} G_1^-1 x)
        C_t+1(y)  = mean_s  B_t+1(G_1^-1 G_s G_1 y)

    with ``G_u`` the homography from the pixels at instant ``u`` (fractions of
    the frame interval from the centre of frame t) to those at the centre of
    frame t (:func:`~stereodeblur.geometry.homography.trajectory_homographies`),
    per view. Pixels of the right view and of frame t + 1 take the proposal of
    the reference pixel that the proposals map onto them.

    Parameters
    ----------
    camera : StereoCamera
    images : list of 4 ndarray, shape (H, W)
        Grey left t, right t, left t + 1, right t + 1.
    groups : ndarray of int, shape (H, W)
        Proposal of every reference pixel (left view, frame t).
    proposals : ProposalSet
    duty_cycle : float
        Exposure time over frame interval, in (0, 1].
    num_samples : int, optional
        Instants per exposure; default from the longest predicted blur (one per
        2 pixels, 4 to 32).

    Returns
    -------
    images : list of 4 ndarray, shape (H, W), float32
    valid : list of 4 ndarray of bool, shape (H, W)
        Pixels whose blur stays inside the image (the others keep their value).
    """
    from ..geometry.camera import Exposure
    from ..geometry.homography import trajectory_homographies
    from ..geometry.plane import plane_from_disparity_coefficients
    from .proposals import predict

    groups = np.asarray(groups, dtype=np.int64)
    height, width = groups.shape
    twists = proposals.twists()
    normals = plane_from_disparity_coefficients(camera, proposals.abc)
    yy, xx = np.mgrid[0:height, 0:width]
    x, y = xx.ravel().astype(np.float64), yy.ravel().astype(np.float64)
    g = groups.ravel()
    d0, x1, y1, d1 = predict(camera, proposals.abc[g], proposals.R[g], proposals.T[g], x, y)
    if num_samples is None:
        length = np.hypot(x1 - x, y1 - y) * duty_cycle
        longest = float(np.nanmax(length)) if np.isfinite(length).any() else 0.0
        num_samples = int(np.clip(np.ceil(longest / 2.0), 4, 32))
    # Fractions of an exposure of length duty_cycle centred on 0.
    fractions = Exposure(1.0, duty_cycle).sample_fractions(num_samples)
    maps = {
        "left_t": groups,
        "right_t": _splat_groups(groups, (x - d0).reshape(height, width), y.reshape(height, width)),
        "left_t1": _splat_groups(groups, x1.reshape(height, width), y1.reshape(height, width)),
        "right_t1": _splat_groups(
            groups, (x1 - d1).reshape(height, width), y1.reshape(height, width)
        ),
    }
    out, valid = [None] * 4, [None] * 4
    for view, (i_t, i_t1) in (("left", (0, 2)), ("right", (1, 3))):
        G = trajectory_homographies(
            camera, normals, twists, np.concatenate([fractions, 1.0 + fractions, [1.0]]), view
        )
        S = len(fractions)
        Gs, G1s, G1 = G[:, :S], G[:, S : 2 * S], G[:, -1]
        G1_inv = np.linalg.inv(G1)
        for i, H in (
            (i_t, G1s @ G1_inv[:, None]),
            (i_t1, G1_inv[:, None] @ Gs @ G1[:, None]),
        ):
            name = ("left_t", "right_t", "left_t1", "right_t1")[i]
            blurred, ok = _average_along(
                np.ascontiguousarray(images[i], dtype=np.float32),
                np.ascontiguousarray(maps[name]),
                np.ascontiguousarray(H),
            )
            out[i], valid[i] = blurred, ok
    return out, valid


def blur_length_change(
    camera: StereoCamera,
    groups: np.ndarray,
    proposals: ProposalSet,
    *,
    duty_cycle: float,
    relative: bool = False,
) -> np.ndarray:
    """Length of a reference pixel's blur path in frame t + 1 minus that in frame t (pixels;
    if ``relative``, over the longer of the two or 1 pixel)."""
    from ..geometry.rigid import se3_exp

    groups = np.asarray(groups, dtype=np.int64)
    height, width = groups.shape
    twists = proposals.twists()
    yy, xx = np.mgrid[0:height, 0:width]
    x, y = xx.ravel().astype(np.float64), yy.ravel().astype(np.float64)
    g = groups.ravel()
    abc = proposals.abc[g]
    d0 = np.maximum(abc[:, 0] * x + abc[:, 1] * y + abc[:, 2], 1e-6)
    depth = camera.fx * camera.baseline / d0
    P = (camera.K_inv @ np.stack([x, y, np.ones_like(x)]) * depth).T
    half = duty_cycle / 2
    positions = []
    for u in (-half, half, 1 - half, 1 + half):
        Mu = se3_exp(u * twists)[g]
        Q = np.einsum("nij,nj->ni", Mu[:, :3, :3], P) + Mu[:, :3, 3]
        z = np.where(Q[:, 2] > 1e-9, Q[:, 2], np.nan)
        positions.append(np.stack([camera.fx * Q[:, 0] / z, camera.K[1, 1] * Q[:, 1] / z], axis=1))
    length_t = np.linalg.norm(positions[1] - positions[0], axis=1)
    length_t1 = np.linalg.norm(positions[3] - positions[2], axis=1)
    change = np.nan_to_num(length_t1 - length_t)
    if relative:
        change = change / np.maximum(np.nan_to_num(np.maximum(length_t, length_t1)), 1.0)
    return change.reshape(height, width)


def _usable(camera, proposals, groups, x, y, ref_valid, target_valid, margin):
    """Reference pixels valid themselves whose three predicted matches lie ``margin``
    pixels inside the valid parts of the other images."""
    from .proposals import predict

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
