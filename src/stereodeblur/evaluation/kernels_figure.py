"""``stereodeblur kernels``: homography- vs flow-induced blur kernels (paper Fig. 3).

A textured plane faces the camera at ``depth`` and yaws about the vertical axis
through its centre (``yaw`` radians per frame interval; the paper uses an
"extremely large yaw angle" to make the effect visible). Its scene flow is one
segment; the homography-induced operator is
:func:`stereodeblur.blur.homography.homography_blur` of it, the flow-induced one
:func:`stereodeblur.blur.displacement.displacement_blur` of its 2D projection
(forward flow ``sceneflow.flow()``, backward flow that of the reversed motion).

The *kernel* of blurred pixel ``x`` is row ``x`` of the blur matrix, the weights
of the sharp pixels it averages, drawn as a patch centred on ``x`` (patch pixel
``(r, c)`` is sharp pixel ``x + (c - R, r - R)``). Near the rotation axis the
motion is small and both kernels agree; towards the image periphery trajectories
bend and accelerate, and the straight constant-velocity displacement model
differs from the exact homography trajectories.

The picture shows three panels side by side: homography kernels, flow kernels
(each patch scaled to its own maximum) and their signed difference (red:
homography larger, blue: flow larger, scaled by the larger of the two patch
maxima).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..settings import NUM_SAMPLES

# The figure's defaults: a small frame, the paper's "extremely large yaw angle", 3 m away.
SIZE = (320, 240)
YAW = 0.3
DEPTH = 3.0
# Beyond a quarter turn per frame interval the plane turns its back to the camera.
MAX_YAW = math.pi / 2


@dataclass(frozen=True, eq=False)
class KernelGrid:
    """Blur kernels of both models at a grid of pixels.

    Attributes
    ----------
    pixels : ndarray, shape (rows, cols, 2), int
        ``(x, y)`` of each kernel's blurred pixel.
    homography, displacement : ndarray, shape (rows, cols, P, P), float64
        The kernels (rows of the blur matrices) as patches, ``P = 2 R + 1``.
    """

    pixels: np.ndarray
    homography: np.ndarray
    displacement: np.ndarray

    @property
    def difference(self) -> np.ndarray:
        """``homography - displacement``, shape (rows, cols, P, P)."""
        return self.homography - self.displacement

    def difference_norm(self) -> np.ndarray:
        """L1 norm of each kernel difference, shape (rows, cols); 0 equal, 2 disjoint."""
        return np.abs(self.difference).sum(axis=(2, 3))


def row_patch(matrix, index: int, shape: tuple[int, int], radius: int) -> np.ndarray:
    """Row ``index`` of a blur matrix as a ``(2 radius + 1)`` square patch around its pixel.

    Weights of sharp pixels farther than ``radius`` along x or y are dropped.
    """
    height, width = shape
    y0, x0 = divmod(int(index), width)
    start, end = matrix.indptr[index], matrix.indptr[index + 1]
    cols, weights = matrix.indices[start:end], matrix.data[start:end]
    ys, xs = np.divmod(cols, width)
    dy, dx = ys - y0, xs - x0
    keep = (np.abs(dx) <= radius) & (np.abs(dy) <= radius)
    patch = np.zeros((2 * radius + 1, 2 * radius + 1))
    np.add.at(patch, (dy[keep] + radius, dx[keep] + radius), weights[keep])
    return patch


def yaw_sceneflow(size: tuple[int, int], *, yaw: float, depth: float):
    """One-segment scene flow of a fronto-parallel plane yawing about its own centre."""
    from ..sceneflow.model import SceneFlow
    from ..synth.planar import planar_camera

    if not (np.isfinite(depth) and depth > 0):
        raise InputError(f"depth must be a positive number, got {depth!r}", parameter="depth")
    if not (np.isfinite(yaw) and abs(yaw) <= MAX_YAW):
        raise InputError(
            f"yaw must be a number in [-{MAX_YAW:.4g}, {MAX_YAW:.4g}] (a quarter turn per frame "
            f"interval at most), got {yaw!r}",
            parameter="yaw",
        )
    width, height = size
    camera = planar_camera(size)
    center = np.array([0.0, 0.0, depth])
    omega = np.array([0.0, yaw, 0.0])
    twist = np.concatenate([-np.cross(omega, center), omega])
    return SceneFlow(
        camera,
        np.zeros((height, width), np.int32),
        np.array([[0.0, 0.0, 1.0 / depth]]),
        twist[None],
        np.zeros((height, width), bool),
    )


def kernel_grid(
    *,
    size: tuple[int, int] = SIZE,
    yaw: float = YAW,
    depth: float = DEPTH,
    grid: tuple[int, int] = (5, 4),
    num_samples: int = NUM_SAMPLES,
    inset: float = 0.1,
) -> KernelGrid:
    """Homography- and flow-induced kernels of the yawing plane at ``grid`` pixels.

    Parameters
    ----------
    size : tuple of int
        ``(width, height)`` of the image the operators are built on.
    yaw : float
        Rotation about the vertical axis through the plane's centre, radians per frame
        interval (exposure 0.04 s at 20 frames per second: 80 % of it per exposure).
    depth : float
        Distance of the plane, metres (camera of the planar benchmark).
    grid : tuple of int
        ``(columns, rows)`` of kernels, evenly spread over the image.
    num_samples : int
        Instants per exposure (paper: 70).
    inset : float
        Fraction of the width and height kept free of kernels at the borders.
    """
    from ..blur.displacement import displacement_blur
    from ..blur.homography import homography_blur
    from ..geometry.camera import Exposure
    from ..synth.planar import EXPOSURE, FRAME_RATE

    width, height = size
    cols, rows = (int(v) for v in grid)
    if cols < 1 or rows < 1:
        raise InputError(f"grid must be at least 1 x 1, got {grid!r}")
    if not 0 <= inset < 0.5:
        raise InputError(f"inset must be in [0, 0.5), got {inset!r}")
    sceneflow = yaw_sceneflow(size, yaw=yaw, depth=depth)
    exposure = Exposure(FRAME_RATE, EXPOSURE)
    flow = sceneflow.flow()
    sampling = {"num_samples": num_samples, "interpolation": "bilinear"}  # the paper's Fig. 3
    matrices = {
        "homography": homography_blur(sceneflow, exposure, **sampling).matrix,
        "displacement": displacement_blur(
            flow, sceneflow.reversed().flow(), exposure, **sampling
        ).matrix,
    }
    xs = np.linspace(inset * (width - 1), (1 - inset) * (width - 1), cols).round().astype(int)
    ys = np.linspace(inset * (height - 1), (1 - inset) * (height - 1), rows).round().astype(int)
    pixels = np.stack(np.meshgrid(xs, ys), -1)
    # Radius: the farthest tap of any chosen row of either matrix.
    radius = 1
    for matrix in matrices.values():
        for x, y in pixels.reshape(-1, 2):
            i = y * width + x
            taps = matrix.indices[matrix.indptr[i] : matrix.indptr[i + 1]]
            ty, tx = np.divmod(taps, width)
            radius = max(radius, int(np.max(np.abs(tx - x), initial=0)))
            radius = max(radius, int(np.max(np.abs(ty - y), initial=0)))
    patches = {
        kind: np.array(
            [
                [row_patch(m, y * width + x, (height, width), radius) for x, y in line]
                for line in pixels
            ]
        )
        for kind, m in matrices.items()
    }
    return KernelGrid(pixels, patches["homography"], patches["displacement"])


def _panel(tiles: np.ndarray, zoom: int, gap: int) -> np.ndarray:
    """Coloured tiles ``(rows, cols, P, P, 3)`` uint8 on a dark grid, each zoomed ``zoom`` x."""
    rows, cols, P = tiles.shape[:3]
    cell = P * zoom
    panel = np.full((rows * (cell + gap) + gap, cols * (cell + gap) + gap, 3), 40, np.uint8)
    for r in range(rows):
        for c in range(cols):
            top, left = gap + r * (cell + gap), gap + c * (cell + gap)
            panel[top : top + cell, left : left + cell] = np.kron(
                tiles[r, c], np.ones((zoom, zoom, 1), np.uint8)
            )
    return panel


def _levels(values: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``sqrt(|values| / scale)`` as uint8 (square root: faint tails stay visible)."""
    scale = np.where(scale > 0, scale, 1.0)
    return (np.sqrt(np.clip(np.abs(values) / scale, 0, 1)) * 255).round().astype(np.uint8)


def render_kernel_figure(kernels: KernelGrid, *, zoom: int = 3, gap: int = 4) -> np.ndarray:
    """The three panels side by side with titles, uint8 RGB."""
    import cv2

    def grey(patches):
        level = _levels(patches, patches.max(axis=(2, 3), keepdims=True))
        return np.repeat(level[..., None], 3, -1)

    both = np.maximum(
        kernels.homography.max(axis=(2, 3), keepdims=True),
        kernels.displacement.max(axis=(2, 3), keepdims=True),
    )
    difference = kernels.difference
    level = _levels(difference, both)
    signed = np.zeros(difference.shape + (3,), np.uint8)
    signed[..., 0] = np.where(difference > 0, level, 0)
    signed[..., 2] = np.where(difference < 0, level, 0)
    panels = [
        ("homography-induced", grey(kernels.homography)),
        ("flow-induced", grey(kernels.displacement)),
        ("difference", signed),
    ]
    title_height = 24
    out = []
    for title, tiles in panels:
        panel = _panel(tiles, zoom, gap)
        head = np.full((title_height, panel.shape[1], 3), 255, np.uint8)
        cv2.putText(head, title, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        out += [
            np.concatenate([head, panel], 0),
            np.full((title_height + panel.shape[0], 8, 3), 255, np.uint8),
        ]
    return np.concatenate(out[:-1], 1)


def write_kernel_figure(path: str | os.PathLike, **options) -> KernelGrid:
    """Compute :func:`kernel_grid` (``options`` are its arguments) and write the PNG to ``path``."""
    from ..io.formats import write_png

    kernels = kernel_grid(**options)
    picture = render_kernel_figure(kernels)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_png(path, picture.astype(np.float32) / 255.0, bit_depth=8)
    return kernels
