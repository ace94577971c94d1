"""Blur operators: the exposure integral of the paper's Eq. 3-4 as a sparse matrix.

Start at :func:`homography_blur` (Eq. 3): the blur of one view under piecewise-rigid scene
flow, each row the mean of ``N = 70`` samples of the sharp image along the pixel's trajectory,
each interpolated by Keys' cubic convolution (``interpolation='cubic'``, the default of the
builders, of :class:`~stereodeblur.settings.DeblurSettings` and of the command line) or
bilinearly as in the paper (``interpolation='bilinear'``). It returns a :class:`SparseBlur`
(``forward`` = ``A I``, ``adjoint`` = ``A^T B``, ``gram`` = ``A^T W^2 A I`` in one pass over
the matrix), the operator that :func:`stereodeblur.deconv.deblur_irls` inverts;
:class:`TiledBlur` holds only what its float32 products read.
:func:`displacement_blur` builds the same kind of operator from 2D flow, and
:mod:`.trajectories` holds the sampling rules both share. :func:`estimate_duty_cycle` reads
the exposure (as a share of the frame interval) from a blurred frame and its optical flow.

Names are imported on first use, so importing this package does not load numba.
"""

from __future__ import annotations

from .._lazy import lazy_exports

_EXPORTS = {
    "homography_blur": "stereodeblur.blur.homography",
    "displacement_blur": "stereodeblur.blur.displacement",
    "SparseBlur": "stereodeblur.blur.operator",
    "TiledBlur": "stereodeblur.blur.operator",
    "dot_test": "stereodeblur.blur.operator",
    "estimate_duty_cycle": "stereodeblur.blur.exposure",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
