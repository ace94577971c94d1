"""Plane-induced homographies of rigid motions, for either view.

``H_t_from_ref`` maps a pixel of the view at the reference instant to the pixel
where the same scene point is seen after the motion ``P' = R P + T``:
``H = K (R + T n^T) K^-1`` with ``n`` the plane at the reference instant (paper
Sec. 3). Its inverse, ``H_ref_from_t``, is what blur formation samples (Eq. 4).
For the right view the plane and motion are first expressed in right-camera
coordinates (a translation by the baseline): ``n_r = n / (1 - b n_x)`` and
``T_r = T + (R - I) (b, 0, 0)``.
"""

from __future__ import annotations

import numpy as np

from .camera import StereoCamera
from .plane import plane_in_view
from .rigid import se3_exp


def motion_in_view(
    R: np.ndarray, T: np.ndarray, center: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Motion ``P' = R P + T`` (left coordinates) in a camera centred at ``center``."""
    c = np.asarray(center, dtype=np.float64)
    return R, T + (R - np.eye(3)) @ c


def homography(K: np.ndarray, R: np.ndarray, T: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``K (R + T n^T) K^-1`` for one motion and plane in the same camera's coordinates.

    Broadcasts over leading axes of ``R`` (..., 3, 3), ``T`` (..., 3) and ``n`` (..., 3).
    """
    G = R + T[..., :, None] * n[..., None, :]
    return K @ G @ np.linalg.inv(K)


def trajectory_homographies(
    camera: StereoCamera,
    normals: np.ndarray,
    twists: np.ndarray,
    fractions: np.ndarray,
    view: str = "left",
) -> np.ndarray:
    """``H_ref_from_t`` for every plane and sampled instant, shape (L, S, 3, 3).

    Parameters
    ----------
    camera : StereoCamera
    normals : ndarray, shape (L, 3)
        Scaled normals in left-camera coordinates at the reference instant.
    twists : ndarray, shape (L, 6)
        Motions from frame t to t + 1 (twists ``(v, omega)``).
    fractions : ndarray, shape (S,)
        Instants as fractions of the frame interval relative to the reference instant.
    view : {'left', 'right'}
        The view whose pixels the homographies act on.
    """
    normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    twists = np.asarray(twists, dtype=np.float64).reshape(-1, 6)
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1)
    c = camera.center(view)
    M = se3_exp(fractions[None, :, None] * twists[:, None, :])  # (L, S, 4, 4)
    R, T = M[..., :3, :3], M[..., :3, 3]
    n = np.stack([plane_in_view(ni, c) for ni in normals])[:, None, :]
    T = T + ((R - np.eye(3)) @ c)
    H_t_from_ref = homography(camera.K, R, T, np.broadcast_to(n, T.shape))
    return np.linalg.inv(H_t_from_ref)
