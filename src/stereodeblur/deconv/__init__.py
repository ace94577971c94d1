"""Deconvolution: conjugate gradients and IRLS with the sparse gradient prior (Sec. 3)."""

from stereodeblur.deconv.cg import CGResult, conjugate_gradient
from stereodeblur.deconv.irls import (
    DeblurResult,
    IrlsIterate,
    deblur_irls,
    gradient,
    gradient_adjoint,
)

__all__ = [
    "CGResult",
    "DeblurResult",
    "IrlsIterate",
    "conjugate_gradient",
    "deblur_irls",
    "gradient",
    "gradient_adjoint",
]
