"""Rectified stereo camera and exposure timing.

Conventions
-----------
Camera coordinates: x right, y down, z forward (OpenCV). Pixel centres sit at
integer coordinates, (0, 0) is the centre of the top-left pixel. Both rectified
views share ``K``; the right camera centre is at ``(baseline, 0, 0)`` in left
camera coordinates, so a point ``P`` projects to ``K P`` in the left view and to
``K (P - (baseline, 0, 0))`` in the right view, and disparity is
``d = fx * baseline / Z`` with ``x_right = x_left - d``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

VIEWS = ("left", "right")


_ROWS = 16384  # rows per matrix product: small enough for BLAS to stay on one thread

# A baseline beyond these bounds overflows depths and disparities downstream (metres: 1 um to
# 1000 km; in millimetres: 1 nm to 1 km).
BASELINE_RANGE = (1e-6, 1e6)
# Faster than any camera that blurs (high-speed cameras reach about 1e5 frames per second).
MAX_FRAME_RATE = 1e6


def apply_matrix(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v @ M.T``: ``M v`` for every 3-vector along the last axis of ``v``, shape (..., 3).

    The same matrix product, taken in blocks of rows: one tall 3-wide product makes a
    multi-threaded BLAS start threads that stall on a busy machine (100x slower).
    """
    v = np.asarray(v, dtype=np.float64)
    flat = np.ascontiguousarray(v).reshape(-1, 3)
    out = np.empty_like(flat)
    Mt = np.asarray(M, dtype=np.float64).T
    for start in range(0, len(flat), _ROWS):
        np.matmul(flat[start : start + _ROWS], Mt, out=out[start : start + _ROWS])
    return out.reshape(v.shape)


def pixel_rays(K_inv: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Viewing rays ``K^-1 (x, y, 1)`` of pixels, shape (..., 3)."""
    x = np.asarray(x, dtype=np.float64)
    return apply_matrix(K_inv, np.stack([x, y, np.ones_like(x)], axis=-1))


@dataclass(frozen=True)
class StereoCamera:
    """Intrinsics ``K`` shared by both rectified views and the baseline (scene units)."""

    K: np.ndarray
    baseline: float

    def __post_init__(self):
        K = np.asarray(self.K, dtype=np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise ValueError(f"K must be a finite 3x3 matrix, got {self.K!r}")
        if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
            raise ValueError(
                f"K must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, got {K.tolist()}"
            )
        if abs(K[1, 0]) > 0:
            raise ValueError(f"K[1][0] must be 0, got {K[1, 0]}")
        b = float(self.baseline)
        low, high = BASELINE_RANGE
        if not np.isfinite(b) or not low <= b <= high:
            raise ValueError(
                f"baseline must be a number in [{low:g}, {high:g}] scene units, "
                f"got {self.baseline!r}"
            )
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "baseline", b)

    @property
    def fx(self) -> float:
        return float(self.K[0, 0])

    @property
    def K_inv(self) -> np.ndarray:
        return np.linalg.inv(self.K)

    def center(self, view: str) -> np.ndarray:
        """Camera centre of ``view`` ('left' or 'right') in left-camera coordinates."""
        if view not in VIEWS:
            raise ValueError(f"view must be 'left' or 'right', got {view!r}")
        return np.array([self.baseline if view == "right" else 0.0, 0.0, 0.0])

    def depth_to_disparity(self, depth: np.ndarray) -> np.ndarray:
        """Disparity ``fx * baseline / Z`` in pixels."""
        return self.fx * self.baseline / np.asarray(depth)

    def disparity_to_depth(self, disparity: np.ndarray) -> np.ndarray:
        """Depth ``fx * baseline / d`` in scene units."""
        return self.fx * self.baseline / np.asarray(disparity)

    def backproject(self, x: np.ndarray, y: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Left-camera 3D points of left-view pixels ``(x, y)`` at ``depth``, shape (..., 3)."""
        return pixel_rays(self.K_inv, x, y) * np.asarray(depth)[..., None]

    def project(self, P: np.ndarray, view: str = "left") -> np.ndarray:
        """Pixel coordinates ``(..., 2)`` of left-camera points ``P`` in ``view``."""
        q = apply_matrix(self.K, np.asarray(P) - self.center(view))
        return q[..., :2] / q[..., 2:3]


@dataclass(frozen=True)
class Exposure:
    """Frame timing: frames per second and exposure time (seconds) of every frame.

    Frame i is exposed from ``i / frame_rate - exposure / 2`` to
    ``i / frame_rate + exposure / 2``.
    """

    frame_rate: float
    exposure: float

    def __post_init__(self):
        fr, ex = float(self.frame_rate), float(self.exposure)
        if not np.isfinite(fr) or not 0 < fr <= MAX_FRAME_RATE:
            raise ValueError(
                f"frame_rate must be a number in (0, {MAX_FRAME_RATE:g}] per second, "
                f"got {self.frame_rate!r}"
            )
        if not np.isfinite(ex) or ex < 0:
            raise ValueError(f"exposure must be a non-negative number, got {self.exposure!r}")
        if ex > 1.0 / fr * (1 + 1e-9):
            raise ValueError(
                f"exposure {ex} s is longer than the frame interval 1/frame_rate = {1 / fr:.6g} s"
            )
        object.__setattr__(self, "frame_rate", fr)
        object.__setattr__(self, "exposure", ex)

    @property
    def duty_cycle(self) -> float:
        """Exposure as a fraction of the frame interval (the paper's tau)."""
        return self.exposure * self.frame_rate

    def sample_fractions(self, num_samples: int) -> np.ndarray:
        """Midpoints of ``num_samples`` equal sub-intervals of ``[-tau/2, tau/2]``.

        Fractions of the frame interval relative to the frame's centre instant.
        """
        if num_samples < 1:
            raise ValueError(f"num_samples must be >= 1, got {num_samples}")
        tau = self.duty_cycle
        return -tau / 2 + tau * (np.arange(num_samples) + 0.5) / num_samples
