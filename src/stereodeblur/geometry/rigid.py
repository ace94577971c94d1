"""Rigid motions as twists, with an exact exponential and logarithm.

Conventions
-----------
A twist is a 6-vector ``xi = (v, omega)``: ``v`` the translational part and
``omega`` the rotation vector (axis times angle, radians). Its exponential is
the 4x4 rigid motion ``M = exp(xi^) = [[R, T], [0, 1]]`` (paper Eq. 1-2,
``M = exp(theta xi)`` with ``theta = |omega|``), acting on points as
``P' = R P + T``. The motion over a fraction ``s`` of the frame interval is
``exp(s xi^)`` (paper Eq. 2), so ``s = 1`` is the motion from frame t to
t + 1 and ``s = -0.5`` half a frame backwards.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_SMALL = 1e-6


def hat(omega: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix ``[omega]_x`` of a 3-vector (batched over leading axes)."""
    omega = np.asarray(omega)
    out = np.zeros(omega.shape[:-1] + (3, 3), dtype=omega.dtype)
    out[..., 0, 1] = -omega[..., 2]
    out[..., 0, 2] = omega[..., 1]
    out[..., 1, 0] = omega[..., 2]
    out[..., 1, 2] = -omega[..., 0]
    out[..., 2, 0] = -omega[..., 1]
    out[..., 2, 1] = omega[..., 0]
    return out


def _as_float(a) -> np.ndarray:
    """``a`` as a float array, float32 and float64 kept, anything else as float64."""
    a = np.asarray(a)
    return a if a.dtype in (np.float32, np.float64) else a.astype(np.float64)


def _coefficients(theta: np.ndarray):
    """``a = sin t / t``, ``b = (1 - cos t) / t^2``, ``c = (t - sin t) / t^3``, series near 0."""
    t2 = theta * theta
    small = theta < 1e-3
    ts = np.where(small, 1.0, theta)
    a = np.where(small, 1 - t2 / 6 + t2 * t2 / 120, np.sin(ts) / ts)
    b = np.where(small, 0.5 - t2 / 24 + t2 * t2 / 720, (1 - np.cos(ts)) / ts**2)
    c = np.where(small, 1 / 6 - t2 / 120 + t2 * t2 / 5040, (ts - np.sin(ts)) / ts**3)
    return a, b, c


def so3_exp(omega: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp([omega]_x)`` by Rodrigues' formula, shape ``(..., 3, 3)``."""
    omega = _as_float(omega)
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    a, b, _ = _coefficients(theta)
    W = hat(omega)
    eye = np.eye(3, dtype=omega.dtype)
    return (eye + a * W + b * (W @ W)).astype(omega.dtype)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix, exact for angles in [0, pi]."""
    R = _as_float(R)
    dtype = R.dtype
    Rd = R.astype(np.float64).reshape(-1, 3, 3)
    out = np.empty((Rd.shape[0], 3))
    for i, r in enumerate(Rd):
        out[i] = _so3_log_single(r)
    return out.reshape(R.shape[:-2] + (3,)).astype(dtype)


def _so3_log_single(R: np.ndarray) -> np.ndarray:
    cos = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2
    sin = np.linalg.norm(skew)
    theta = np.arctan2(sin, cos)
    if theta < 1e-3:
        # log R = theta/sin(theta) * skew, series of theta/sin(theta) in sin.
        return skew * (1 + sin**2 / 6 + 3 * sin**4 / 40)
    if np.pi - theta > 1e-3:
        return skew * (theta / sin)
    # Near pi: (R + R^T)/2 - cos I = (1 - cos) a a^T; take its best-conditioned column.
    S = (R + R.T) / 2 - cos * np.eye(3)
    k = int(np.argmax(np.diag(S)))
    axis = S[:, k] / np.sqrt(S[k, k])
    axis /= np.linalg.norm(axis)
    if axis @ skew < 0:
        axis = -axis
    return axis * theta


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """4x4 rigid motion ``exp(xi^)`` of twists ``xi = (v, omega)``, shape ``(..., 4, 4)``."""
    xi = _as_float(xi)
    v, omega = xi[..., :3], xi[..., 3:]
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    a, b, c = _coefficients(theta)
    W = hat(omega)
    W2 = W @ W
    eye = np.eye(3, dtype=xi.dtype)
    R = eye + a * W + b * W2
    V = eye + b * W + c * W2
    M = np.zeros(xi.shape[:-1] + (4, 4), dtype=xi.dtype)
    M[..., :3, :3] = R
    M[..., :3, 3] = (V @ v[..., None])[..., 0]
    M[..., 3, 3] = 1
    return M


def se3_log(M: np.ndarray) -> np.ndarray:
    """Twist ``(v, omega)`` of a 4x4 rigid motion, the inverse of :func:`se3_exp`."""
    M = _as_float(M)
    dtype = M.dtype
    R, T = M[..., :3, :3].astype(np.float64), M[..., :3, 3].astype(np.float64)
    omega = so3_log(R).astype(np.float64)
    theta = np.linalg.norm(omega, axis=-1)[..., None, None]
    W = hat(omega)
    t2 = theta * theta
    small = theta < 1e-3
    ts = np.where(small, 1.0, theta)
    # V^-1 = I - W/2 + (1/t^2) (1 - t sin t / (2 (1 - cos t))) W^2
    coef = np.where(
        small, 1 / 12 + t2 / 720, (1 - ts * np.sin(ts) / (2 * (1 - np.cos(ts)))) / ts**2
    )
    Vinv = np.eye(3) - W / 2 + coef * (W @ W)
    v = (Vinv @ T[..., None])[..., 0]
    return np.concatenate([v, omega], axis=-1).astype(dtype)


@dataclass(frozen=True)
class RigidMotion:
    """A rigid motion from frame t to t + 1, stored as a twist ``(v, omega)``.

    Parameters
    ----------
    twist : array_like, shape (6,)
        Translational part ``v`` (scene units) then rotation vector ``omega`` (radians).
    """

    twist: np.ndarray

    def __post_init__(self):
        xi = np.asarray(self.twist, dtype=np.float64).reshape(-1)
        if xi.shape != (6,) or not np.all(np.isfinite(xi)):
            raise ValueError(f"twist must be 6 finite numbers, got {self.twist!r}")
        object.__setattr__(self, "twist", xi)

    @classmethod
    def from_matrix(cls, M: np.ndarray) -> RigidMotion:
        """Motion whose exponential is the 4x4 matrix ``M``."""
        return cls(se3_log(np.asarray(M, dtype=np.float64)))

    @classmethod
    def from_rt(cls, R: np.ndarray, T: np.ndarray) -> RigidMotion:
        """Motion ``P' = R P + T``."""
        M = np.eye(4)
        M[:3, :3], M[:3, 3] = R, T
        return cls.from_matrix(M)

    def matrix(self, fraction: float = 1.0) -> np.ndarray:
        """4x4 matrix of the motion over ``fraction`` of the frame interval (paper Eq. 2)."""
        return se3_exp(fraction * self.twist)

    def rt(self, fraction: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and translation of the motion over ``fraction`` of the frame interval."""
        M = self.matrix(fraction)
        return M[:3, :3], M[:3, 3]
