"""Sample positions along blur trajectories and their interpolation weights.

This module is the one source of truth for how both blur operators sample time
and space; :mod:`.homography` and :mod:`.displacement` only assemble matrices
from what is defined here. Every rule has a scalar form compiled with numba
(used by the fast kernels in :mod:`._kernels`) and a vectorised numpy form (used
by the slow reference builders and the tests); the tests check that both build
the same matrices.

Conventions
-----------
Pixel centres sit at integer coordinates, ``(0, 0)`` is the centre of the
top-left pixel, x right, y down, and the flat pixel index is ``y * W + x``.

Instants are the fractions ``s`` of the frame interval returned by
:meth:`stereodeblur.geometry.camera.Exposure.sample_fractions` (midpoints of
``num_samples`` equal sub-intervals of ``[-tau/2, tau/2]``, paper Eq. 4 with
``delta t = tau / N``).

Homography trajectories (gather, paper Eq. 3-4): blurred pixel ``x`` at instant
``s`` shows the sharp reference image at ``H_ref_from_t[label(x), s] @ x``. A
homogeneous point whose third coordinate is not positive (the plane passes
behind the camera) is replaced by ``x`` itself.

Displacement trajectories (splat, Kim & Lee 2015, supplement Fig. 11): the
content of source pixel ``y`` sits at ``y + s * flow_forward(y)`` for ``s >= 0``
and at ``y + |s| * flow_backward(y)`` for ``s < 0``.

Bilinear weights: a position ``(px, py)`` has the four taps
``(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)`` with ``x0 = floor(px)``
and weights ``(1 - fx)(1 - fy), fx (1 - fy), (1 - fx) fy, fx fy``,
``fx = px - x0``. A fractional part within ``SNAP = 1e-9`` of 0 or 1 is rounded
to it, so that zero motion gives exactly the identity despite rounding in the
homographies. Taps with weight zero are dropped.

Cubic weights (``interpolation='cubic'``, both operators): Keys' cubic convolution
(a = -0.5) over the sixteen taps ``x0 - 1 .. x0 + 2`` by ``y0 - 1 .. y0 + 2``, with the same
snapping; gathering clamps each tap coordinate to the image (replicate edge), splatting drops
the taps outside it. It interpolates the sharp image with third-order accuracy instead of
bilinear interpolation's smoothing, which on noiseless frames is the largest part of the
bilinear operator's model error (``docs/defaults.md#interpolation``).

Border rule (shared by both operators)
--------------------------------------
Sharp-image content outside the frame is the content of the nearest edge pixel
(replicate edge). Gathering (homography) clamps a sample position to
``[0, W - 1] x [0, H - 1]`` before taking its bilinear taps, which equals
bilinear interpolation of the edge-replicated image; splatting (displacement)
moves source pixels of an extended grid whose flow and column are those of the
nearest in-image pixel. Either way, content entering the frame during the
exposure is modelled as the edge pixel's content, and every row sums to one.
Splat taps that land outside the frame have no blurred pixel to go to and are
dropped (the content has left the view).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..settings import INTERPOLATIONS

SNAP = 1e-9
"""Fractional parts closer than this to 0 or 1 are rounded (see module docstring)."""

_MIN_DEPTH = 1e-12
"""Homogeneous coordinates with a third component at or below this are invalid."""


# --------------------------------------------------------------------------------------
# Scalar forms (numba), used by the kernels.
# --------------------------------------------------------------------------------------


@njit(cache=True)
def homography_point(homographies, label, sample, x, y):
    """Position ``homographies[label, sample] @ (x, y, 1)`` in pixels.

    ``(x, y)`` itself when the homogeneous depth is not positive or the result is not finite.
    """
    Hm = homographies
    w = Hm[label, sample, 2, 0] * x + Hm[label, sample, 2, 1] * y + Hm[label, sample, 2, 2]
    if not w > _MIN_DEPTH:
        return x, y
    px = (Hm[label, sample, 0, 0] * x + Hm[label, sample, 0, 1] * y + Hm[label, sample, 0, 2]) / w
    py = (Hm[label, sample, 1, 0] * x + Hm[label, sample, 1, 1] * y + Hm[label, sample, 1, 2]) / w
    if not (np.isfinite(px) and np.isfinite(py)):
        return x, y
    return px, py


@njit(cache=True)
def displacement_point(x, y, fraction, forward_u, forward_v, backward_u, backward_v):
    """Position at ``fraction`` of content at ``(x, y)`` moving on a straight line."""
    if fraction >= 0.0:
        return x + fraction * forward_u, y + fraction * forward_v
    return x - fraction * backward_u, y - fraction * backward_v


@njit(cache=True)
def keys_weight(t):
    """Keys' cubic convolution kernel (a = -0.5) at offset ``t``."""
    t = abs(t)
    if t <= 1.0:
        return (1.5 * t - 2.5) * t * t + 1.0
    if t < 2.0:
        return ((-0.5 * t + 2.5) * t - 4.0) * t + 2.0
    return 0.0


@njit(cache=True)
def split_coordinate(p):
    """Integer part and snapped fractional part of a coordinate: ``(i0, f)``."""
    i0 = np.floor(p)
    f = p - i0
    if f < SNAP:
        f = 0.0
    elif f > 1.0 - SNAP:
        f = 0.0
        i0 += 1.0
    return np.int64(i0), f


@njit(cache=True)
def clamp(p, upper):
    """``p`` clamped to ``[0, upper]``."""
    return min(max(p, 0.0), float(upper))


# --------------------------------------------------------------------------------------
# Vectorised forms (numpy), used by the reference builders and the tests.
# --------------------------------------------------------------------------------------


def homography_positions(homographies: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Sample positions of every blurred pixel under its segment's homographies.

    Parameters
    ----------
    homographies : ndarray, shape (L, S, 3, 3)
        ``H_ref_from_t`` per segment and instant.
    labels : ndarray of int, shape (H, W) or (H, W, S)
        The segment of every pixel, or of every pixel at every instant.

    Returns
    -------
    ndarray, shape (H, W, S, 2)
        ``(x, y)`` in the sharp reference image, float64, not clamped.
    """
    height, width = labels.shape[:2]
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    if labels.ndim == 2:
        Hm = homographies[labels]  # (H, W, S, 3, 3)
    else:
        Hm = homographies[labels, np.arange(homographies.shape[1])]
    x = x[..., None]
    y = y[..., None]
    w = Hm[..., 2, 0] * x + Hm[..., 2, 1] * y + Hm[..., 2, 2]
    valid = w > _MIN_DEPTH
    ws = np.where(valid, w, 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        px = (Hm[..., 0, 0] * x + Hm[..., 0, 1] * y + Hm[..., 0, 2]) / ws
        py = (Hm[..., 1, 0] * x + Hm[..., 1, 1] * y + Hm[..., 1, 2]) / ws
    valid &= np.isfinite(px) & np.isfinite(py)
    px = np.where(valid, px, np.broadcast_to(x, px.shape))
    py = np.where(valid, py, np.broadcast_to(y, py.shape))
    return np.stack([px, py], axis=-1)


def displacement_positions(
    x: np.ndarray,
    y: np.ndarray,
    flow_forward: np.ndarray,
    flow_backward: np.ndarray,
    fractions: np.ndarray,
) -> np.ndarray:
    """Positions ``(..., S, 2)`` of content at ``(x, y)`` moving along straight lines.

    ``flow_forward`` and ``flow_backward`` have shape ``x.shape + (2,)``.
    """
    s = np.asarray(fractions, dtype=np.float64)
    start = np.stack([x, y], axis=-1).astype(np.float64)[..., None, :]
    flow = np.where(
        (s >= 0)[:, None],
        flow_forward[..., None, :].astype(np.float64),
        flow_backward[..., None, :].astype(np.float64),
    )
    return start + np.abs(s)[:, None] * flow


def _split(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    i0 = np.floor(p)
    f = p - i0
    up = f > 1.0 - SNAP
    f = np.where((f < SNAP) | up, 0.0, f)
    return (i0 + up).astype(np.int64), f


def _split_positions(positions: np.ndarray, shape: tuple[int, int], border: str):
    """``(x0, fx), (y0, fy)`` of :func:`_split` for ``positions``, clamped to the image first
    for ``border='clamp'`` (gathering), as they are for ``'drop'`` (splatting)."""
    height, width = shape
    px, py = positions[..., 0], positions[..., 1]
    if border == "clamp":
        px = np.clip(px, 0.0, width - 1)
        py = np.clip(py, 0.0, height - 1)
    elif border != "drop":
        raise ValueError(f"border must be 'clamp' or 'drop', got {border!r}")
    return _split(px), _split(py)


def bilinear_taps(
    positions: np.ndarray, shape: tuple[int, int], *, border: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The four bilinear taps of every position.

    Parameters
    ----------
    positions : ndarray, shape (..., 2)
        ``(x, y)`` in pixels.
    shape : tuple of int
        Image shape ``(H, W)``.
    border : {'clamp', 'drop'}
        'clamp' clamps positions to the image first (gathering); 'drop' marks
        taps outside the image invalid (splatting).

    Returns
    -------
    index : ndarray of int64, shape (..., 4)
        Flat pixel index ``y * W + x`` of each tap (arbitrary where invalid).
    weight : ndarray of float64, shape (..., 4)
        Bilinear weight, zero where the tap is invalid.
    valid : ndarray of bool, shape (..., 4)
        Whether the tap is inside the image and has a non-zero weight.
    """
    height, width = shape
    (x0, fx), (y0, fy) = _split_positions(positions, shape, border)
    xs = np.stack([x0, x0 + 1, x0, x0 + 1], axis=-1)
    ys = np.stack([y0, y0, y0 + 1, y0 + 1], axis=-1)
    weight = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], axis=-1)
    valid = (weight > 0) & (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
    index = np.where(valid, ys * width + xs, 0)
    return index, np.where(valid, weight, 0.0), valid


def is_cubic(interpolation: str) -> bool:
    """Whether ``interpolation`` (``'bilinear'`` or ``'cubic'``) asks for cubic taps."""
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
    return interpolation == "cubic"


def keys_weights(t: np.ndarray) -> np.ndarray:
    """:func:`keys_weight` of every offset in ``t``."""
    t = np.abs(t)
    near = 1.5 * t**3 - 2.5 * t**2 + 1
    far = -0.5 * t**3 + 2.5 * t**2 - 4 * t + 2
    return np.where(t <= 1, near, np.where(t < 2, far, 0.0))


def cubic_taps(
    positions: np.ndarray, shape: tuple[int, int], *, border: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sixteen cubic taps of every position (as :func:`bilinear_taps`).

    ``border``: 'clamp' clamps the positions and the taps to the image (gathering; taps may
    then repeat a pixel), 'drop' marks taps outside the image invalid (splatting).

    Returns
    -------
    index, weight, valid : ndarray, shape (..., 16)
        Flat pixel index, Keys' weight (zero where invalid) and validity of each tap.
    """
    height, width = shape
    (x0, fx), (y0, fy) = _split_positions(positions, shape, border)
    offsets = np.arange(-1, 3)
    xs, ys = x0[..., None] + offsets, y0[..., None] + offsets
    inside_x, inside_y = (xs >= 0) & (xs < width), (ys >= 0) & (ys < height)
    if border == "clamp":
        xs, ys = np.clip(xs, 0, width - 1), np.clip(ys, 0, height - 1)
        inside_x[:], inside_y[:] = True, True
    wx = keys_weights(fx[..., None] - offsets)
    wy = keys_weights(fy[..., None] - offsets)
    index = (ys[..., :, None] * width + xs[..., None, :]).reshape(*x0.shape, 16)
    weight = (wy[..., :, None] * wx[..., None, :]).reshape(*x0.shape, 16)
    valid = (weight != 0) & (inside_y[..., :, None] & inside_x[..., None, :]).reshape(*x0.shape, 16)
    return np.where(valid, index, 0), np.where(valid, weight, 0.0), valid


# --------------------------------------------------------------------------------------
# The extended source grid of splatting (border rule).
# --------------------------------------------------------------------------------------


def displacement_margin(
    flow_forward: np.ndarray, flow_backward: np.ndarray, fractions: np.ndarray, *, cubic=False
) -> int:
    """Width in pixels of the extended grid: the farthest reach from outside plus the taps'
    (one pixel, two for cubic taps), at most the image's larger side.

    Extended pixels carry the flow of the nearest edge pixel, so only the flow on
    the image border matters; content from farther outside never reaches the image.
    A reach beyond the image's size is a degenerate motion (an estimated plane whose motion
    takes it through the camera: flows of millions of pixels, a grid of terabytes); the
    grid stops there, and the rows lose what came from farther out (the edge pixels'
    replicas) before they are normalised.
    """
    s = np.asarray(fractions, dtype=np.float64)
    ahead = float(max(s.max(initial=0.0), 0.0))
    behind = float(max(-s.min(initial=0.0), 0.0))

    def border_max(flow: np.ndarray) -> float:
        edges = [flow[0], flow[-1], flow[:, 0], flow[:, -1]]
        return float(max(np.abs(e).max(initial=0.0) for e in edges))

    reach = max(ahead * border_max(flow_forward), behind * border_max(flow_backward))
    return int(np.ceil(min(reach, max(flow_forward.shape[:2])))) + (2 if cubic else 1)


def extended_grid(shape: tuple[int, int], margin: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Source pixels of the grid extended by ``margin`` on every side.

    Returns
    -------
    x, y : ndarray of int32, shape (M,)
        Coordinates of the extended pixels (``-margin .. W - 1 + margin``).
    source : ndarray of int32, shape (M,)
        Flat index of the nearest in-image pixel, whose flow and content the
        extended pixel takes. The pixels are ordered by ``source`` (ties in
        row-major order), which the fast assembly relies on.
    """
    height, width = shape
    y, x = np.mgrid[-margin : height + margin, -margin : width + margin]
    x, y = x.ravel(), y.ravel()
    source = np.clip(y, 0, height - 1) * width + np.clip(x, 0, width - 1)
    order = np.argsort(source, kind="stable")
    return (
        x[order].astype(np.int32),
        y[order].astype(np.int32),
        source[order].astype(np.int32),
    )
