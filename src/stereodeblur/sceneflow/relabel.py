"""Segment boundaries moved to where a dense optical flow puts them.

A superpixel of the estimate ends where the blurred image's colour changes, which near a
motion boundary is up to a blur length away from where the surfaces change. A dense flow
of the blurred frames follows the surfaces there more closely. :func:`relabel_by_flow`
gives each pixel near a segment boundary the segment, among those within ``radius``
pixels, whose plane and motion predict that flow best (why: ``docs/defaults.md#relabel-radius``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.homography import homography, motion_in_view
from ..geometry.plane import plane_in_view
from ..geometry.rigid import se3_exp
from .model import SceneFlow


def flow_homographies(sceneflow: SceneFlow) -> np.ndarray:
    """Per segment, the homography ``(L, 3, 3)`` that takes a reference pixel showing its
    plane to where its motion moves it at the next frame (``H_t_from_ref`` of
    :mod:`~stereodeblur.geometry.homography`, in the scene flow's view)."""
    camera = sceneflow.camera
    c = camera.center(sceneflow.view)
    motion = se3_exp(sceneflow.twists)
    R, T = motion_in_view(motion[:, :3, :3], motion[:, :3, 3], c)
    n = np.stack([plane_in_view(normal, c) for normal in sceneflow.normals])
    return homography(camera.K, R, T, n)


def segment_flow(homographies: np.ndarray, x: np.ndarray, y: np.ndarray, segments: np.ndarray):
    """Flow ``(N, 2)`` of the pixels ``(x, y)`` (each ``(N,)``) under the
    :func:`flow_homographies` of ``segments`` (``(N,)`` indices)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    h = homographies[segments]
    q = h[:, :, 0] * x[:, None] + h[:, :, 1] * y[:, None] + h[:, :, 2]
    return np.stack([q[:, 0] / q[:, 2] - x, q[:, 1] / q[:, 2] - y], axis=-1)


def relabel_by_flow(
    sceneflow: SceneFlow,
    forward: np.ndarray,
    backward: np.ndarray | None = None,
    *,
    radius: int,
    jump: float = 0.0,
    relative: float = 0.0,
    margin: float = 0.0,
) -> SceneFlow:
    """``sceneflow`` with each pixel given the segment within ``radius`` px (square window)
    whose flows (:func:`segment_flow`) come nearest the dense flows ``forward`` (to the
    frame the scene flow's motions lead to) and ``backward`` (to the frame on the other
    side, if given; each ``(H, W, 2)``): the least sum of the end-point distances. A tie
    keeps the pixel's own segment. Only another surface is taken: a segment whose forward
    flow at the pixel differs from the pixel's own segment's by more than ``jump`` px and
    more than ``relative`` times the longer of the two (as
    :func:`~stereodeblur.deconv.trust.near_motion_boundaries` tells a motion boundary),
    and only by more than ``margin`` times the median over the view of the own segments'
    distances: where the dense flow disagrees with the estimate everywhere, one pixel's
    distance is no evidence. Planes, motions and the occlusion mask are kept."""
    labels = sceneflow.labels
    height, width = labels.shape
    targets = [(flow_homographies(sceneflow), forward)]
    if backward is not None:
        targets.append((flow_homographies(sceneflow.reversed()), backward))
    for _, flow in targets:
        if np.shape(flow) != (height, width, 2):
            raise ValueError(f"flows must have shape {(height, width, 2)}, got {np.shape(flow)}")
    ys, xs = np.mgrid[0:height, 0:width]
    xs, ys = xs.ravel(), ys.ravel()
    own = labels.ravel()
    targets = [(h, np.asarray(f, dtype=np.float64).reshape(-1, 2)) for h, f in targets]
    own_forward = segment_flow(targets[0][0], xs, ys, own)
    own_length = np.hypot(*own_forward.T)
    best = np.linalg.norm(own_forward - targets[0][1], axis=1)
    for homographies, target in targets[1:]:
        best += np.linalg.norm(segment_flow(homographies, xs, ys, own) - target, axis=1)

    threshold = margin * np.median(best)
    homographies = np.stack([h for h, _ in targets])
    flows = np.stack([f for _, f in targets])
    padded = np.pad(labels, radius, mode="edge")
    out = own.copy()
    _relabel(padded, radius, homographies, flows, own_forward, own_length, best, threshold,
             float(jump), float(relative), out)  # fmt: skip
    return SceneFlow(
        sceneflow.camera, out.reshape(height, width), sceneflow.normals, sceneflow.twists,
        sceneflow.occlusion, sceneflow.view,
    )  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def _relabel(padded, radius, homographies, flows, own_forward, own_length, best, threshold,
             jump, relative, out):  # fmt: skip  # pragma: no cover - compiled
    """Each pixel's candidates of the window, in row order, a candidate met one column left
    or one row up skipped (weighed already); the least :func:`_distance` wins, below
    ``best`` (the own segment's, overwritten)."""
    size = 2 * radius + 1
    height, width = padded.shape[0] - 2 * radius, padded.shape[1] - 2 * radius
    for i in range(height):
        for j in range(width):
            p = i * width + j
            own = padded[i + radius, j + radius]
            for dy in range(size):
                for dx in range(size):
                    s = padded[i + dy, j + dx]
                    if s == own:
                        continue
                    if dx > 0 and s == padded[i + dy, j + dx - 1]:
                        continue
                    if dy > 0 and s == padded[i + dy - 1, j + dx]:
                        continue
                    e = _distance(homographies, flows, own_forward, own_length, threshold,
                                  jump, relative, p, float(j), float(i), s)  # fmt: skip
                    if e < best[p]:
                        best[p] = e
                        out[p] = s


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _distance(homographies, flows, own_forward, own_length, threshold, jump, relative, p, x, y, s):
    """Segment ``s``'s end-point distances to the dense flows at pixel ``p`` = ``(x, y)``
    plus ``threshold``; inf where its forward flow is the own segment's surface (no motion
    boundary between them)."""
    total = threshold
    for k in range(homographies.shape[0]):
        h = homographies[k, s]
        q0 = h[0, 0] * x + h[0, 1] * y + h[0, 2]
        q1 = h[1, 0] * x + h[1, 1] * y + h[1, 2]
        q2 = h[2, 0] * x + h[2, 1] * y + h[2, 2]
        fx, fy = q0 / q2 - x, q1 / q2 - y
        ex, ey = fx - flows[k, p, 0], fy - flows[k, p, 1]
        total += np.sqrt(ex * ex + ey * ey)
        if k == 0:
            longer = max(np.hypot(fx, fy), own_length[p])
            apart = np.hypot(fx - own_forward[p, 0], fy - own_forward[p, 1])
            if apart <= max(jump, relative * longer):
                return np.inf
    return total
