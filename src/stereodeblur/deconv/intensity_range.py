"""Where a sharp estimate leaves the intensity range: the motion cannot have made the frame.

A blurred pixel is an average of sharp intensities in [0, 1]. If a blur operator can only
explain the blurred frame with a sharp estimate far outside that range over a whole region,
the operator is wrong there: e.g. a motion aliased on a fine periodic texture, whose blur
runs across the stripes that the blurred frame still shows.
:func:`unexplained_regions` finds such regions; the pipeline deblurs them with no motion
instead (``DeblurSettings.range_guard``). Where they cover much of the frame, the motion failed
on a whole surface and is not trusted in the rest of it either: the frame is then deblurred
with no motion everywhere. Why the guard and its constants: ``docs/defaults.md#range-guard``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage


def range_excess(image: np.ndarray) -> np.ndarray:
    """How far each pixel lies outside [0, 1], float32 ``(H, W)`` (its worst channel)."""
    image = np.asarray(image, dtype=np.float32)
    excess = np.maximum(image - 1.0, 0.0) + np.maximum(-image, 0.0)
    return excess.max(axis=-1) if excess.ndim == 3 else excess


def unexplained_regions(
    image: np.ndarray,
    *,
    excess: float,
    window: int,
    share: float,
    area: float = 0.0,
    whole: float = 1.0,
) -> np.ndarray:
    """Bool ``(H, W)``: pixels whose ``window`` x ``window`` neighbourhood has more than
    ``share`` of its pixels more than ``excess`` outside [0, 1] in the sharp estimate
    ``image`` (not clipped), in connected regions of at least ``area`` of the image; every
    pixel where those regions cover more than ``whole`` of it."""
    if not 0 < share < 1 or excess < 0 or window < 1 or not 0 <= area < 1 or not 0 < whole <= 1:
        raise ValueError(
            f"need 0 < share < 1, excess >= 0, window >= 1, 0 <= area < 1, 0 < whole <= 1: "
            f"{share, excess, window, area, whole}"
        )
    outside = (range_excess(image) > excess).astype(np.float32)
    found = ndimage.uniform_filter(outside, size=window, mode="nearest") > share
    if area > 0 and found.any():
        labels, count = ndimage.label(found)
        sizes = np.bincount(labels.ravel(), minlength=count + 1)
        large = sizes >= area * found.size
        large[0] = False
        found = large[labels]
    if found.mean() > whole:
        found[...] = True
    return found
