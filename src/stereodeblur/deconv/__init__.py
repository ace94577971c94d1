"""Deconvolution: IRLS with the sparse gradient prior (paper Sec. 3).

Start at :func:`deblur_irls` (Eq. 6-8): it minimises
``sum_x || w(x) (B(x) - A_x I) ||^2 + alpha sum |d I|^0.8`` by iteratively reweighted least
squares, 10 iterations of 25 conjugate-gradient steps (:mod:`.cg`) with the prior weights of
Eq. 7 (:mod:`.prior`). The data weights ``w`` of Eq. 5 come from :class:`PaperWeights`
(motion-boundary weights updated from the residual every iteration, :mod:`.weights`);
:mod:`.trust` and :mod:`.noise` choose anchors and ``alpha`` for the pipeline.

Names are imported on first use, so importing this package does not load numba.
"""

from __future__ import annotations

from .._lazy import lazy_exports

_EXPORTS = {
    "CGResult": "stereodeblur.deconv.cg",
    "conjugate_gradient": "stereodeblur.deconv.cg",
    "DeblurResult": "stereodeblur.deconv.irls",
    "IrlsIterate": "stereodeblur.deconv.irls",
    "deblur_irls": "stereodeblur.deconv.irls",
    "gradient": "stereodeblur.deconv.prior",
    "gradient_adjoint": "stereodeblur.deconv.prior",
    "PaperWeights": "stereodeblur.deconv.weights",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
