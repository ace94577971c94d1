"""Initial disparity by semi-global matching and initial optical flow by DIS.

These are the correspondences the scene flow starts from. The optical flow is
the paper's "initial optical flow" (the baseline that later figures compare
with). Both work on 8-bit grey images, as OpenCV needs; :func:`to_gray_u8`
converts the float images in [0, 1] of the rest of the package. Disparities
are left-view, in pixels (``x_right = x_left - d``), NaN where the matcher
found no consistent match; flow is ``(u, v)`` along x and y.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# DIS settings: full-resolution finest scale for sub-pixel accuracy, overlapping
# 8x8 patches, and a variational refinement for a dense, smooth field.
_DIS_PATCH_SIZE = 8
_DIS_PATCH_STRIDE = 3
_DIS_GRADIENT_ITERATIONS = 25
_DIS_VARIATIONAL_ITERATIONS = 5


def to_gray(image: np.ndarray) -> np.ndarray:
    """Grey float32 (H, W) of an (H, W) or (H, W, 3) image (Rec. 601 luma weights)."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 3 and image.shape[2] == 3:
        return image @ np.array([0.299, 0.587, 0.114], dtype=np.float32)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[..., 0]
    if image.ndim != 2:
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got {image.shape}")
    return image


def to_gray_u8(image: np.ndarray, *, scale: float = 1.0) -> np.ndarray:
    """8-bit grey of a float image in [0, 1], multiplied by ``scale`` before rounding."""
    gray = np.nan_to_num(to_gray(image), nan=0.0) * np.float32(scale)
    return np.clip(np.rint(gray * 255.0), 0, 255).astype(np.uint8)


def initial_optical_flow(
    image_a: np.ndarray, image_b: np.ndarray, *, finest_scale: int = 0
) -> np.ndarray:
    """Dense optical flow from ``image_a`` to ``image_b`` by DIS (Kroeger et al. 2016).

    Parameters
    ----------
    image_a, image_b : ndarray, shape (H, W) or (H, W, 3)
        Float images in [0, 1] (or uint8 grey).
    finest_scale : int
        Finest pyramid level DIS searches on (0: full resolution, the default;
        1: half, about four times faster), followed by variational refinement.

    Returns
    -------
    ndarray, shape (H, W, 2), float32
        ``(u, v)`` such that pixel ``(x, y)`` of ``image_a`` is seen at
        ``(x + u, y + v)`` in ``image_b``.
    """
    a = image_a if np.asarray(image_a).dtype == np.uint8 else to_gray_u8(image_a)
    b = image_b if np.asarray(image_b).dtype == np.uint8 else to_gray_u8(image_b)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"images must be the same (H, W) size, got {a.shape} and {b.shape}")
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setFinestScale(int(finest_scale))
    dis.setPatchSize(_DIS_PATCH_SIZE)
    dis.setPatchStride(_DIS_PATCH_STRIDE)
    dis.setGradientDescentIterations(_DIS_GRADIENT_ITERATIONS)
    dis.setVariationalRefinementIterations(_DIS_VARIATIONAL_ITERATIONS)
    dis.setUseMeanNormalization(True)
    dis.setUseSpatialPropagation(True)
    flow = dis.calc(np.ascontiguousarray(a), np.ascontiguousarray(b), None)
    return np.nan_to_num(flow.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)


def default_max_disparity(width: int) -> int:
    """Disparity search range: a quarter of the width, a multiple of 16 in [16, 256]."""
    return int(min(256, max(16, 16 * int(np.ceil(width / 4 / 16)))))


def initial_disparity(
    left: np.ndarray,
    right: np.ndarray,
    *,
    max_disparity: int | None = None,
    block_size: int = 5,
) -> np.ndarray:
    """Left-view disparity by OpenCV's semi-global block matching (Hirschmueller 2008).

    The left image is padded by the search range so that pixels near the left
    border get a disparity too; the matcher's left-right check and speckle
    filter leave NaN holes where no consistent match exists.

    Parameters
    ----------
    left, right : ndarray, shape (H, W) or (H, W, 3)
        Float images in [0, 1] (or uint8 grey) of a rectified pair.
    max_disparity : int, optional
        Search range in pixels (rounded up to a multiple of 16); default
        :func:`default_max_disparity`.
    block_size : int
        Matching block size (odd).

    Returns
    -------
    ndarray, shape (H, W), float32
        Disparity in pixels, NaN where unknown.
    """
    a = left if np.asarray(left).dtype == np.uint8 else to_gray_u8(left)
    b = right if np.asarray(right).dtype == np.uint8 else to_gray_u8(right)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"images must be the same (H, W) size, got {a.shape} and {b.shape}")
    height, width = a.shape
    if max_disparity is None:
        max_disparity = default_max_disparity(width)
    num = int(16 * max(1, int(np.ceil(max_disparity / 16))))
    channels = 1
    matcher = cv2.StereoSGBM_create(
        minDisparity=0,
        numDisparities=num,
        blockSize=block_size,
        P1=8 * channels * block_size**2,
        P2=32 * channels * block_size**2,
        disp12MaxDiff=1,
        preFilterCap=63,
        uniquenessRatio=10,
        speckleWindowSize=100,
        speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )
    a_pad = cv2.copyMakeBorder(a, 0, 0, num, 0, cv2.BORDER_REPLICATE)
    b_pad = cv2.copyMakeBorder(b, 0, 0, num, 0, cv2.BORDER_REPLICATE)
    raw = matcher.compute(a_pad, b_pad)[:, num:]
    disparity = raw.astype(np.float32) / 16.0
    disparity[raw <= 0] = np.nan
    # A match that would fall left of the right image's first column is unsupported.
    x = np.arange(width, dtype=np.float32)[None, :]
    disparity[x - disparity < -0.5] = np.nan
    return disparity


@dataclass(frozen=True)
class InitialMatches:
    """The correspondences the scene flow starts from (stage 2).

    Attributes
    ----------
    disparity, disparity_next : ndarray, (H, W) float32
        Semi-global matching disparity at t and at t + 1 (in frame t + 1's pixels), NaN in
        holes.
    flow : ndarray, (H, W, 2) float32
        DIS optical flow of the left view, t -> t + 1 (the paper's "initial optical flow").
    flow_back : ndarray, (H, W, 2) float32
        DIS flow t + 1 -> t at half resolution, for the occlusion check only.
    messages : tuple of str
        Problems found (stereo matching found next to nothing).
    """

    disparity: np.ndarray
    disparity_next: np.ndarray
    flow: np.ndarray
    flow_back: np.ndarray
    messages: tuple[str, ...] = ()


def initial_matches(u8: tuple[np.ndarray, ...]) -> InitialMatches:
    """Disparities at t and t + 1 and the left view's flow both ways, from the four 8-bit
    frames (left t, right t, left t + 1, right t + 1)."""
    disparity = initial_disparity(u8[0], u8[1])
    disparity_next = initial_disparity(u8[2], u8[3])
    flow = initial_optical_flow(u8[0], u8[2])
    flow_back = initial_optical_flow(u8[2], u8[0], finest_scale=1)
    messages = ()
    valid_fraction = float(np.mean(np.isfinite(disparity)))
    if valid_fraction < 0.05:
        messages = (
            f"stereo matching found a disparity for only {100 * valid_fraction:.1f}% of the "
            "pixels at frame t",
        )
    return InitialMatches(disparity, disparity_next, flow, flow_back, messages)
