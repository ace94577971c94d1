"""Scene flow fitted to ground-truth correspondences (``--motion-source gt``).

Every superpixel of the reference view gets the plane that fits its true
disparity at frame t and the rigid motion that maps its true 3D points at t to
their true 3D points at t + 1 (found through the true flow and the true
disparity at t + 1). Deblurring with it judges the blur model apart from
motion estimation.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..geometry.camera import StereoCamera
from ..geometry.plane import plane_from_disparity_coefficients
from ..geometry.rigid import se3_log
from .fitting import robust_fit_plane_disparity, robust_fit_rigid
from .model import SceneFlow


def default_num_segments(shape: tuple[int, int]) -> int:
    """About 1200 segments at 640x480, scaled with the image area (paper supplement B)."""
    return max(16, round(1200 * shape[0] * shape[1] / (640 * 480)))


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
    valid = valid0 & inside & np.isfinite(d1) & (d1 > 0)

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
    v0s, vs = valid0.ravel()[order], valid.ravel()[order]
    for k in range(num):
        s = slice(bounds[k], bounds[k + 1])
        m0, m = v0s[s], vs[s]
        if m0.sum() >= 3:
            abc = robust_fit_plane_disparity(xs[s][m0], ys[s][m0], ds[s][m0])
            normals[k] = plane_from_disparity_coefficients(camera, abc)
            has_plane[k] = True
        if m.sum() >= 3:
            R, T = robust_fit_rigid(Ps[s][m], Qs[s][m])
            M = np.eye(4)
            M[:3, :3], M[:3, 3] = R, T
            twists[k] = se3_log(M)
            has_motion[k] = True
    _fill_from_nearest(labels, normals, has_plane)
    _fill_from_nearest(labels, twists, has_motion)
    return SceneFlow(camera, labels, normals, twists, ~valid)


def _fill_from_nearest(labels: np.ndarray, params: np.ndarray, known: np.ndarray) -> None:
    """Give segments without a fit the parameters of the nearest segment with one (in place)."""
    if known.all() or not known.any():
        return
    _, (iy, ix) = ndimage.distance_transform_edt(~known[labels], return_indices=True)
    donor = labels[iy, ix]
    for k in np.flatnonzero(~known):
        params[k] = params[np.bincount(donor[labels == k]).argmax()]
