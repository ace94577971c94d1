"""Blur operators and test images for the deconvolution tests, built here with scipy.sparse."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from skimage import data, transform

from stereodeblur.blur.operator import SparseBlur


def horizontal_box_matrix(lengths: np.ndarray) -> sp.csr_matrix:
    """Row-stochastic CSR blur: pixel (y, x) averages ``lengths[y, x]`` (odd) pixels along x.

    Columns outside the image are clamped to the border (replicate boundary).
    """
    height, width = lengths.shape
    half = (lengths // 2).astype(np.int64)
    offsets = np.arange(-half.max(), half.max() + 1)
    ys, xs = np.mgrid[0:height, 0:width]
    inside = np.abs(offsets)[None, None, :] <= half[..., None]
    cols = np.clip(xs[..., None] + offsets, 0, width - 1)
    rows = np.broadcast_to((ys * width + xs)[..., None], inside.shape)
    values = np.broadcast_to((1.0 / lengths)[..., None], inside.shape)
    n = height * width
    matrix = sp.coo_matrix(
        (values[inside], (rows[inside], (ys[..., None] * width + cols)[inside])), shape=(n, n)
    )
    return matrix.tocsr().astype(np.float32)


def varying_lengths(shape, low: int, high: int, seed: int) -> np.ndarray:
    """Odd box lengths in [low, high] varying smoothly over the image."""
    rng = np.random.default_rng(seed)
    height, width = shape
    ys, xs = np.mgrid[0:height, 0:width]
    phase = rng.uniform(0, 2 * np.pi, 2)
    field = 0.5 + 0.25 * (
        np.sin(2 * np.pi * xs / width + phase[0]) + np.cos(np.pi * ys / height + phase[1])
    )
    lengths = low + np.round(field * (high - low) / 2) * 2
    return np.clip(lengths, low, high).astype(np.int64)


@pytest.fixture
def box_blur():
    """``box_blur(shape, low, high, seed=0, identity=0.0) -> SparseBlur``.

    ``identity`` mixes in the identity: ``identity * I + (1 - identity) * box``.
    """

    def build(shape, low, high, seed=0, identity=0.0):
        matrix = horizontal_box_matrix(varying_lengths(shape, low, high, seed))
        if identity:
            n = shape[0] * shape[1]
            matrix = (
                identity * sp.identity(n, dtype=np.float32, format="csr")
                + (1.0 - identity) * matrix
            )
        return SparseBlur(sp.csr_matrix(matrix, dtype=np.float32), tuple(shape))

    return build


@pytest.fixture
def camera_image():
    """``camera_image(shape) -> float32`` grey natural image in [0, 1]."""

    def build(shape):
        image = data.camera().astype(np.float64) / 255.0
        return transform.resize(image, shape, anti_aliasing=True).astype(np.float32)

    return build


@pytest.fixture
def colour_image():
    """``colour_image(shape) -> float32 (H, W, 3)`` natural image in [0, 1]."""

    def build(shape):
        image = data.astronaut().astype(np.float64) / 255.0
        return transform.resize(image, (*shape, 3), anti_aliasing=True).astype(np.float32)

    return build
