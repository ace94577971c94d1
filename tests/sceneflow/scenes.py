"""Test scenes for the scene flow estimator, rendered here by ray casting.

A textured plane ``P^T n = 1`` (left-camera coordinates at frame t) moves by
``exp(s * twist)``. Every pixel of a view at instant ``s`` casts its ray from the
view's camera centre, meets the moved plane, and the hit is moved back to the
pose at t and projected into the left view at t, where the texture is a fixed
smooth random image. Blurred frames average several instants of the exposure.
This does not use the package's homographies or scene-flow model, so it is an
independent truth for them.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from stereodeblur.geometry import StereoCamera, move_plane, se3_exp

SIZE = (96, 128)  # (H, W)
CAMERA = StereoCamera([[100.0, 0.0, 63.5], [0.0, 100.0, 47.5], [0.0, 0.0, 1.0]], 0.3)


def texture_field(seed: int = 0, *, shape=(400, 480), offset=(150, 176)):
    """A smooth random texture over left-view coordinates at t, with a margin."""
    rng = np.random.default_rng(seed)
    field = np.zeros(shape)
    for sigma, amp in ((1.0, 0.4), (2.5, 1.0), (6.0, 1.0)):
        layer = ndimage.gaussian_filter(rng.standard_normal(shape), sigma)
        field += amp * layer / layer.std()
    field = np.clip(0.5 + 0.12 * field, 0.02, 0.98)

    def sample(u, v):
        return ndimage.map_coordinates(
            field, [v + offset[0], u + offset[1]], order=3, mode="mirror"
        )

    return sample


def render_views(
    normal, twist, *, camera=CAMERA, size=SIZE, seed=0, duty_cycle=0.5, num_instants=5
):
    """Blurred left/right frames at t and t + 1: dict ``(view, frame) -> (H, W) float32``."""
    sample = texture_field(seed)
    height, width = size
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    rays = np.stack([x, y, np.ones_like(x)], -1) @ camera.K_inv.T
    offsets = -duty_cycle / 2 + duty_cycle * (np.arange(num_instants) + 0.5) / num_instants
    out = {}
    for view in ("left", "right"):
        c = camera.center(view)
        for frame in (0, 1):
            acc = np.zeros(size)
            for s in frame + offsets:
                M = se3_exp(s * np.asarray(twist, dtype=np.float64))
                R, T = M[:3, :3], M[:3, 3]
                n_s = move_plane(np.asarray(normal, dtype=np.float64), R, T)
                lam = (1.0 - c @ n_s) / (rays @ n_s)
                P = c + rays * lam[..., None]
                P0 = (P - T) @ R  # back to the pose at t: R^T (P - T)
                q = P0 @ camera.K.T
                acc += sample(q[..., 0] / q[..., 2], q[..., 1] / q[..., 2])
            out[(view, frame)] = (acc / len(offsets)).astype(np.float32)
    return out


def frames(views):
    """The four frames in the estimator's argument order."""
    return views[("left", 0)], views[("right", 0)], views[("left", 1)], views[("right", 1)]
