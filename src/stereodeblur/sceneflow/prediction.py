"""The piecewise-rigid model's predictions, and per-group sums over pixels.

A proposal is a plane and a rigid motion. Planes are held as left-view disparity
coefficients ``(a, b, c)``, ``d0 = a x + b y + c`` at frame t (see
:mod:`stereodeblur.geometry.plane`); motions as rotation ``R`` and translation
``T`` acting on left-camera points, ``Q = R P + T``, from frame t to t + 1.
Fits run on all groups of pixels at once (a group is a segment, a region of
segments, or the whole image): per-pixel terms are summed per group with
``bincount`` (:func:`group_sums`).
"""

from __future__ import annotations

import numpy as np

from ..geometry.camera import StereoCamera, apply_matrix, pixel_rays


def rays(camera: StereoCamera, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Viewing rays ``K^-1 (x, y, 1)`` of left-view pixels, shape (..., 3)."""
    return pixel_rays(camera.K_inv, x, y)


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
    p = apply_matrix(camera.K, q)
    x1 = np.where(ok, p[..., 0] / qz_safe, np.nan)
    y1 = np.where(ok, p[..., 1] / qz_safe, np.nan)
    d1 = np.where(ok, fb * w / qz_safe, np.nan)
    return d0, x1, y1, d1


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


def group_sums(groups: np.ndarray, num_groups: int, values: np.ndarray) -> np.ndarray:
    """Sum the trailing-axis-free values ``(N, ...)`` per group, shape (G, ...)."""
    shape = values.shape[1:]
    flat = values.reshape(len(values), int(np.prod(shape)))
    out = np.empty((num_groups, flat.shape[1]))
    for k in range(flat.shape[1]):
        out[:, k] = np.bincount(groups, flat[:, k], num_groups)
    return out.reshape((num_groups,) + shape)


def grouped(groups: np.ndarray, num_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices sorting ``groups`` (stable) and the bounds of each group in that order."""
    order = np.argsort(groups, kind="stable")
    bounds = np.searchsorted(groups[order], np.arange(num_groups + 1))
    return order, bounds
