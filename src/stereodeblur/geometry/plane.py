"""Planes as scaled normals and their relation to disparity.

A plane is the set of points ``P`` with ``P^T n = 1`` (paper Sec. 3), ``n`` in the
coordinates of the camera it is expressed in. For a rectified pair, inverse depth
on a plane is affine in the pixel, so disparity is ``d(x, y) = a x + b y + c`` with
``(a, b, c) = fx * baseline * K^-T n``.
"""

from __future__ import annotations

import numpy as np

from .camera import StereoCamera


def plane_from_disparity_coefficients(camera: StereoCamera, abc: np.ndarray) -> np.ndarray:
    """Scaled normal ``n`` of the plane whose disparity is ``a x + b y + c``, shape (..., 3)."""
    return np.asarray(abc, dtype=np.float64) @ camera.K / (camera.fx * camera.baseline)


def disparity_coefficients(camera: StereoCamera, n: np.ndarray) -> np.ndarray:
    """Coefficients ``(a, b, c)`` of the left-view disparity ``a x + b y + c`` of plane ``n``."""
    return camera.fx * camera.baseline * (np.asarray(n, dtype=np.float64) @ camera.K_inv)


def plane_disparity(
    camera: StereoCamera, n: np.ndarray, x: np.ndarray, y: np.ndarray
) -> np.ndarray:
    """Left-view disparity of plane ``n`` at pixels ``(x, y)``."""
    a, b, c = disparity_coefficients(camera, n)
    return a * x + b * y + c


def plane_in_view(n: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Plane ``n`` (left coordinates) in the coordinates of a camera centred at ``center``.

    The camera is a pure translation of the left one: ``P_c = P - center``.
    """
    n = np.asarray(n, dtype=np.float64)
    return n / (1.0 - n @ np.asarray(center, dtype=np.float64))


def move_plane(n: np.ndarray, R: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Plane ``n`` after the motion ``P' = R P + T``: ``n' = R n / (1 + n^T R^T T)``."""
    n = np.asarray(n, dtype=np.float64)
    Rn = R @ n
    return Rn / (1.0 + Rn @ T)
