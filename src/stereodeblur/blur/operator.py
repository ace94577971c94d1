"""The linear-operator interface shared by blur operators, and the dot test.

An operator maps a sharp image to a blurred one over the same pixel grid. Images
are ``(H, W)`` or ``(H, W, C)``; every channel is blurred by the same matrix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp


@dataclass(frozen=True)
class SparseBlur:
    """A blur operator held as a CSR matrix (rows: blurred pixels, columns: sharp pixels).

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix, shape (H*W, H*W)
        Row-major pixel order, ``index = y * W + x``.
    shape : tuple of int
        Image shape ``(H, W)``.
    """

    matrix: sp.csr_matrix
    shape: tuple[int, int]

    def __post_init__(self):
        n = self.shape[0] * self.shape[1]
        if self.matrix.shape != (n, n):
            raise ValueError(f"matrix shape {self.matrix.shape} does not match image shape {self.shape}")
        object.__setattr__(self, "matrix", sp.csr_matrix(self.matrix))
        object.__setattr__(self, "_matrix_t", sp.csr_matrix(self.matrix.T))

    def _apply(self, M: sp.csr_matrix, image: np.ndarray) -> np.ndarray:
        image = np.asarray(image)
        if image.shape[:2] != tuple(self.shape):
            raise ValueError(f"image shape {image.shape} does not match operator shape {self.shape}")
        flat = image.reshape(M.shape[1], -1)
        return (M @ flat).reshape(image.shape)

    def forward(self, image: np.ndarray) -> np.ndarray:
        """Blur ``image``: ``A I``."""
        return self._apply(self.matrix, image)

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """Apply the transpose: ``A^T B``."""
        return self._apply(self._matrix_t, image)


def dot_test(operator, shape: tuple[int, ...], *, seed: int = 0) -> float:
    """Relative error ``|<A x, y> - <x, A^T y>| / max(|<A x, y>|, |<x, A^T y>|)``.

    ``x`` and ``y`` are drawn from a seeded generator, never global random state.
    """
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(shape)
    y = rng.standard_normal(shape)
    lhs = float(np.vdot(operator.forward(x), y))
    rhs = float(np.vdot(x, operator.adjoint(y)))
    return abs(lhs - rhs) / max(abs(lhs), abs(rhs), 1e-300)
