"""Pictures of flows, disparities, segments and masks, as uint8 RGB arrays.

Every function is pure: it takes arrays and returns an ``(H, W, 3)`` uint8 image.

* Flow uses the Middlebury colour wheel (Baker et al., IJCV 2011) as in the
  Middlebury ``flowToColor`` code (angle ``atan2(-v, -u)``): the hue gives the
  direction, the saturation the magnitude relative to ``max_flow``; flow to the
  right ``(1, 0)`` is red, down ``(0, 1)`` yellow, left cyan-blue, up blue-violet;
  zero flow is white, beyond ``max_flow`` the colour is darkened, non-finite flow
  is black.
* Disparity uses the "turbo" colour map (Mikhailov 2019, polynomial fit): near
  (large disparity) is red, far is blue; holes (non-finite or <= 0) are black.
"""

from __future__ import annotations

import numpy as np

# Middlebury colour wheel: segment lengths red-yellow, yellow-green, ...
_WHEEL_SEGMENTS = (("RY", 15), ("YG", 6), ("GC", 4), ("CB", 11), ("BM", 13), ("MR", 6))


def color_wheel() -> np.ndarray:
    """The Middlebury colour wheel, shape (55, 3), float in [0, 255]."""
    ry, yg, gc, cb, bm, mr = (n for _, n in _WHEEL_SEGMENTS)
    wheel = np.zeros((ry + yg + gc + cb + bm + mr, 3))
    col = 0
    wheel[col : col + ry, 0] = 255
    wheel[col : col + ry, 1] = np.floor(255 * np.arange(ry) / ry)
    col += ry
    wheel[col : col + yg, 0] = 255 - np.floor(255 * np.arange(yg) / yg)
    wheel[col : col + yg, 1] = 255
    col += yg
    wheel[col : col + gc, 1] = 255
    wheel[col : col + gc, 2] = np.floor(255 * np.arange(gc) / gc)
    col += gc
    wheel[col : col + cb, 1] = 255 - np.floor(255 * np.arange(cb) / cb)
    wheel[col : col + cb, 2] = 255
    col += cb
    wheel[col : col + bm, 2] = 255
    wheel[col : col + bm, 0] = np.floor(255 * np.arange(bm) / bm)
    col += bm
    wheel[col : col + mr, 2] = 255 - np.floor(255 * np.arange(mr) / mr)
    wheel[col : col + mr, 0] = 255
    return wheel


def flow_to_color(flow: np.ndarray, *, max_flow: float | None = None) -> np.ndarray:
    """Middlebury colour coding of a flow field.

    Parameters
    ----------
    flow : ndarray, shape (H, W, 2)
        ``(u, v)`` in pixels.
    max_flow : float, optional
        Magnitude shown at full saturation; default the largest finite magnitude.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    flow = np.asarray(flow, dtype=np.float64)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise ValueError(f"flow must have shape (H, W, 2), got {flow.shape}")
    known = np.all(np.isfinite(flow), axis=-1)
    u = np.where(known, flow[..., 0], 0.0)
    v = np.where(known, flow[..., 1], 0.0)
    radius = np.hypot(u, v)
    if max_flow is None:
        max_flow = float(radius.max()) if radius.size else 0.0
    if not max_flow > 0:
        max_flow = 1.0
    u, v, radius = u / max_flow, v / max_flow, radius / max_flow
    wheel = color_wheel()
    ncols = len(wheel)
    angle = np.arctan2(-v, -u) / np.pi  # in [-1, 1]
    fk = (angle + 1) / 2 * (ncols - 1)
    k0 = np.floor(fk).astype(np.int64)
    k1 = (k0 + 1) % ncols
    f = (fk - k0)[..., None]
    col = ((1 - f) * wheel[k0] + f * wheel[k1]) / 255.0
    r = radius[..., None]
    inside = r <= 1
    col = np.where(inside, 1 - r * (1 - col), col * 0.75)
    out = np.floor(255 * col)
    out[~known] = 0
    return np.clip(out, 0, 255).astype(np.uint8)


# Turbo colour map: polynomial approximation (Mikhailov, Google AI blog 2019).
_TURBO_R = (0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943)
_TURBO_G = (0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604)
_TURBO_B = (0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973)


def _turbo(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    powers = np.stack([t**k for k in range(6)], axis=-1)
    rgb = np.stack([powers @ np.array(c) for c in (_TURBO_R, _TURBO_G, _TURBO_B)], axis=-1)
    return np.clip(rgb, 0.0, 1.0)


def disparity_to_color(
    disparity: np.ndarray, *, max_disparity: float | None = None, min_disparity: float = 0.0
) -> np.ndarray:
    """Turbo colour map of a disparity map (red near, blue far, black holes).

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Pixels; non-finite or <= 0 are holes.
    max_disparity, min_disparity : float
        Range mapped onto the colour map; default maximum: the largest known value.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    d = np.asarray(disparity, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"disparity must have shape (H, W), got {d.shape}")
    known = np.isfinite(d) & (d > 0)
    if max_disparity is None:
        max_disparity = float(d[known].max()) if known.any() else 1.0
    span = max(float(max_disparity) - float(min_disparity), 1e-12)
    t = (np.where(known, d, min_disparity) - min_disparity) / span
    rgb = np.rint(_turbo(t) * 255)
    rgb[~known] = 0
    return rgb.astype(np.uint8)


def _to_rgb_u8(image: np.ndarray) -> np.ndarray:
    a = np.asarray(image)
    if a.dtype != np.uint8:
        a = np.rint(np.clip(np.nan_to_num(a.astype(np.float64)), 0.0, 1.0) * 255).astype(np.uint8)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got {np.shape(image)}")
    return a


def segment_overlay(
    image: np.ndarray, labels: np.ndarray, *, color: tuple[int, int, int] = (255, 255, 0)
) -> np.ndarray:
    """``image`` (float in [0, 1] or uint8, grey or RGB) with segment boundaries drawn in ``color``.

    A pixel is drawn when its right or lower neighbour belongs to another segment
    (one-pixel lines).
    """
    rgb = _to_rgb_u8(image).copy()
    labels = np.asarray(labels)
    if labels.shape != rgb.shape[:2]:
        raise ValueError(f"labels have shape {labels.shape}, image {rgb.shape[:2]}")
    edge = np.zeros(labels.shape, dtype=bool)
    edge[:, :-1] |= labels[:, :-1] != labels[:, 1:]
    edge[:-1, :] |= labels[:-1, :] != labels[1:, :]
    rgb[edge] = color
    return rgb


def mask_to_image(
    mask: np.ndarray,
    image: np.ndarray | None = None,
    *,
    color: tuple[int, int, int] = (255, 0, 0),
    opacity: float = 0.6,
) -> np.ndarray:
    """A boolean mask as a picture: white on black, or tinted over ``image`` if given."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2:
        raise ValueError(f"mask must have shape (H, W), got {mask.shape}")
    if image is None:
        return np.repeat(np.where(mask, 255, 0).astype(np.uint8)[..., None], 3, axis=2)
    rgb = _to_rgb_u8(image).astype(np.float64)
    if rgb.shape[:2] != mask.shape:
        raise ValueError(f"mask has shape {mask.shape}, image {rgb.shape[:2]}")
    tint = (1 - opacity) * rgb + opacity * np.array(color, dtype=np.float64)
    rgb[mask] = tint[mask]
    return np.rint(rgb).astype(np.uint8)
