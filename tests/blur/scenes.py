"""Seeded synthetic scene flows and flow fields for the blur-operator tests."""

from __future__ import annotations

import numpy as np

from stereodeblur.geometry import Exposure, StereoCamera
from stereodeblur.sceneflow.model import SceneFlow

EXPOSURE = Exposure(frame_rate=25.0, exposure=0.03)  # duty cycle 0.75


def camera(shape: tuple[int, int]) -> StereoCamera:
    """A camera with a focal length of about the image width."""
    height, width = shape
    f = 0.9 * width
    return StereoCamera([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]], 0.2)


def grid_labels(shape: tuple[int, int], rows: int, cols: int) -> np.ndarray:
    height, width = shape
    y = np.arange(height) * rows // height
    x = np.arange(width) * cols // width
    return (y[:, None] * cols + x[None, :]).astype(np.int32)


def random_sceneflow(
    shape: tuple[int, int], seed: int, *, view: str = "left", grid=(2, 3), speed: float = 1.0
) -> SceneFlow:
    """Random tilted planes at depths 2..4 moving by random twists (blur of a few pixels)."""
    rng = np.random.default_rng(seed)
    labels = grid_labels(shape, *grid)
    num = grid[0] * grid[1]
    depth = rng.uniform(2.0, 4.0, num)
    tilt = rng.uniform(-0.15, 0.15, (num, 2))
    normals = np.column_stack([tilt, np.ones(num)]) / depth[:, None]
    twists = np.column_stack(
        [rng.normal(0, 0.15 * speed, (num, 3)), rng.normal(0, 0.03 * speed, (num, 3))]
    )
    return SceneFlow(camera(shape), labels, normals, twists, np.zeros(shape, bool), view)


def translation_sceneflow(
    shape: tuple[int, int], velocity: tuple[float, float], depth: float = 3.0, view: str = "left"
) -> SceneFlow:
    """One fronto-parallel plane at ``depth`` translating by ``(vx, vy, 0)`` per frame."""
    normals = np.array([[0.0, 0.0, 1.0 / depth]])
    twists = np.array([[velocity[0], velocity[1], 0.0, 0.0, 0.0, 0.0]])
    labels = np.zeros(shape, np.int32)
    return SceneFlow(camera(shape), labels, normals, twists, np.zeros(shape, bool), view)


def smooth_flow(shape: tuple[int, int], seed: int, amplitude: float = 4.0) -> np.ndarray:
    """A smooth random flow field (H, W, 2): a constant plus low-frequency waves."""
    rng = np.random.default_rng(seed)
    height, width = shape
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    flow = np.empty(shape + (2,))
    for c in range(2):
        field = np.full(shape, rng.uniform(-1, 1))
        for _ in range(3):
            fx, fy = rng.uniform(0.5, 2.0, 2)
            phase = rng.uniform(0, 2 * np.pi)
            field += 0.5 * np.sin(2 * np.pi * (fx * x / width + fy * y / height) + phase)
        flow[..., c] = amplitude * field / 2.5
    return flow
