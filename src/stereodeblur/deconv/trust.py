"""Where the blur model can be trusted: the motion's temporal consistency.

The blur operator of a frame is right where the motion it was built from is right. The
same motion also predicts the neighbouring frame: frame ``t + 1`` at ``x + f(x)`` shows what
frame ``t`` shows at ``x``, blur included (both frames are smeared by nearly the same
motion). Where that prediction fails, the motion is wrong there (a scene-flow error), or
``x`` lies at a motion boundary or is occluded, and deconvolving with the model puts
artefacts where there was only blur.

``trust(x) = c(x) / (1 + e(x)^2 / s(x)^2)``, with ``c(x)`` the share of a Gaussian window
(deviation ``smoothing`` px) that has a correspondence (stays in view, not marked
occluded), ``e(x)^2`` the window's mean over those pixels of ``|B_next(x + f(x)) - B(x)|^2``
(mean over channels, bilinear sampling) and

    ``s(x)^2 = relative^2 e_0(x)^2 + scale^2 + (3 sigma)^2``,

``e_0(x)^2`` the same window mean of ``|B_next(x) - B(x)|^2`` (no motion), ``sigma`` the
noise level of ``B``. The first term makes the test relative: a motion that explains all
but a fraction ``relative`` of the change between the frames is trusted half, whatever the
contrast of the texture or the length of the blur (the error a wrong kernel does grows
with both, and so does what keeping the blurred pixel costs). The last term keeps two
noisy frames (``e^2 = 2 sigma^2``) at ``trust > 0.8``.
Pixels whose flow leaves the view or that are marked occluded get ``trust = 0``, and their
neighbours less than 1.

Deblurring with a blur model that has nothing better at its boundaries uses it as an
anchor (``deblur_irls(anchor=...)``), ``beta = strength (1 - trust)``: where the model is
not trusted the estimate stays near the blurred frame. Zero data weights (the paper's Eq. 5
taken to its limit) would leave those pixels to the prior alone, which on texture is worse
than the blur. Where the pipeline takes the boundaries' blur from the dense optical flow
(:func:`stereodeblur.pipeline.boundary_motion`), it sets no anchor: there the anchor only
kept the boundaries' blur.

Where the motion fails visibly somewhere, it is also less exact everywhere else (a
piecewise-planar fit of curved or independently moving objects): :func:`alpha_from_trust`
raises the prior weight with the share of untrusted pixels, up to the paper's 0.001 (why:
``docs/defaults.md#trust-floor``).

Separately from the motion, the blur model is wrong where it reaches outside the view: a
pixel whose exposure path leaves the image (:func:`leaves_view`) mixes in content the frame
does not show, which both blur operators replace by the edge pixel's (the border rule of
:mod:`stereodeblur.blur.trajectories`). Fitting those pixels forces the model's error into
the estimate, where it rings up to ~30 px inwards, differently for the two kernel types.
The pipeline gives them the small data weight :data:`OUTSIDE_WEIGHT`, so that the prior and
their neighbours' data decide them, and does not count them in :func:`alpha_from_trust`
(why: ``docs/defaults.md#exposure-leaving-the-view``).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

from ..errors import InputError
from ..settings import PAPER_ALPHA
from .noise import estimate_noise_sigma

# Why (the trust's constants): docs/defaults.md#trust-floor
TRUST_RELATIVE = 0.5
"""``relative``: the share of the frame-to-frame change left unexplained at ``trust = 0.5``."""

TRUST_SCALE = 0.005
"""``scale``: floor of ``s`` (intensity), for static or flat regions."""

UNTRUSTED_SHARE = 0.02
"""Share of untrusted pixels (trust < 0.5) from which :func:`alpha_from_trust` gives the
paper's alpha."""


# Why: docs/defaults.md#boundary-handling
ANCHOR_STRENGTH = 0.3
"""``strength`` of the anchor, relative to the data term's unit weight."""

# Why: docs/defaults.md#boundary-band
BOUNDARY_RELATIVE = 0.02
"""Least flow difference of a motion boundary, as a share of the flow's length
(:func:`near_motion_boundaries`): the segments of one surface whose long flows differ by a
fraction of a pixel are not a boundary."""

# Why: docs/defaults.md#exposure-leaving-the-view
OUTSIDE_WEIGHT = 0.1
"""Data weight ``w`` of the pixels whose exposure path leaves the view."""

# Why: docs/defaults.md#exposure-leaving-the-view
LEAVES_MARGIN = 0.0
"""``margin`` of :func:`leaves_view` in pixels: the straight path's ends are exact for the
clamp rule."""


def _as_3d(image, name: str) -> np.ndarray:
    image = np.asarray(image, dtype=np.float64)
    if image.ndim not in (2, 3):
        raise InputError(f"{name} must have shape (H, W) or (H, W, C), got {image.shape}")
    return image if image.ndim == 3 else image[..., None]


def motion_trust(
    blurred: np.ndarray,
    blurred_next: np.ndarray,
    flow: np.ndarray,
    *,
    occlusion: np.ndarray | None = None,
    relative: float = TRUST_RELATIVE,
    scale: float = TRUST_SCALE,
    smoothing: float = 2.0,
    noise_sigma: float | None = None,
) -> np.ndarray:
    """Trust in the blur model per pixel, float32 ``(H, W)`` in [0, 1] (module docstring).

    Parameters
    ----------
    blurred, blurred_next : ndarray, shape (H, W) or (H, W, C)
        The frame to deblur and the frame its motion leads to.
    flow : ndarray, shape (H, W, 2)
        Flow ``(u, v)`` from ``blurred`` to ``blurred_next``.
    occlusion : ndarray of bool, shape (H, W), optional
        Pixels without a reliable correspondence (trust 0).
    relative : float
        Unexplained share of the frame-to-frame change that gives ``trust = 0.5``.
    scale : float
        Floor of the residual scale ``s``.
    smoothing : float
        Deviation in pixels of the window of ``e``.
    noise_sigma : float, optional
        Noise level of ``blurred``; estimated from it when None.
    """
    (trust,) = motion_trusts(
        blurred,
        blurred_next,
        (flow,),
        occlusion=occlusion,
        relative=relative,
        scale=scale,
        smoothing=smoothing,
        noise_sigma=noise_sigma,
    )
    return trust


def motion_trusts(
    blurred: np.ndarray,
    blurred_next: np.ndarray,
    flows,
    *,
    occlusion: np.ndarray | None = None,
    relative: float = TRUST_RELATIVE,
    scale: float = TRUST_SCALE,
    smoothing: float = 2.0,
    noise_sigma: float | None = None,
) -> list[np.ndarray]:
    """:func:`motion_trust` of each of several flows between the same two frames.

    Each map equals :func:`motion_trust`'s; what does not depend on the flow (the frames'
    difference and its window mean) is computed once.

    Parameters
    ----------
    flows : sequence of ndarray, shape (H, W, 2)
        Flows ``(u, v)`` from ``blurred`` to ``blurred_next``.
    blurred, blurred_next, occlusion, relative, scale, smoothing, noise_sigma
        As for :func:`motion_trust`.
    """
    b = _as_3d(blurred, "blurred")
    b_next = _as_3d(blurred_next, "blurred_next")
    flows = [np.asarray(flow, dtype=np.float64) for flow in flows]
    H, W = b.shape[:2]
    if b_next.shape != b.shape or any(flow.shape != (H, W, 2) for flow in flows):
        shapes = ", ".join(str(flow.shape) for flow in flows)
        raise InputError(
            f"blurred {b.shape}, blurred_next {b_next.shape} and flow {shapes} "
            "must cover the same (H, W)"
        )
    for name, value in (("relative", relative), ("scale", scale), ("smoothing", smoothing)):
        if not (np.isfinite(value) and value >= 0):
            raise InputError(f"{name} must be a non-negative number, got {value!r}")
    if occlusion is not None:
        occlusion = np.asarray(occlusion, dtype=bool)
        if occlusion.shape != (H, W):
            raise InputError(f"occlusion must have shape {(H, W)}, got {occlusion.shape}")
    if not flows:
        return []
    sigma = estimate_noise_sigma(blurred) if noise_sigma is None else float(noise_sigma)
    still = np.mean((b_next - b) ** 2, axis=2)
    if smoothing > 0:
        still = ndimage.gaussian_filter(still, smoothing, mode="nearest")
    s2 = relative**2 * still + scale**2 + (3.0 * sigma) ** 2
    b, b_next = np.ascontiguousarray(b), np.ascontiguousarray(b_next)
    trusts = []
    for flow in flows:
        squared, leaves = _residuals(b, b_next, np.ascontiguousarray(flow), occlusion)
        share = (~leaves).astype(np.float64)
        if smoothing > 0:
            share = ndimage.gaussian_filter(share, smoothing, mode="nearest")
            squared = ndimage.gaussian_filter(squared, smoothing, mode="nearest")
            squared = squared / np.maximum(share, 1e-6)
        trust = share / (1.0 + squared / np.maximum(s2, 1e-24))
        trust[leaves] = 0.0
        trusts.append(np.clip(trust, 0.0, 1.0).astype(np.float32))
    return trusts


def _residuals(b, b_next, flow, occlusion) -> tuple[np.ndarray, np.ndarray]:
    """``(e^2, leaves)`` per pixel before the window: the mean over channels of
    ``|B_next(x + f(x)) - B(x)|^2`` (0 where the pixel leaves the view or is occluded) and
    where it does. Rows in parallel.

    ``B_next`` is sampled bilinearly as ``ndimage.map_coordinates(..., order=1,
    mode='nearest')`` samples it, bit for bit (the same weights ``w_0 = 1 - f``,
    ``w_1 = 1 - w_0``, taps clamped to the image, the same order of products and sums), and
    the mean sums the channels in order, as ``np.mean`` does
    (``tests/pipeline/test_shared_trust.py``).
    """
    from .._threads import run_ranges

    height = b.shape[0]
    squared = np.empty(b.shape[:2])
    leaves = np.empty(b.shape[:2], bool)
    occluded = np.zeros((0, 0), bool) if occlusion is None else occlusion
    parts = 2 * numba.get_num_threads() if b.size >= 1 << 16 else 1
    bounds = np.linspace(0, height, parts + 1).round().astype(np.int64)
    ranges = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]
    run_ranges(_residual_rows, ranges, b, b_next, flow, occluded, squared, leaves)
    return squared, leaves


@numba.njit(cache=True, nogil=True, inline="always")
def _taps(coordinate, size):
    """The two taps along one axis and their weights, as ``map_coordinates`` has them."""
    start = np.floor(coordinate)
    w0 = 1.0 - (coordinate - start)
    first = min(max(start, 0.0), size - 1.0)
    second = min(max(start + 1.0, 0.0), size - 1.0)
    return np.int64(first), np.int64(second), w0, 1.0 - w0


@numba.njit(cache=True, nogil=True)
def _residual_rows(first, last, b, b_next, flow, occluded, squared, leaves):
    """Rows ``first .. last - 1`` of :func:`_residuals`."""
    height, width, channels = b.shape
    for y in range(first, last):
        for x in range(width):
            xs = x + flow[y, x, 0]
            ys = y + flow[y, x, 1]
            known = np.isfinite(xs) and np.isfinite(ys)
            if not known:
                xs = float(x)
                ys = float(y)
            out = not known or xs < 0 or xs > width - 1 or ys < 0 or ys > height - 1
            if occluded.shape[0] > 0 and occluded[y, x]:
                out = True
            leaves[y, x] = out
            if out:
                squared[y, x] = 0.0
                continue
            y0, y1, wy0, wy1 = _taps(ys, height)
            x0, x1, wx0, wx1 = _taps(xs, width)
            total = 0.0
            for c in range(channels):
                t = 0.0
                t += b_next[y0, x0, c] * wy0 * wx0
                t += b_next[y0, x1, c] * wy0 * wx1
                t += b_next[y1, x0, c] * wy1 * wx0
                t += b_next[y1, x1, c] * wy1 * wx1
                d = t - b[y, x, c]
                total = d * d if c == 0 else total + d * d
            squared[y, x] = total / channels


def trust_anchor(trust: np.ndarray, *, strength: float = ANCHOR_STRENGTH) -> np.ndarray:
    """``beta = strength (1 - trust)`` for ``deblur_irls(anchor=...)``, float32 ``(H, W)``."""
    if not (np.isfinite(strength) and strength >= 0):
        raise InputError(f"strength must be a non-negative number, got {strength!r}")
    trust = np.asarray(trust, dtype=np.float32)
    return (strength * (1.0 - np.clip(trust, 0.0, 1.0))).astype(np.float32)


def alpha_from_trust(
    trust: np.ndarray, *, share: float = UNTRUSTED_SHARE, alpha: float = PAPER_ALPHA
) -> float:
    """Prior weight the motion's errors call for: ``alpha * min(1, q / share)``.

    ``q`` is the share of pixels with ``trust < 0.5``. The pipeline takes the larger of this
    and the noise-driven :func:`stereodeblur.deconv.noise.auto_alpha`.
    """
    if not (np.isfinite(share) and share > 0 and np.isfinite(alpha) and alpha >= 0):
        raise InputError(f"share and alpha must be positive numbers, got {share!r}, {alpha!r}")
    untrusted = float(np.mean(np.asarray(trust) < 0.5))
    return float(alpha * min(1.0, untrusted / share))


def near_motion_boundaries(
    flow: np.ndarray, duty_cycle: float, *, jump: float = 0.5, relative: float = BOUNDARY_RELATIVE
) -> np.ndarray:
    """Pixels that a motion boundary's blur can reach, bool ``(H, W)``.

    A boundary is a pair of 4-neighbours whose flows differ by more than ``jump`` px and by
    more than ``relative`` times the longer of the two flows (an estimated motion's error
    grows with the motion: the segments of one rigid surface disagree by a small share of
    it, which is no boundary). The band reaches ``2 + duty_cycle * |f|_95`` px from it
    (``|f|_95`` the 95th percentile of the flow's length: how far content moves during the
    exposure). Elsewhere (a smoothly moving surface) a failed prediction of the neighbouring
    frame comes from the blur changing between the frames (an approach), not from a wrong
    motion, and is not held against it.
    """
    flow = np.asarray(flow, dtype=np.float64)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise InputError(f"flow must have shape (H, W, 2), got {flow.shape}")
    flow = np.nan_to_num(flow)
    length = np.hypot(flow[..., 0], flow[..., 1])
    seeds = np.zeros(flow.shape[:2], bool)
    for a, b in (
        ((slice(None), slice(None, -1)), (slice(None), slice(1, None))),
        ((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
    ):
        longer = np.maximum(length[a], length[b])
        differ = np.hypot(*np.moveaxis(flow[a] - flow[b], -1, 0)) > np.maximum(
            jump, relative * longer
        )
        seeds[a] |= differ
        seeds[b] |= differ
    if not seeds.any():
        return seeds
    reach = 2.0 + duty_cycle * float(np.percentile(length, 95))
    return ndimage.distance_transform_edt(~seeds) <= reach


def leaves_view(
    flow_forward: np.ndarray,
    flow_backward: np.ndarray | None,
    duty_cycle: float,
    *,
    margin: float = LEAVES_MARGIN,
) -> np.ndarray:
    """Pixels whose path during the exposure leaves the view, bool ``(H, W)``.

    The path of pixel ``x`` runs straight from ``x + (tau / 2) f_b(x)`` to
    ``x + (tau / 2) f_f(x)`` (``tau = duty_cycle``, the displacement kernels' model); it
    leaves the view where an end lies outside ``[margin, W - 1 - margin] x [margin, H - 1 -
    margin]``. The blurred pixel then shows content from outside the frame, which the blur
    operators replace by the edge pixel's. Non-finite flows count as leaving.

    Parameters
    ----------
    flow_forward : ndarray, shape (H, W, 2)
        Flow ``(u, v)`` to the next frame.
    flow_backward : ndarray, shape (H, W, 2), or None
        Flow to the previous frame; ``-flow_forward`` when None.
    duty_cycle : float
        Exposure time over frame interval, in [0, 1].
    margin : float
        Distance in pixels from the outermost pixel centres at which a path counts as
        leaving (a ring this wide always does).
    """
    forward = np.asarray(flow_forward, dtype=np.float64)
    if forward.ndim != 3 or forward.shape[2] != 2:
        raise InputError(f"flow_forward must have shape (H, W, 2), got {forward.shape}")
    if flow_backward is None:
        backward = -forward
    else:
        backward = np.asarray(flow_backward, dtype=np.float64)
        if backward.shape != forward.shape:
            raise InputError(
                f"flow_backward must have the shape of flow_forward {forward.shape}, "
                f"got {backward.shape}"
            )
    if not (np.isfinite(duty_cycle) and 0 <= duty_cycle <= 1):
        raise InputError(f"duty_cycle must be in [0, 1], got {duty_cycle!r}")
    if not (np.isfinite(margin) and margin >= 0):
        raise InputError(f"margin must be a non-negative number, got {margin!r}")
    H, W = forward.shape[:2]
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    leaves = np.zeros((H, W), bool)
    for flow in (forward, backward):
        with np.errstate(invalid="ignore"):
            ex = x + 0.5 * duty_cycle * flow[..., 0]
            ey = y + 0.5 * duty_cycle * flow[..., 1]
        inside = (ex >= margin) & (ex <= W - 1 - margin) & (ey >= margin) & (ey <= H - 1 - margin)
        leaves |= ~inside  # NaN compares False: a non-finite flow leaves
    return leaves
