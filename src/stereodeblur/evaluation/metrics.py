"""Image and motion error measures.

Images are compared in [0, 1]; PSNR and SSIM can exclude a border of ``border``
pixels, where content entering the view from outside is not recoverable.
"""

from __future__ import annotations

import numpy as np


def border_for(width: int) -> int:
    """The border the benches leave out of PSNR and SSIM: 2.5 % of the width, at least 4 px."""
    return max(4, round(0.025 * width))


def _crop(a: np.ndarray, border: int) -> np.ndarray:
    return a[border : a.shape[0] - border, border : a.shape[1] - border] if border else a


def psnr(
    estimate: np.ndarray, reference: np.ndarray, *, border: int = 0, peak: float = 1.0
) -> float:
    """Peak signal-to-noise ratio in dB of ``estimate`` clipped to [0, peak]."""
    e = _crop(np.clip(np.asarray(estimate, dtype=np.float64), 0, peak), border)
    r = _crop(np.asarray(reference, dtype=np.float64), border)
    mse = float(np.mean((e - r) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(peak**2 / mse)


def masked_mse(
    estimate: np.ndarray, reference: np.ndarray, mask: np.ndarray, *, border: int = 0
) -> float:
    """Mean squared error of ``estimate`` clipped to [0, 1] over the pixels of ``mask``
    (and channels); NaN if ``mask`` is empty."""
    inside = _crop(np.asarray(mask, dtype=bool), border)
    if not inside.any():
        return float("nan")
    e = _crop(np.clip(np.asarray(estimate, dtype=np.float64), 0, 1), border)
    r = _crop(np.asarray(reference, dtype=np.float64), border)
    return float(np.mean((e - r)[inside] ** 2))


def ssim(estimate: np.ndarray, reference: np.ndarray, *, border: int = 0) -> float:
    """Structural similarity (Wang et al. 2004, Gaussian window) of images in [0, 1]."""
    from skimage.metrics import structural_similarity

    e = _crop(np.clip(np.asarray(estimate, dtype=np.float64), 0, 1), border)
    r = _crop(np.asarray(reference, dtype=np.float64), border)
    return float(
        structural_similarity(
            e,
            r,
            data_range=1.0,
            gaussian_weights=True,
            sigma=1.5,
            use_sample_covariance=False,
            channel_axis=-1 if e.ndim == 3 else None,
        )
    )


def endpoint_error(flow: np.ndarray, reference: np.ndarray) -> float:
    """Mean endpoint error (AEP) in pixels over pixels with a known reference flow.

    Non-finite estimates count as zero flow.
    """
    f = np.nan_to_num(np.asarray(flow, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    r = np.asarray(reference, dtype=np.float64)
    known = np.all(np.isfinite(r), axis=-1)
    return float(np.mean(np.linalg.norm(f - r, axis=-1)[known]))


def disparity_error(disparity: np.ndarray, reference: np.ndarray) -> float:
    """Mean absolute disparity error (ADE) in pixels over pixels with a known reference.

    Holes (non-finite estimates) count as zero disparity.
    """
    d = np.nan_to_num(np.asarray(disparity, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    r = np.asarray(reference, dtype=np.float64)
    known = np.isfinite(r) & (r > 0)
    return float(np.mean(np.abs(d - r)[known]))
