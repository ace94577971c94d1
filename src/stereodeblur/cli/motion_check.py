"""Ground-truth motion checked before a ``--motion-source gt`` run starts.

Ground truth that is entirely unknown, or that describes a motion no frame can show, gives
no deblurring or a result worse than the input without any error downstream. Every gt
file the run will read is checked once, up front:

- disparity: some pixel known (finite and > 0), and every known value in
  ``[MIN_DISPARITY, width]`` pixels: a disparity above the frame's width puts the point
  out of the other view, one below 0.001 px is a point more than 1000 times farther than
  the depth at 1 px, where a plane fit from it is meaningless;
- flow: some pixel known, and every known ``|flow|`` at most the frame's diagonal
  (a longer motion leaves the frame within one frame interval).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from ..errors import InputError

MIN_DISPARITY = 1e-3


def gt_files(scene, indices: Iterable[int], settings) -> list[tuple[str, int]]:
    """The left view's gt files ``(kind, frame)`` the frames ``indices`` read."""
    needed: dict[tuple[str, int], None] = {}
    last = scene.num_frames - 1
    for index in indices:
        neighbour = index + 1 if index < last else index - 1
        needed[("disparity", index)] = None
        needed[("disparity", neighbour)] = None
        needed[("flow", min(index, neighbour))] = None
        if 0 < index and scene.has_gt("flow", "left", index - 1):
            needed[("flow", index - 1)] = None
    return list(needed)


def check_disparity(disparity: np.ndarray, path) -> None:
    """InputError naming ``path`` unless the disparity is usable (module docstring)."""
    width = disparity.shape[1]
    known = disparity[np.isfinite(disparity) & (disparity > 0)]
    if known.size == 0:
        raise InputError(f"{path}: no known disparity (every value is NaN or <= 0)")
    low, high = float(known.min()), float(known.max())
    if low < MIN_DISPARITY or high > width:
        raise InputError(
            f"{path}: disparities from {low:.3g} to {high:.3g} px, expected within "
            f"[{MIN_DISPARITY:g}, {width}] px (the frame's width)"
        )


def check_flow(flow: np.ndarray, path) -> None:
    """InputError naming ``path`` unless the flow is usable (module docstring)."""
    height, width = flow.shape[:2]
    length = np.linalg.norm(flow, axis=-1)
    known = length[np.isfinite(length)]
    if known.size == 0:
        raise InputError(f"{path}: no known flow (every value is unknown)")
    diagonal = math.hypot(width, height)
    if float(known.max()) > diagonal:
        raise InputError(
            f"{path}: flow up to {float(known.max()):.4g} px long, expected at most the "
            f"frame's diagonal, {diagonal:.0f} px"
        )


def check_gt_motion(scene, indices: Iterable[int], settings) -> None:
    """Check every gt file the deblurring of ``indices`` reads with ``--motion-source gt``.

    A missing file is left to the run, which names it.
    """
    for kind, index in gt_files(scene, indices, settings):
        if not scene.has_gt(kind, "left", index):
            continue
        path = scene.gt_path(kind, "left", index)
        if kind == "disparity":
            check_disparity(scene.read_gt_disparity("left", index), path)
        else:
            check_flow(scene.read_gt_flow("left", index), path)
