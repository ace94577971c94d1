"""Scene flow fitted to ground-truth correspondences (``--motion-source gt``).

Every superpixel of the reference view gets the plane that fits its true
disparity at frame t and the rigid motion that carries its true 3D points at t to
where the true flow projects them at t + 1. Deblurring with it judges the blur model
apart from motion estimation. Superpixels of the blurred image straddle object
boundaries; :func:`split_at_discontinuities` cuts them where the true disparity or flow
jumps, so that no segment has to fit two objects.

The motion is fitted to the projections (:func:`~.fitting.fit_rigid_to_projections`),
not to the 3D points at t + 1: those need the disparity at t + 1 where the point lands,
which a nearer surface hides there for every point it covers by then, so that such segments
would take a fit from few points or a neighbour's motion. Where some points are seen at
t + 1, their 3D fit picks which of a small patch's two nearly alike poses is kept. How close
the fit comes to the rendered flow: ``docs/defaults.md#true-motion-fit``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..geometry.camera import StereoCamera
from ..geometry.plane import plane_from_disparity_coefficients
from ..geometry.rigid import se3_log
from .fitting import fit_rigid_to_projections, robust_fit_plane_disparity, robust_fit_rigid
from .model import SceneFlow

FIT_VERSION = 2
"""Version of the fit, part of the signature of cached benchmark results with the true
motion: raise it whenever the fit changes."""


def default_num_segments(shape: tuple[int, int]) -> int:
    """About 1200 segments at 640x480, scaled with the image area (paper supplement B)."""
    return max(16, round(1200 * shape[0] * shape[1] / (640 * 480)))


def split_at_discontinuities(
    labels: np.ndarray,
    disparity: np.ndarray,
    flow: np.ndarray,
    *,
    disparity_jump: float = 1.0,
    flow_jump: float = 0.5,
    min_size: int = 20,
) -> np.ndarray:
    """Cut segments where the true disparity or flow jumps between 4-neighbours.

    A jump is a step between two neighbours beyond the smaller of the steps next to it
    along the same line: on one surface disparity and flow change smoothly, however
    steeply (the flow of a road under fast forward motion changes by more than 1 px per
    pixel near the image bottom; a fixed threshold cut it into single pixels). Two
    neighbouring pixels stay connected when they share a label and neither the disparity
    nor the flow jumps by more than ``disparity_jump`` / ``flow_jump`` px (pixels of unknown
    disparity connect to their segment); every connected component becomes a segment. A
    component smaller than ``min_size`` pixels (a sliver, too small for a rigid fit) joins
    the neighbouring larger one it differs least from across their border.

    Returns
    -------
    ndarray, int32, shape (H, W)
        Labels consecutive from 0.
    """
    H, W = labels.shape
    d = np.nan_to_num(np.asarray(disparity, dtype=np.float64))
    flow = np.asarray(flow, dtype=np.float64)
    index = np.arange(H * W).reshape(H, W)
    first, second, jump, same = [], [], [], []
    for axis in (1, 0):
        a = (slice(None), slice(None, -1)) if axis == 1 else (slice(None, -1), slice(None))
        b = (slice(None), slice(1, None)) if axis == 1 else (slice(1, None), slice(None))
        flow_step = np.linalg.norm(np.diff(flow, axis=axis), axis=-1)
        disparity_step = np.abs(np.diff(d, axis=axis))
        gap = np.maximum(
            _beyond_neighbours(flow_step, axis) / flow_jump,
            _beyond_neighbours(disparity_step, axis) / disparity_jump,
        )
        first.append(index[a].ravel())
        second.append(index[b].ravel())
        jump.append(gap.ravel())
        same.append((labels[a] == labels[b]).ravel() & (gap.ravel() <= 1))
    first, second = np.concatenate(first), np.concatenate(second)
    jump, same = np.concatenate(jump), np.concatenate(same)
    graph = coo_matrix(
        (np.ones(same.sum(), np.int8), (first[same], second[same])), shape=(H * W, H * W)
    )
    _, components = connected_components(graph, directed=False)
    sizes = np.bincount(components)
    # Slivers join the larger neighbouring part they differ least from.
    ca, cb = components[first], components[second]
    small = np.concatenate([ca, cb])
    big = np.concatenate([cb, ca])
    gap = np.concatenate([jump, jump])
    pick = (sizes[small] < min_size) & (sizes[big] >= min_size)
    order = np.lexsort((gap[pick], small[pick]))
    small, big = small[pick][order], big[pick][order]
    firsts = np.r_[True, small[1:] != small[:-1]] if small.size else small.astype(bool)
    target = np.arange(sizes.size)
    target[small[firsts]] = big[firsts]
    components = target[components]
    _, consecutive = np.unique(components, return_inverse=True)
    return consecutive.reshape(H, W).astype(np.int32)


def _beyond_neighbours(step: np.ndarray, axis: int) -> np.ndarray:
    """How far each step between neighbours along ``axis`` exceeds the smaller of the two
    steps beside it (the previous and the next along the same line; the edge repeats)."""
    pad = [(0, 0), (0, 0)]
    pad[axis] = (1, 1)
    padded = np.pad(step, pad, mode="edge")
    n = step.shape[axis]
    before = np.take(padded, np.arange(0, n), axis=axis)
    after = np.take(padded, np.arange(2, n + 2), axis=axis)
    return np.maximum(step - np.minimum(before, after), 0.0)


def _sample_smooth(
    image: np.ndarray, x: np.ndarray, y: np.ndarray, *, max_bend: float
) -> np.ndarray:
    """Bilinear samples of a disparity map; NaN next to holes and discontinuities.

    Disparity is affine on a plane, so a second difference above ``max_bend`` px
    marks a jump between surfaces; a sample there would mix them and is dropped.
    """
    H, W = image.shape
    pad = np.pad(image, 1, mode="edge")
    with np.errstate(invalid="ignore"):
        bend = np.maximum(
            np.abs(pad[1:-1, :-2] - 2 * image + pad[1:-1, 2:]),
            np.abs(pad[:-2, 1:-1] - 2 * image + pad[2:, 1:-1]),
        )
    bad = ~(bend <= max_bend)
    known = np.isfinite(x) & np.isfinite(y)  # unknown flow gives unknown positions
    x, y = np.where(known, x, 0.0), np.where(known, y, 0.0)
    x0 = np.clip(np.floor(x).astype(int), 0, W - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, H - 2)
    near_bad = bad[y0, x0] | bad[y0, x0 + 1] | bad[y0 + 1, x0] | bad[y0 + 1, x0 + 1]
    out = ndimage.map_coordinates(np.nan_to_num(image), [y, x], order=1, mode="nearest")
    return np.where(near_bad | ~known, np.nan, out)


def sceneflow_from_gt(
    camera: StereoCamera,
    disparity: np.ndarray,
    disparity_next: np.ndarray,
    flow: np.ndarray,
    labels: np.ndarray,
) -> SceneFlow:
    """Fit a plane and a rigid motion per segment to true correspondences of the left view.

    Parameters
    ----------
    camera : StereoCamera
    disparity, disparity_next : ndarray, shape (H, W)
        True left-view disparity at frames t and t + 1 (NaN where unknown).
    flow : ndarray, shape (H, W, 2)
        True left-view flow from t to t + 1.
    labels : ndarray of int, shape (H, W)
        Segments, consecutive from 0.

    Returns
    -------
    SceneFlow
        Occlusion marks pixels whose correspondence leaves the view or is unknown.
    """
    H, W = labels.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    x1, y1 = x + flow[..., 0], y + flow[..., 1]
    inside = (x1 >= 0) & (x1 <= W - 1) & (y1 >= 0) & (y1 <= H - 1)
    d1 = _sample_smooth(np.asarray(disparity_next, dtype=np.float64), x1, y1, max_bend=0.1)
    d0 = np.asarray(disparity, dtype=np.float64)
    valid0 = np.isfinite(d0) & (d0 > 0)
    valid = valid0 & inside & np.isfinite(d1) & (d1 > 0) & ~_hidden_next(d0, x1, y1, valid0)
    projected = valid0 & np.isfinite(x1) & np.isfinite(y1)  # in view or not, hidden or not

    num = int(labels.max()) + 1
    normals = np.zeros((num, 3))
    twists = np.zeros((num, 6))
    has_plane = np.zeros(num, dtype=bool)
    has_motion = np.zeros(num, dtype=bool)
    order = np.argsort(labels.ravel(), kind="stable")
    bounds = np.searchsorted(labels.ravel()[order], np.arange(num + 1))
    P = camera.backproject(x, y, camera.disparity_to_depth(np.where(valid0, d0, 1.0)))
    Q = camera.backproject(x1, y1, camera.disparity_to_depth(np.where(valid, d1, 1.0)))
    xs, ys, ds = x.ravel()[order], y.ravel()[order], d0.ravel()[order]
    Ps, Qs = P.reshape(-1, 3)[order], Q.reshape(-1, 3)[order]
    targets = np.column_stack([x1.ravel(), y1.ravel()])[order]
    v0s, ps, vs = valid0.ravel()[order], projected.ravel()[order], valid.ravel()[order]
    for k in range(num):
        s = slice(bounds[k], bounds[k + 1])
        m0, m, seen = v0s[s], ps[s], vs[s]
        if m0.sum() >= 3:
            abc = robust_fit_plane_disparity(xs[s][m0], ys[s][m0], ds[s][m0])
            normals[k] = plane_from_disparity_coefficients(camera, abc)
            has_plane[k] = True
        if m.sum() >= 4 and not _degenerate(Ps[s][m]):
            R, T = _fit_motion(Ps[s][m], targets[s][m], Ps[s][seen], Qs[s][seen], camera.K)
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = R, T
            twists[k] = se3_log(M)
            has_motion[k] = True
    _fill_from_nearest(labels, normals, has_plane)
    _fill_from_nearest(labels, twists, has_motion)
    return SceneFlow(camera, labels, normals, twists, ~valid)


def _fit_motion(P, xy, seen_P, seen_Q, K):
    """The rigid motion of a segment whose points ``P`` project to ``xy`` at t + 1: fitted to
    the projections, from SQPnP and, where some points are seen at t + 1 (``seen_P`` at
    ``seen_Q``), also from their 3D fit; of the two, the one nearer ``seen_Q``."""
    R, T = fit_rigid_to_projections(P, xy, K)
    if len(seen_P) < 3 or _degenerate(seen_P):
        return R, T
    other = fit_rigid_to_projections(P, xy, K, start=robust_fit_rigid(seen_P, seen_Q))

    def distance(motion):
        return np.median(np.linalg.norm(seen_P @ motion[0].T + motion[1] - seen_Q, axis=1))

    return min((R, T), other, key=distance)


def _hidden_next(disparity, x1, y1, known, *, jump: float = 1.0) -> np.ndarray:
    """Pixels whose point is covered at t + 1 by a nearer one landing on the same pixel.

    Forward z-buffer of the disparity at t along the flow; a pixel is hidden if a
    pixel more than ``jump`` px nearer lands within half a pixel of where it lands.
    """
    H, W = disparity.shape
    inside = known & (x1 > -0.5) & (x1 < W - 0.5) & (y1 > -0.5) & (y1 < H - 0.5)
    target = np.full((H, W), -1)
    target[inside] = np.rint(y1[inside]).astype(int) * W + np.rint(x1[inside]).astype(int)
    nearest = np.full(H * W, -np.inf)
    np.maximum.at(nearest, target[inside], disparity[inside])
    hidden = np.zeros((H, W), bool)
    hidden[inside] = nearest[target[inside]] > disparity[inside] + jump
    return hidden


def _degenerate(points: np.ndarray, *, ratio: float = 0.05) -> bool:
    """True if ``points`` (n, 3) lie nearly on a line: no unique rigid motion fits them."""
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(spread[1] <= ratio * spread[0])


def _fill_from_nearest(labels: np.ndarray, params: np.ndarray, known: np.ndarray) -> None:
    """Give segments without a fit the parameters of the nearest segment with one (in place)."""
    if known.all() or not known.any():
        return
    _, (iy, ix) = ndimage.distance_transform_edt(~known[labels], return_indices=True)
    donor = labels[iy, ix]
    for k in np.flatnonzero(~known):
        params[k] = params[np.bincount(donor[labels == k]).argmax()]
