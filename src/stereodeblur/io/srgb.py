"""The sRGB transfer curve (IEC 61966-2-1), for scenes stored with ``color = 'srgb'``."""

from __future__ import annotations

import numpy as np


def _float_out(x) -> tuple[np.ndarray, np.dtype]:
    x = np.asarray(x)
    dtype = x.dtype if np.issubdtype(x.dtype, np.floating) else np.dtype(np.float64)
    return x.astype(np.float64), dtype


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """Decode the sRGB curve (IEC 61966-2-1): values in [0, 1] to linear [0, 1].

    Keeps a floating input's dtype (float64 otherwise).
    """
    x, dtype = _float_out(x)
    curve = ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4
    return np.where(x <= 0.04045, x / 12.92, curve).astype(dtype)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Encode the sRGB curve (IEC 61966-2-1): linear [0, 1] to sRGB [0, 1].

    Keeps a floating input's dtype (float64 otherwise).
    """
    x, dtype = _float_out(x)
    curve = 1.055 * np.maximum(x, 0.0031308) ** (1 / 2.4) - 0.055
    return np.where(x <= 0.0031308, x * 12.92, curve).astype(dtype)
