"""Segment boundaries moved to where a dense optical flow puts them.

A superpixel of the estimate ends where the blurred image's colour changes, which near a
motion boundary is up to a blur length away from where the surfaces change. A dense flow
of the blurred frames follows the surfaces there more closely. :func:`relabel_by_flow`
gives each pixel near a segment boundary the segment, among those within ``radius``
pixels, whose plane and motion predict that flow best (why: ``docs/defaults.md#relabel-radius``).
"""

from __future__ import annotations

import numpy as np

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

    def error(index, segments):
        """Distance of other ``segments``' flows at pixels ``index``, plus the margin; inf
        for one surface."""
        total = np.full(index.size, threshold)
        for k, (homographies, target) in enumerate(targets):
            predicted = segment_flow(homographies, xs[index], ys[index], segments)
            total += np.linalg.norm(predicted - target[index], axis=1)
            if k == 0:  # no motion boundary between them: the same surface, no candidate
                longer = np.maximum(np.hypot(*predicted.T), own_length[index])
                apart = np.hypot(*(predicted - own_forward[index]).T)
                same = apart <= np.maximum(jump, relative * longer)
                total[same] = np.inf
        return total

    out = own.copy()
    padded = np.pad(labels, radius, mode="edge")

    def window(dy, dx):
        return padded[dy : dy + height, dx : dx + width].ravel()

    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            shifted = window(dy, dx)
            new = shifted != own
            # A candidate met one column left or one row up has been weighed already.
            if dx > 0:
                new &= shifted != window(dy, dx - 1)
            if dy > 0:
                new &= shifted != window(dy - 1, dx)
            index = np.flatnonzero(new)
            e = error(index, shifted[index])
            better = e < best[index]
            best[index[better]], out[index[better]] = e[better], shifted[index[better]]
    return SceneFlow(
        sceneflow.camera, out.reshape(height, width), sceneflow.normals, sceneflow.twists,
        sceneflow.occlusion, sceneflow.view,
    )  # fmt: skip
