"""Blur balancing: give frames t and t + 1 the same blur before matching them.

Under strong blur that changes between the frames (a near plane approaching fast)
matching the blurred frames directly is biased; :func:`cross_blur` blurs each
frame once more with the other frame's predicted blur, and
:func:`blur_length_change` says where the blur changes enough to make it worth
it. Conventions as in :mod:`prediction` (left view at t the reference).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

from ..geometry.camera import StereoCamera, pixel_rays
from .fusion import ProposalSet
from .prediction import predict


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
    finite = np.isfinite(px) & np.isfinite(py)
    finite &= (np.abs(np.where(finite, px, 0)) < 1e9) & (np.abs(np.where(finite, py, 0)) < 1e9)
    ix = np.rint(np.where(finite, px, -1.0)).astype(np.int64)
    iy = np.rint(np.where(finite, py, -1.0)).astype(np.int64)
    ok = finite & (ix >= 0) & (iy >= 0) & (ix < width) & (iy < height)
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
    P = pixel_rays(camera.K_inv, x, y).T * depth  # (3, N)
    half = duty_cycle / 2
    positions = []
    for u in (-half, half, 1 - half, 1 + half):
        M = se3_exp(u * twists)  # per proposal; Q = R P + T per pixel, row by row
        # Summed in the order numpy's einsum took on the transposed points, 0, 1, 2.
        Q = [
            M[g, i, 0] * P[0] + M[g, i, 1] * P[1] + M[g, i, 2] * P[2] + M[g, i, 3] for i in range(3)
        ]
        z = np.where(Q[2] > 1e-9, Q[2], np.nan)
        positions.append(np.stack([camera.fx * Q[0] / z, camera.K[1, 1] * Q[1] / z], axis=1))
    length_t = np.linalg.norm(positions[1] - positions[0], axis=1)
    length_t1 = np.linalg.norm(positions[3] - positions[2], axis=1)
    change = np.nan_to_num(length_t1 - length_t)
    if relative:
        change = change / np.maximum(np.nan_to_num(np.maximum(length_t, length_t1)), 1.0)
    return change.reshape(height, width)
