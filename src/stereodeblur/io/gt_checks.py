"""Ground-truth motion that a run can use: checked once, before the run starts.

Ground truth that is entirely unknown, or that describes a motion no frame can show, gives
no deblurring or a result worse than the input without any error downstream:

- disparity: some pixel known (finite and > 0), and every known value in
  ``[MIN_DISPARITY, width]`` pixels: a disparity above the frame's width puts the point
  out of the other view, one below 0.001 px is a point more than 1000 times farther than
  the depth at 1 px, where a plane fit from it is meaningless;
- flow: some pixel known (finite, below the FLO format's 1e9 "unknown"), and every known
  ``|flow|`` at most the frame's diagonal (a longer motion leaves the frame within one
  frame interval).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError

MIN_DISPARITY = 1e-3
FLO_UNKNOWN = 1e9


def check_disparity(disparity: np.ndarray, path) -> None:
    """InputError naming ``path`` unless the disparity is usable (module docstring)."""
    width = disparity.shape[1]
    with np.errstate(invalid="ignore"):
        known = disparity[np.isfinite(disparity) & (disparity > 0)]
    if known.size == 0:
        raise InputError(
            f"{path}: no known disparity, the ground truth is unknown everywhere "
            "(every value is NaN or <= 0)"
        )
    low, high = float(known.min()), float(known.max())
    if low < MIN_DISPARITY or high > width:
        raise InputError(
            f"{path}: disparities from {low:.3g} to {high:.3g} px, expected within "
            f"[{MIN_DISPARITY:g}, {width}] px (the frame's width)"
        )


def check_flow(flow: np.ndarray, path) -> None:
    """InputError naming ``path`` unless the flow is usable (module docstring)."""
    height, width = flow.shape[:2]
    with np.errstate(invalid="ignore"):
        known = np.all(np.isfinite(flow) & (np.abs(flow) < FLO_UNKNOWN), axis=-1)
    if not known.any():
        raise InputError(
            f"{path}: no known flow, the ground truth is unknown everywhere "
            f"(every vector is non-finite or {FLO_UNKNOWN:g} px and more)"
        )
    longest = float(np.linalg.norm(flow[known].astype(np.float64), axis=-1).max())
    diagonal = math.hypot(width, height)
    if longest > diagonal:
        raise InputError(
            f"{path}: flow up to {longest:.4g} px long, expected at most the frame's "
            f"diagonal, {diagonal:.0f} px"
        )


def check_gt_file(path: Path) -> None:
    """Check a gt disparity (``.pfm``) or flow (``.flo``) file; other files pass."""
    from .formats import read_flo, read_pfm

    suffix = Path(path).suffix.lower()
    if suffix == ".pfm":
        check_disparity(read_pfm(path), path)
    elif suffix == ".flo":
        check_flow(read_flo(path), path)
