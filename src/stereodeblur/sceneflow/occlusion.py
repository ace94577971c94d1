"""Occlusion and motion-boundary masks of a piecewise-rigid scene flow (left view, t).

A pixel of the reference view is marked when its scene point cannot be followed
into frame t + 1 or when the blur model of a single plane does not hold there:

* ``out_of_view``: its position at t + 1 leaves the image;
* ``occluded``: at t + 1 another reference pixel lands within half a pixel of the
  same position with a disparity larger by more than ``depth_margin`` (z-buffer
  test on the scene flow's own prediction);
* ``inconsistent``: forward-backward check: the scene flow ``f(x)`` and the
  backward optical flow ``b`` at ``x + f(x)`` do not cancel (``|f + b| >
  max(1 px, 5 % |f|)``) and the initial forward flow disagrees with the scene
  flow there too;
* ``motion_boundary``: pixels within ``ceil(|df| / 2)`` pixels (1 to 10) of a
  border between segments whose flows differ by ``|df| > 0.5`` px: the band
  where a blurred pixel mixes the two motions when the exposure spans at most
  the whole frame interval.

The right view enters through ``left_right``: pixels whose point is hidden in the
right view at t by a nearer plane (a z-buffer test along the epipolar line).
It is reported, but not part of :attr:`OcclusionMasks.combined`, since the
reference view's blur does not depend on the other view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class OcclusionMasks:
    """Boolean (H, W) masks over the reference view; ``combined`` is their union
    without ``left_right``."""

    out_of_view: np.ndarray
    occluded: np.ndarray
    inconsistent: np.ndarray
    motion_boundary: np.ndarray
    left_right: np.ndarray

    @property
    def combined(self) -> np.ndarray:
        return self.out_of_view | self.occluded | self.inconsistent | self.motion_boundary


def _zbuffer_hidden(xt: np.ndarray, yt: np.ndarray, depth_key: np.ndarray, margin: float):
    """True where another point lands on the same rounded pixel with a ``depth_key`` larger
    by more than ``margin``."""
    height, width = xt.shape
    xi = np.rint(xt)
    yi = np.rint(yt)
    ok = np.isfinite(xi) & np.isfinite(yi) & (xi >= 0) & (xi < width) & (yi >= 0) & (yi < height)
    idx = np.where(ok, yi * width + xi, 0).astype(np.int64)
    best = np.full(height * width, -np.inf)
    np.maximum.at(best, idx[ok], depth_key[ok])
    return ok & (best[idx] > depth_key + margin)


def motion_boundary_band(
    labels: np.ndarray, flow: np.ndarray, *, threshold: float = 0.5, max_radius: int = 10
) -> np.ndarray:
    """Pixels within ``ceil(|df| / 2)`` of a segment border with flow jump ``|df| > threshold``."""
    height, width = labels.shape
    seeds = np.zeros((height, width), dtype=bool)
    radius = np.zeros((height, width))
    for axis in (0, 1):
        a = [slice(None), slice(None)]
        b = [slice(None), slice(None)]
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        jump = np.linalg.norm(flow[a] - flow[b], axis=-1)
        mark = (labels[a] != labels[b]) & (jump > threshold)
        r = np.clip(np.ceil(jump / 2), 1, max_radius)
        for sl in (a, b):
            seeds[sl] |= mark
            radius[sl] = np.maximum(radius[sl], np.where(mark, r, 0))
    if not seeds.any():
        return seeds
    dist, (iy, ix) = ndimage.distance_transform_edt(~seeds, return_indices=True)
    return dist <= radius[iy, ix]


def occlusion_masks(
    disparity: np.ndarray,
    flow: np.ndarray,
    disparity_next: np.ndarray,
    labels: np.ndarray,
    *,
    backward_flow: np.ndarray | None = None,
    initial_flow: np.ndarray | None = None,
    depth_margin: float = 0.5,
    boundary_jump: float = 0.5,
) -> OcclusionMasks:
    """Occlusion masks of a scene flow given by its dense disparity, flow and disparity at t + 1.

    Parameters
    ----------
    disparity, disparity_next : ndarray, shape (H, W)
        Scene-flow disparity at t and of the same point at t + 1.
    flow : ndarray, shape (H, W, 2)
        Scene-flow 2D projection, t -> t + 1.
    labels : ndarray of int, shape (H, W)
    backward_flow : ndarray, shape (H, W, 2), optional
        Optical flow t + 1 -> t for the forward-backward check.
    initial_flow : ndarray, shape (H, W, 2), optional
        Optical flow t -> t + 1; pixels where it agrees with the scene flow are
        never marked inconsistent.
    depth_margin : float
        Disparity margin of the z-buffer tests, pixels.
    boundary_jump : float
        Flow jump (pixels) across a segment border that starts a motion-boundary band
        (:func:`motion_boundary_band`).
    """
    height, width = labels.shape
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    flow = np.nan_to_num(np.asarray(flow, dtype=np.float64))
    x1, y1 = x + flow[..., 0], y + flow[..., 1]
    out_of_view = ~((x1 >= -0.5) & (x1 <= width - 0.5) & (y1 >= -0.5) & (y1 <= height - 0.5))
    d1 = np.nan_to_num(np.asarray(disparity_next, dtype=np.float64), nan=-1.0)
    occluded = _zbuffer_hidden(x1, y1, d1, depth_margin) & ~out_of_view
    d0 = np.nan_to_num(np.asarray(disparity, dtype=np.float64), nan=-1.0)
    left_right = _zbuffer_hidden(x - d0, y, d0, depth_margin)
    inconsistent = np.zeros((height, width), dtype=bool)
    if backward_flow is not None:
        back = np.stack(
            [
                ndimage.map_coordinates(backward_flow[..., k], [y1, x1], order=1, mode="nearest")
                for k in (0, 1)
            ],
            axis=-1,
        )
        mag = np.linalg.norm(flow, axis=-1)
        bad = np.linalg.norm(flow + back, axis=-1) > np.maximum(1.0, 0.05 * mag)
        if initial_flow is not None:
            agree = np.linalg.norm(flow - initial_flow, axis=-1) <= np.maximum(1.0, 0.05 * mag)
            bad &= ~agree
        inconsistent = bad & ~out_of_view
    boundary = motion_boundary_band(labels, flow, threshold=boundary_jump)
    return OcclusionMasks(
        out_of_view=out_of_view,
        occluded=occluded,
        inconsistent=inconsistent,
        motion_boundary=boundary,
        left_right=left_right,
    )
