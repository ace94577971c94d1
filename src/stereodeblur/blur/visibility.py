"""Which segment every pixel shows at every instant of the exposure (occlusion-aware blur).

A piecewise-rigid scene flow labels the pixels at the reference instant, and the
paper's operator (Eq. 3-4) lets every blurred pixel show its own segment for the
whole exposure. Near motion boundaries that is wrong: a moving surface sweeps
over the pixels next to it, and behind it a surface reappears that the reference
instant does not show. Here every instant gets the segment that covers the pixel
then, the nearest to the camera where several do.

Segment ``s`` covers pixel ``x`` at instant ``t`` if the reference pixel nearest to
``H_ref_from_t[s, t] x`` belongs to ``s``. Surfaces are ordered by their inverse
depth at that reference pixel: objects do not pass through each other within an
exposure, and the depth at the reference instant does not depend on how the
motion between the frames is split into rotation and translation (which is
ambiguous for a small planar patch). The candidates for a pixel are its own
segment and the segments that a z-buffered forward mapping of all reference
pixels to instant ``t`` puts at the pixel or its eight neighbours. A pixel no
segment covers shows, at that instant, a surface hidden at the reference instant
(:data:`HIDDEN`): the reference image holds nothing that explains it.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit

from ..geometry.camera import Exposure
from ..geometry.plane import plane_in_view
from ..sceneflow.model import SceneFlow
from . import _kernels
from .trajectories import homography_point

HIDDEN = -1
"""Label of a pixel that shows, at that instant, a surface hidden at the reference instant."""


@njit(**_kernels._JIT)
def _instants(
    first, last, ref_from_t, t_from_ref, inverse_depth, labels, own_labels, entering, out
):
    """Visible segment of every pixel at instants ``first .. last - 1``, into ``out``.

    ``own_labels``: each pixel's own segment; ``entering``: content from outside the
    reference image is the own segment's (else hidden)."""
    height, width = labels.shape
    nearest = np.empty((height, width), np.float64)
    splat = np.empty((height, width), np.int32)
    for t in range(first, last):
        # Forward z-buffer: the nearest segment mapped onto each pixel.
        nearest[:] = -np.inf
        splat[:] = HIDDEN
        for y in range(height):
            for x in range(width):
                s = labels[y, x]
                qx, qy = homography_point(t_from_ref, s, t, float(x), float(y))
                ix = np.int64(np.floor(qx + 0.5))
                iy = np.int64(np.floor(qy + 0.5))
                if 0 <= ix < width and 0 <= iy < height:
                    d = inverse_depth[s, 0] * x + inverse_depth[s, 1] * y + inverse_depth[s, 2]
                    if d > nearest[iy, ix]:
                        nearest[iy, ix] = d
                        splat[iy, ix] = s
        # Backward check of the candidates, the own segment first, then the splatted
        # segments of the 3 x 3 neighbourhood in row order; the nearest covering one wins
        # (the first of equals). A segment checked before is skipped: same verdict.
        for y in range(height):
            y0, y1 = max(y - 1, 0), min(y + 2, height)
            for x in range(width):
                x0, x1 = max(x - 1, 0), min(x + 2, width)
                own = own_labels[y, x]
                best, best_d, other = HIDDEN, -np.inf, HIDDEN
                if own >= 0:
                    d = _covering(ref_from_t, labels, inverse_depth, own, own, entering, t, x, y)
                    if d > best_d:
                        best_d, best = d, own
                for ny in range(y0, y1):
                    for nx in range(x0, x1):
                        c = splat[ny, nx]
                        if c < 0 or c == own or c == other or c == best:
                            continue
                        other = c
                        d = _covering(ref_from_t, labels, inverse_depth, c, own, entering, t, x, y)
                        if d > best_d:
                            best_d, best = d, c
                out[t, y, x] = best


@njit(cache=True, nogil=True, inline="always")
def _covering(ref_from_t, labels, inverse_depth, c, own, entering, t, x, y) -> float:
    """Inverse depth of segment ``c`` at pixel ``(x, y)`` at instant ``t`` if ``c`` covers
    it then (its reference pixel belongs to ``c``; outside the reference image only the own
    segment, and only with ``entering``), else -inf."""
    height, width = labels.shape
    px, py = homography_point(ref_from_t, c, t, float(x), float(y))
    ix = np.int64(np.floor(px + 0.5))
    iy = np.int64(np.floor(py + 0.5))
    if ix < 0 or iy < 0 or ix >= width or iy >= height:
        if c != own or not entering:  # entering the view: the own segment's
            return -np.inf
    elif labels[iy, ix] != c:
        return -np.inf
    return inverse_depth[c, 0] * px + inverse_depth[c, 1] * py + inverse_depth[c, 2]


def visible_labels(
    ref_from_t: np.ndarray, labels: np.ndarray, inverse_depth: np.ndarray, *, own=None
) -> np.ndarray:
    """Segment shown by every pixel at every instant.

    Parameters
    ----------
    ref_from_t : ndarray, shape (L, S, 3, 3)
        ``H_ref_from_t`` per segment and instant.
    labels : ndarray of int, shape (H, W)
        Segments at the reference instant.
    inverse_depth : ndarray, shape (L, 3)
        Inverse depth of segment ``s`` at reference pixel ``(x, y)`` is
        ``inverse_depth[s] . (x, y, 1)`` (any positive scale).
    own : ndarray of int, shape (H, W), optional
        The segment every pixel shows at the centre of another frame's exposure, whose
        instants ``ref_from_t`` then holds: the reference image holds nothing of what lies
        outside it (hidden). None: ``labels``, content entering the view is the pixel's own
        segment.

    Returns
    -------
    ndarray, shape (S, H, W)
        int16 (int32 from 32768 segments on); :data:`HIDDEN` where no segment of the
        reference instant covers the pixel.
    """
    ref_from_t = np.ascontiguousarray(ref_from_t, dtype=np.float64)
    t_from_ref = np.ascontiguousarray(np.linalg.inv(ref_from_t))
    labels = np.ascontiguousarray(labels, dtype=np.int32)
    entering = own is None
    own = labels if own is None else np.ascontiguousarray(own, dtype=np.int32)
    inverse_depth = np.ascontiguousarray(inverse_depth, dtype=np.float64)
    num_segments, num_samples = ref_from_t.shape[:2]
    dtype = np.int16 if num_segments <= np.iinfo(np.int16).max else np.int32
    out = np.empty((num_samples,) + labels.shape, dtype)
    parts = min(num_samples, 4 * numba.get_num_threads())
    bounds = np.linspace(0, num_samples, parts + 1).round().astype(int)
    ranges = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]
    args = ref_from_t, t_from_ref, inverse_depth, labels, own, entering, out
    _kernels.run_ranges(_instants, ranges, *args)
    return out


def sceneflow_visibility(
    sceneflow: SceneFlow, exposure: Exposure, num_samples: int, *, offset=0.0, own=None
) -> np.ndarray:
    """:func:`visible_labels` of ``sceneflow``'s view at ``offset + exposure.sample_fractions``.

    ``offset`` (frame intervals) and ``own``: the exposure of another frame, whose pixels show
    the segments ``own`` at its centre (:func:`visible_labels`).
    """
    homographies = sceneflow.homographies(offset + exposure.sample_fractions(num_samples))
    camera = sceneflow.camera
    center = camera.center(sceneflow.view)
    planes = np.stack([plane_in_view(n, center) for n in sceneflow.normals])
    return visible_labels(homographies, sceneflow.labels, planes @ camera.K_inv, own=own)


def hidden_fraction(visible: np.ndarray) -> np.ndarray:
    """Share of the instants at which each pixel shows a hidden surface, float32 (H, W)."""
    return np.mean(visible == HIDDEN, axis=0, dtype=np.float32)
