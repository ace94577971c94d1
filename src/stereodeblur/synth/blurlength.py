"""The longest blur of a frame, and the motion scale that gives a chosen one.

Objects are given in their pose at the centre of the frame to measure (instant 0 here)
with twists per frame interval. The blur of the point seen at a pixel is the length of
its true image path over the exposure ``[-tau / 2, tau / 2]`` (``tau`` the duty cycle),
summed over :data:`PATH_STEPS` straight steps, occlusion ignored (as in
:func:`stereodeblur.synth.planar.curvature_px`). The frame's longest blur is the largest
over the left view's pixels at least ``border`` pixels from the image edge, on every
``stride``-th pixel.

Scaling every twist by ``k`` moves each point along the same path ``k`` times as fast, so
the path over ``[-tau / 2, tau / 2]`` at scale ``k`` is the unscaled path over
``[-k tau / 2, k tau / 2]``: its length grows monotonically with ``k``, and
:func:`scale_for_blur` finds the ``k`` of a target length.
"""

from __future__ import annotations

import numpy as np

from ..geometry.camera import StereoCamera
from .render import RayHits, cast_rays, track

PATH_STEPS = 12
"""Straight steps of a blur path over the exposure."""

SCALE_TOLERANCE = 0.002
"""Relative accuracy of the longest blur reached by :func:`scale_for_blur`."""


def _sampled_hits(objects, camera: StereoCamera, size, *, border: int, stride: int) -> RayHits:
    """Hits of the left view at instant 0 on every ``stride``-th pixel inside ``border``."""
    width, height = size
    if 2 * border >= min(width, height):
        raise ValueError(f"border {border} leaves no pixels of a {width}x{height} image")
    hits = cast_rays(objects, camera, "left", size, 0.0)
    keep = (slice(border, height - border, stride), slice(border, width - border, stride))
    return RayHits(
        depth=hits.depth[keep],
        object_id=hits.object_id[keep],
        texture_u=hits.texture_u[keep],
        texture_v=hits.texture_v[keep],
        points=hits.points[keep],
    )


def _longest(objects, camera, hits: RayHits, duty_cycle: float, scale: float) -> float:
    fractions = scale * duty_cycle * np.linspace(-0.5, 0.5, PATH_STEPS + 1)
    path = track(objects, camera, "left", hits, fractions)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=-1).sum(axis=0)
    steps = steps[np.isfinite(steps)]
    return float(steps.max()) if steps.size else 0.0


def longest_blur(
    objects,
    camera: StereoCamera,
    size: tuple[int, int],
    duty_cycle: float,
    *,
    scale: float = 1.0,
    border: int = 8,
    stride: int = 2,
) -> float:
    """Longest blur in pixels of the left view at instant 0 (module docstring).

    Parameters
    ----------
    objects : sequence of objects (see :func:`~stereodeblur.synth.render.cast_rays`)
        In their pose at the frame's centre.
    camera : StereoCamera
    size : tuple of int
        ``(width, height)``.
    duty_cycle : float
        Exposure time times frame rate.
    scale : float
        Factor applied to every twist.
    border, stride : int
        Pixels skipped along each edge; spacing of the pixels measured.
    """
    hits = _sampled_hits(objects, camera, size, border=border, stride=stride)
    return _longest(objects, camera, hits, duty_cycle, scale)


def scale_for_blur(
    objects,
    camera: StereoCamera,
    size: tuple[int, int],
    duty_cycle: float,
    target: float,
    *,
    border: int = 8,
    stride: int = 2,
    low: float = 1e-4,
    high: float = 1e2,
) -> tuple[float, float]:
    """The twist scale ``k`` whose longest blur is ``target`` pixels, and that blur.

    Steps ``k <- k * target / blur`` from ``k = 1`` (the blur is nearly linear in ``k``),
    then, if they do not settle, bisection in ``log k`` over ``[low, high]``, until the
    blur is within :data:`SCALE_TOLERANCE` of ``target`` (relative).

    Raises
    ------
    ValueError
        If ``target`` is not reached within ``[low, high]`` (no motion, or the motion
        carries points behind the camera first).
    """
    hits = _sampled_hits(objects, camera, size, border=border, stride=stride)
    k = 1.0
    for _ in range(8):  # fixed-point steps k <- k * target / blur: the blur is nearly linear
        blur = _longest(objects, camera, hits, duty_cycle, k)
        if abs(blur - target) <= SCALE_TOLERANCE * target:
            return k, blur
        if not (blur > 0 and low <= k * target / blur <= high):
            break
        k *= target / blur
    if not (
        _longest(objects, camera, hits, duty_cycle, low)
        < target
        < _longest(objects, camera, hits, duty_cycle, high)
    ):
        raise ValueError(f"a longest blur of {target} px is out of reach of this motion")
    lo, hi = np.log(low), np.log(high)
    for _ in range(100):
        mid = (lo + hi) / 2
        blur = _longest(objects, camera, hits, duty_cycle, float(np.exp(mid)))
        if abs(blur - target) <= SCALE_TOLERANCE * target:
            return float(np.exp(mid)), blur
        lo, hi = (mid, hi) if blur < target else (lo, mid)
    raise ValueError(f"no motion scale gives a longest blur of {target} px")
