"""KITTI 2015 scene-flow measures: ground-truth PNGs and the benchmark's outlier rule.

The KITTI 2015 devkit counts a pixel with ground truth as an *outlier* when its error is
over 3 px **and** over 5 % of the true magnitude (the disparity, or the length of the true
flow vector): D1 (disparity at t), D2 (disparity at t + 1 in t's pixels), Fl (optical flow)
and SF (an outlier in any of the three, over the pixels where all three are known). Each is
taken over the non-occluded ground truth (``noc``: ``disp_noc_0``, ``disp_noc_1``,
``flow_noc``) and over all of it (``all``: the ``*_occ*`` folders).

Holes: the devkit fills an estimate's holes by background interpolation before scoring.
Here a hole (a non-finite value) is an outlier, and counts as zero in the mean end-point
error (the package's convention for ADE and AEP): a sparse estimate is not helped.
:func:`interpolate_background` gives the devkit's filling where it is wanted instead.

Ground-truth files (devkit ``io_disp.h``, ``io_flow.h``): 16-bit PNGs; disparity
``d = value / 256``, 0 unknown; flow three channels ``(u, v, valid)`` with
``u = (value - 2**15) / 64``, valid where the third channel is non-zero.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

OUTLIER_PX = 3.0
"""px: an error must exceed this to be an outlier (KITTI's ``ABS_THRESH``)."""
OUTLIER_RELATIVE = 0.05
"""And this share of the true magnitude (KITTI's ``REL_THRESH``)."""


# --------------------------------------------------------------------------- files


def _read_png16(path, channels: int) -> np.ndarray:
    import cv2

    path = Path(path)
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileNotFoundError(f"cannot read {path} as a PNG")
    found = 1 if image.ndim == 2 else image.shape[2]
    if image.dtype != np.uint16 or found != channels:
        raise InputError(
            f"{path}: expected a 16-bit PNG with {channels} channel(s), got {image.dtype} "
            f"with {found}"
        )
    return image


def read_kitti_disparity(path) -> np.ndarray:
    """A KITTI disparity PNG as float32 pixels, NaN where unknown."""
    raw = _read_png16(path, 1).astype(np.float32)
    return np.where(raw > 0, raw / 256.0, np.nan).astype(np.float32)


def read_kitti_flow(path) -> np.ndarray:
    """A KITTI flow PNG as float32 ``(H, W, 2)`` ``(u, v)`` pixels, NaN where unknown."""
    raw = _read_png16(path, 3).astype(np.float32)  # OpenCV's order: valid, v, u
    flow = (raw[..., [2, 1]] - 2.0**15) / 64.0
    flow[raw[..., 0] == 0] = np.nan
    return flow.astype(np.float32)


# --------------------------------------------------------------------------- the rule


def is_outlier(error: np.ndarray, magnitude: np.ndarray) -> np.ndarray:
    """KITTI's outlier: ``error > 3 px`` and ``error > 5 %`` of the true ``magnitude``.

    A non-finite ``error`` (a hole in the estimate) is an outlier.
    """
    error = np.asarray(error, dtype=np.float64)
    magnitude = np.abs(np.asarray(magnitude, dtype=np.float64))
    with np.errstate(invalid="ignore"):
        wrong = (error > OUTLIER_PX) & (error > OUTLIER_RELATIVE * magnitude)
    return wrong | ~np.isfinite(error)


@dataclass(frozen=True)
class Errors:
    """Per-pixel errors of one estimate against one ground truth.

    ``known``: pixels with ground truth; ``outlier``: KITTI's rule there (holes included);
    ``endpoint``: the error, a hole's counted against zero; ``holes``: known pixels the
    estimate has no value for.
    """

    known: np.ndarray
    outlier: np.ndarray
    endpoint: np.ndarray
    holes: np.ndarray

    @property
    def outlier_rate(self) -> float:
        """Share of the known pixels that are outliers (NaN with none known)."""
        n = int(self.known.sum())
        return float(self.outlier[self.known].sum() / n) if n else float("nan")

    @property
    def mean_endpoint(self) -> float:
        """Mean end-point error over the known pixels (NaN with none known)."""
        n = int(self.known.sum())
        return float(self.endpoint[self.known].mean()) if n else float("nan")

    @property
    def hole_rate(self) -> float:
        n = int(self.known.sum())
        return float(self.holes[self.known].sum() / n) if n else float("nan")


def disparity_errors(estimate: np.ndarray, truth: np.ndarray) -> Errors:
    """Errors of a disparity ``estimate`` (NaN holes) against ``truth`` (NaN unknown)."""
    estimate = np.asarray(estimate, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    if estimate.shape != truth.shape:
        raise ValueError(f"estimate {estimate.shape} and truth {truth.shape} differ in shape")
    known = np.isfinite(truth)
    holes = known & ~np.isfinite(estimate)
    error = np.abs(estimate - truth)
    outlier = known & is_outlier(error, truth)
    endpoint = np.where(holes, np.abs(truth), error)
    endpoint[~known] = np.nan
    return Errors(known, outlier, endpoint, holes)


def flow_errors(estimate: np.ndarray, truth: np.ndarray) -> Errors:
    """Errors of a flow ``estimate`` ``(H, W, 2)`` (non-finite holes) against ``truth``."""
    estimate = np.asarray(estimate, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    if estimate.shape != truth.shape or truth.ndim != 3 or truth.shape[2] != 2:
        raise ValueError(f"estimate {estimate.shape} and truth {truth.shape}: expected (H, W, 2)")
    known = np.all(np.isfinite(truth), axis=-1)
    holes = known & ~np.all(np.isfinite(estimate), axis=-1)
    magnitude = np.linalg.norm(truth, axis=-1)
    error = np.linalg.norm(estimate - truth, axis=-1)
    outlier = known & is_outlier(error, magnitude)
    endpoint = np.where(holes, magnitude, error)
    endpoint[~known] = np.nan
    return Errors(known, outlier, endpoint, holes)


def sceneflow_outliers(d1: Errors, d2: Errors, fl: Errors) -> Errors:
    """KITTI's SF: over the pixels where D1, D2 and Fl are all known, an outlier in any.

    Its ``endpoint`` is the flow's (the end-point error has no scene-flow form in KITTI).
    """
    known = d1.known & d2.known & fl.known
    outlier = known & (d1.outlier | d2.outlier | fl.outlier)
    holes = known & (d1.holes | d2.holes | fl.holes)
    return Errors(known, outlier, np.where(known, fl.endpoint, np.nan), holes)


def warp_disparity_next(disparity_next: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """D2 of a two-frame baseline: the disparity at t + 1 (in t + 1's pixels) read at
    ``x + flow`` (bilinear; NaN where a corner is a hole or outside the image)."""
    disparity_next = np.asarray(disparity_next, dtype=np.float64)
    H, W = disparity_next.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    xs, ys = x + flow[..., 0], y + flow[..., 1]
    inside = np.isfinite(xs) & np.isfinite(ys)
    inside &= (xs >= 0) & (xs <= W - 1) & (ys >= 0) & (ys <= H - 1)
    x0 = np.clip(np.floor(np.where(inside, xs, 0)).astype(int), 0, W - 2)
    y0 = np.clip(np.floor(np.where(inside, ys, 0)).astype(int), 0, H - 2)
    fx, fy = np.where(inside, xs, 0) - x0, np.where(inside, ys, 0) - y0
    d = disparity_next
    out = (
        d[y0, x0] * (1 - fx) * (1 - fy)
        + d[y0, x0 + 1] * fx * (1 - fy)
        + d[y0 + 1, x0] * (1 - fx) * fy
        + d[y0 + 1, x0 + 1] * fx * fy
    )
    out[~inside] = np.nan
    return out.astype(np.float32)


def interpolate_background(disparity: np.ndarray) -> np.ndarray:
    """The devkit's ``interpolateBackground``, approximately: each row's holes take the
    smaller (farther) of the valid values either side, or the one there is; rows still
    empty take the nearest filled row's values."""
    d = np.array(disparity, dtype=np.float64)
    H, W = d.shape
    idx = np.arange(W)
    for row in d:
        valid = np.isfinite(row)
        if not valid.any() or valid.all():
            continue
        left = np.maximum.accumulate(np.where(valid, idx, -1))
        right = np.minimum.accumulate(np.where(valid, idx, W)[::-1])[::-1]
        lv = np.where(left >= 0, row[np.clip(left, 0, W - 1)], np.inf)
        rv = np.where(right < W, row[np.clip(right, 0, W - 1)], np.inf)
        row[~valid] = np.minimum(lv, rv)[~valid]
    empty = ~np.isfinite(d).any(axis=1)
    if empty.any() and not empty.all():
        rows = np.flatnonzero(~empty)
        nearest = rows[np.abs(np.arange(H)[:, None] - rows[None, :]).argmin(axis=1)]
        d[empty] = d[nearest[empty]]
    return d.astype(np.float32)
