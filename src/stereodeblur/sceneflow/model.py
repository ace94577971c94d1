"""The piecewise-rigid scene flow: what estimation produces and blur formation consumes.

A label map over the reference view assigns every pixel a segment; each segment
is a 3D plane (scaled normal ``n``, ``P^T n = 1``, left-camera coordinates at
frame t) moving rigidly by a twist from frame t to t + 1 (see
:mod:`stereodeblur.geometry.rigid`). Flow is in pixels, ``(u, v)`` along x and y,
from the centre of frame t to the centre of frame t + 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import VIEWS, StereoCamera, pixel_rays
from ..geometry.homography import trajectory_homographies


@dataclass(frozen=True)
class SceneFlow:
    """Piecewise-rigid scene flow over one reference view.

    Parameters
    ----------
    camera : StereoCamera
    labels : ndarray of int, shape (H, W)
        Segment index of every pixel of the reference view, in ``[0, L)``.
    normals : ndarray, shape (L, 3)
        Scaled plane normals in left-camera coordinates at frame t.
    twists : ndarray, shape (L, 6)
        Rigid motions from frame t to t + 1, twists ``(v, omega)``.
    occlusion : ndarray of bool, shape (H, W)
        True where the pixel is occluded or leaves the view at t + 1.
    view : {'left', 'right'}
        The reference view the label map covers.
    """

    camera: StereoCamera
    labels: np.ndarray
    normals: np.ndarray
    twists: np.ndarray
    occlusion: np.ndarray
    view: str = "left"

    def __post_init__(self):
        labels = np.asarray(self.labels)
        if labels.ndim != 2 or not np.issubdtype(labels.dtype, np.integer):
            raise ValueError(
                f"labels must be a 2D integer array, got {labels.dtype} {labels.shape}"
            )
        normals = np.asarray(self.normals, dtype=np.float64).reshape(-1, 3)
        twists = np.asarray(self.twists, dtype=np.float64).reshape(-1, 6)
        if normals.shape[0] != twists.shape[0]:
            raise ValueError(f"{normals.shape[0]} planes but {twists.shape[0]} motions")
        if labels.size and (labels.min() < 0 or labels.max() >= normals.shape[0]):
            raise ValueError(
                f"labels must lie in [0, {normals.shape[0]}), got [{labels.min()}, {labels.max()}]"
            )
        if not (np.all(np.isfinite(normals)) and np.all(np.isfinite(twists))):
            raise ValueError("planes and motions must be finite")
        occlusion = np.asarray(self.occlusion, dtype=bool)
        if occlusion.shape != labels.shape:
            raise ValueError(f"occlusion has shape {occlusion.shape}, labels {labels.shape}")
        if self.view not in VIEWS:
            raise ValueError(f"view must be 'left' or 'right', got {self.view!r}")
        object.__setattr__(self, "labels", labels.astype(np.int32, copy=False))
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "twists", twists)
        object.__setattr__(self, "occlusion", occlusion)

    @property
    def shape(self) -> tuple[int, int]:
        return self.labels.shape

    @property
    def num_segments(self) -> int:
        return self.normals.shape[0]

    def points(self) -> np.ndarray:
        """Left-camera 3D point of every reference pixel at frame t, shape (H, W, 3).

        Computed once per scene flow (read-only; the geometry must not change in place).
        """
        return self._cached("points", self._points)

    def points_at(self, fraction: float) -> np.ndarray:
        """The reference pixels' 3D points after ``fraction`` of the frame interval
        (computed once per fraction, read-only)."""
        return self._cached(("points_at", float(fraction)), lambda: self._points_at(fraction))

    def _cached(self, key, compute) -> np.ndarray:
        cache = self.__dict__.setdefault("_geometry", {})
        if key not in cache:
            value = compute()
            value.flags.writeable = False
            cache[key] = value
        return cache[key]

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k != "_geometry"}

    def __setstate__(self, state):
        self.__dict__.update(state)

    def _points(self) -> np.ndarray:
        H, W = self.shape
        y, x = np.mgrid[0:H, 0:W].astype(np.float64)
        c = self.camera.center(self.view)
        rays = pixel_rays(self.camera.K_inv, x, y)
        # Plane in this view's coordinates: P_v^T n_v = 1 with n_v = n / (1 - n.c).
        n = self.normals[self.labels]
        n_v = n / (1.0 - n @ c)[..., None]
        depth = 1.0 / np.maximum(np.einsum("hwk,hwk->hw", rays, n_v), 1e-12)
        return rays * depth[..., None] + c

    def _points_at(self, fraction: float) -> np.ndarray:
        from ..geometry.rigid import se3_exp

        M = se3_exp(fraction * self.twists)  # (L, 4, 4); R P + T per pixel, row by row
        P = self.points()
        labels = self.labels
        # Summed in the order of numpy's einsum over j, (0 + 2) + 1, as before.
        rows = [
            (M[labels, i, 0] * P[..., 0] + M[labels, i, 2] * P[..., 2])
            + M[labels, i, 1] * P[..., 1]
            for i in range(3)
        ]
        return np.stack([row + M[labels, i, 3] for i, row in enumerate(rows)], axis=-1)

    def with_occlusion(self, occlusion: np.ndarray) -> SceneFlow:
        """The same scene flow with another occlusion mask (sharing the computed geometry)."""
        out = SceneFlow(self.camera, self.labels, self.normals, self.twists, occlusion, self.view)
        if "_geometry" in self.__dict__:
            out.__dict__["_geometry"] = self.__dict__["_geometry"]
        return out

    def disparity(self) -> np.ndarray:
        """Disparity of every reference pixel at frame t, pixels."""
        return self.camera.depth_to_disparity(self.points()[..., 2])

    def disparity_next(self) -> np.ndarray:
        """Disparity at frame t + 1 of the point seen at each reference pixel at t."""
        return self.camera.depth_to_disparity(self.points_at(1.0)[..., 2])

    def flow(self) -> np.ndarray:
        """2D flow of the reference view from frame t to t + 1, shape (H, W, 2)."""
        H, W = self.shape
        y, x = np.mgrid[0:H, 0:W].astype(np.float64)
        q = self.camera.project(self.points_at(1.0), self.view)
        return np.stack([q[..., 0] - x, q[..., 1] - y], axis=-1)

    def homographies(self, fractions: np.ndarray) -> np.ndarray:
        """``H_ref_from_t`` per segment and instant, shape (L, S, 3, 3)."""
        return trajectory_homographies(self.camera, self.normals, self.twists, fractions, self.view)

    def reversed(self) -> SceneFlow:
        """The same scene flow with every motion inverted (frame t to t - 1), sharing the
        points at frame t."""
        out = SceneFlow(
            self.camera, self.labels, self.normals, -self.twists, self.occlusion, self.view
        )
        points = self.__dict__.get("_geometry", {}).get("points")
        if points is not None:
            out.__dict__["_geometry"] = {"points": points}
        return out
