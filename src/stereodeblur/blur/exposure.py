"""The exposure (duty cycle) of a blurred frame from the frame and its optical flow.

A pixel moving by ``u`` pixels per frame interval is blurred, in a frame exposed for the
fraction ``d`` of the interval (the duty cycle, exposure time x frame rate), along a path of
length ``d |u|``: the blur is a box along the motion. Sampled along the motion's paths (the
flow's streamlines) at a step of ``dt`` frame intervals, every path is a 1-D signal blurred by
a box of ``d / dt`` samples, whose spectrum has zeros at multiples of ``dt / d`` cycles per
sample. :func:`estimate_duty_cycle` fits, in windows over the frame, the spectrum of the
profiles along the streamlines (differenced, tapered, averaged over neighbouring profiles)
with the expected spectrum of a power-law texture blurred by the box plus the frame's noise
(Whittle likelihood; amplitude and texture exponent fitted per window), and adds the windows'
curves (each capped, so that a window with a wrong flow cannot outvote the others). ``d = 0``
(sharp frames) is a candidate like the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy import ndimage

from ..deconv.noise import estimate_noise_sigma

DEFAULT_CANDIDATES = np.concatenate([[0.0], np.geomspace(0.02, 1.0, 61)])
"""Duty cycles tried: 0 (sharp) and 61 values from 0.02 to 1, 6.7 % apart."""

WINDOWS = 300
"""Windows of 16 x 16 pixels above which their spacing grows (:func:`window_stride`)."""
CAP = 10.0
"""Most a window adds to a candidate's curve (nats)."""

_BETAS = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5])
"""Texture exponents tried (power spectrum ``rho**-beta``). No texture roll-off is fitted: a
free one also explains a short blur (small-blur frames then came out sharp)."""
_L_GRID = np.concatenate([[0.0], np.geomspace(0.1, 64.0, 220)])
_FINE = 16


@dataclass(frozen=True)
class DutyEstimate:
    """The duty cycle estimated from one blurred frame.

    Attributes
    ----------
    duty_cycle : float
        Exposure time x frame rate, in [0, 1]; 0 for a sharp frame.
    candidates : ndarray
        The duty cycles tried.
    curve : ndarray
        The summed, capped negative log-likelihood of each candidate, 0 at the minimum.
    confidence : float
        In [0, 1]: 1 when the curve rises steeply on both sides of its minimum.
    windows : int
        Windows that contributed.
    """

    duty_cycle: float
    candidates: np.ndarray = field(repr=False)
    curve: np.ndarray = field(repr=False)
    confidence: float
    windows: int


def central_flow(flows) -> np.ndarray:
    """The motion over one frame interval around a frame, from its optical flows to others.

    Parameters
    ----------
    flows : mapping of int to ndarray, shape (H, W, 2)
        Optical flow from the frame to the frame ``step`` frames away (e.g. ``{1: to_next,
        -1: to_previous}``).

    Returns
    -------
    ndarray, shape (H, W, 2)
        The mean of ``flow / step``.
    """
    if not flows:
        raise ValueError("central_flow needs at least one flow")
    scaled = [np.nan_to_num(np.asarray(f, dtype=np.float64)) / step for step, f in flows.items()]
    if len({f.shape for f in scaled}) != 1 or scaled[0].ndim != 3 or scaled[0].shape[2] != 2:
        raise ValueError(f"flows must all be (H, W, 2), got {[f.shape for f in scaled]}")
    return np.mean(scaled, axis=0)


def _gray(image) -> np.ndarray:
    a = np.asarray(image, dtype=np.float64)
    if a.ndim == 3:
        a = a.mean(axis=2)
    if a.ndim != 2:
        raise ValueError(f"image must be (H, W) or (H, W, C), got shape {np.shape(image)}")
    return a


def _prefilter_sigma(h: int) -> float:
    return 0.0 if h == 1 else 0.5 * h


def _hann(m: int) -> np.ndarray:
    return 0.5 - 0.5 * np.cos(2 * np.pi * (np.arange(m) + 0.5) / m)


def _periodogram(profiles: np.ndarray) -> np.ndarray:
    """Mean periodogram over rows of the differenced, Hann-tapered profiles (bins 1..M/2)."""
    g = np.diff(profiles, axis=-1)
    m = g.shape[-1]
    g = g - g.mean(axis=-1, keepdims=True)
    w = _hann(m)
    p = np.abs(np.fft.rfft(g * w, axis=-1)) ** 2 / np.sum(w**2)
    return p[..., 1 : m // 2 + 1]


@lru_cache(maxsize=16)
def _templates(m: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Expected periodograms (L grid x betas x bins) of a blurred power-law texture, and of noise.

    Texture: spectrum ``rho**-beta * sinc(L rho)**2 * G(rho)**2 * (2 sin pi rho)**2`` per sample
    (``G`` the pre-filter of level ``h``), folded and tapered as :func:`_periodogram` does.
    Noise: unit white noise through the same pre-filter and sampling, simulated.
    """
    f = _FINE * m
    rho = np.arange(f) / f
    rho = np.minimum(rho, 1 - rho)
    rho_safe = np.maximum(rho, 0.25 / f)
    sig = _prefilter_sigma(h)
    gauss2 = np.exp(-4 * np.pi**2 * (sig * rho / h) ** 2)
    diff2 = (2 * np.sin(np.pi * rho)) ** 2
    env = rho_safe[None, :] ** -_BETAS[:, None] * (gauss2 * diff2)[None, :]
    sinc2 = np.sinc(_L_GRID[:, None] * rho[None, :]) ** 2
    spec = sinc2[:, None, :] * env[None, :, :]
    r = np.fft.ifft(spec, axis=-1).real[..., :m]
    w = _hann(m)
    c = np.array([np.sum(w[: m - t] * w[t:]) for t in range(m)]) / np.sum(w**2)
    j = np.arange(1, m // 2 + 1)
    cos = np.cos(2 * np.pi * np.outer(np.arange(m), j) / m)
    cos[1:] *= 2
    tex = np.einsum("lbt,tj->lbj", r * c, cos)
    tex /= tex.mean(axis=-1, keepdims=True)
    rng = np.random.default_rng(12345)
    n = m + 1
    side = n * h + 16
    noise = rng.standard_normal((side, side))
    if sig > 0:
        noise = ndimage.gaussian_filter(noise, sig)
    coef = ndimage.spline_filter(noise, order=3)
    ang = rng.uniform(0, np.pi, 300)
    t = (np.arange(n) - n / 2) * h
    ys = side / 2 + rng.uniform(-4, 4, (300, 1)) + np.sin(ang)[:, None] * t[None, :]
    xs = side / 2 + rng.uniform(-4, 4, (300, 1)) + np.cos(ang)[:, None] * t[None, :]
    prof = ndimage.map_coordinates(coef, [ys, xs], order=3, prefilter=False)
    nt = _periodogram(prof).mean(axis=0)
    return tex, nt


def _streamlines(flow: np.ndarray, starts: np.ndarray, dt: np.ndarray, n: int) -> np.ndarray:
    """Points (P, n, 2) as (y, x) along the flow's streamlines through ``starts`` (P, 2).

    ``n`` points per line, centred on the start, ``dt[p]`` frame intervals apart (RK2).
    """
    fy = np.ascontiguousarray(flow[..., 1])
    fx = np.ascontiguousarray(flow[..., 0])

    def vel(p):
        c = [p[:, 0], p[:, 1]]
        return np.stack(
            [
                ndimage.map_coordinates(fy, c, order=1, mode="nearest"),
                ndimage.map_coordinates(fx, c, order=1, mode="nearest"),
            ],
            axis=1,
        )

    back = n // 2
    out = np.empty((starts.shape[0], n, 2))
    out[:, back] = starts
    for sign, rng_ in ((1, range(back + 1, n)), (-1, range(back - 1, -1, -1))):
        p = starts.copy()
        step = sign * dt[:, None]
        for i in rng_:
            mid = p + 0.5 * step * vel(p)
            p = p + step * vel(mid)
            out[:, i] = p
    return out


def window_stride(shape, windows: int = WINDOWS) -> int:
    """Pixels between window centres: 16, or more on a frame larger than ``windows`` windows of
    16 x 16 pixels, so that the estimate's cost stays bounded."""
    height, width = shape[:2]
    return max(16, round(float(np.sqrt(height * width / windows))))


def window_motion(flow, stride: int, min_flow: float = 2.0) -> tuple:
    """Rows, columns and motion ``(u, v)`` of the window centres, ``stride`` pixels apart, that
    move at least ``min_flow`` pixels per frame (``flow`` median-filtered over 5 x 5 pixels)."""
    flow = np.nan_to_num(np.asarray(flow, dtype=np.float64))
    smooth = np.stack(
        [ndimage.median_filter(flow[..., k], size=5, mode="nearest") for k in range(2)], -1
    )
    height, width = flow.shape[:2]
    ys, xs = np.mgrid[stride // 2 : height : stride, stride // 2 : width : stride]
    ys, xs = ys.ravel(), xs.ravel()
    uc = smooth[ys, xs]
    keep = np.hypot(uc[:, 0], uc[:, 1]) >= min_flow
    return ys[keep], xs[keep], uc[keep]


def duty_cycle_curves(
    blurred,
    flow,
    *,
    candidates=None,
    stride: int | None = None,
    noise: float | None = None,
    length: int = 64,
    lines: int = 12,
    min_flow: float = 2.0,
    max_blur_samples: float = 12.0,
    motion: tuple | None = None,
) -> np.ndarray:
    """Negative log-likelihood of each candidate duty cycle in each window of ``blurred``.

    Parameters
    ----------
    blurred : ndarray, shape (H, W) or (H, W, C)
        The blurred frame, linear values.
    flow : ndarray, shape (H, W, 2)
        ``(u, v)`` per pixel: its motion over one frame interval around the frame
        (:func:`central_flow`).
    candidates : array_like, optional
        Duty cycles tried (default :data:`DEFAULT_CANDIDATES`, 0 included).
    stride : int, optional
        Pixels between window centres (default :func:`window_stride`).
    noise : float, optional
        Deviation of the frame's noise (grey values); estimated if not given.
    length, lines : int
        Samples per profile along a streamline; profiles per window, side by side.
    min_flow : float
        Windows whose motion is shorter (pixels per frame) are not used.
    max_blur_samples : float
        The profiles' step (1, 2, 4 or 8 pixels, the frame pre-filtered to match) is chosen
        so that the longest candidate blur spans at most this many samples.
    motion : tuple, optional
        :func:`window_motion` of ``flow``, ``stride`` and ``min_flow``, if already computed.

    Returns
    -------
    ndarray, shape (windows, candidates)
        Each window's curve, divided by its over-dispersion (at least 1).
    """
    gray = _gray(blurred)
    flow = np.asarray(flow, dtype=np.float64)
    if flow.shape != gray.shape + (2,):
        raise ValueError(f"flow must have shape {gray.shape + (2,)}, got {flow.shape}")
    flow = np.nan_to_num(flow)
    cand = _candidates(candidates)
    sigma_n = estimate_noise_sigma(gray) if noise is None else float(noise)
    stride = window_stride(gray.shape) if stride is None else int(stride)
    height, width = gray.shape
    ys, xs, uc = window_motion(flow, stride, min_flow) if motion is None else motion
    speed = np.hypot(uc[:, 0], uc[:, 1])
    level = np.clip(np.ceil(np.log2(np.maximum(speed / max_blur_samples, 1.0))), 0, 3).astype(int)
    curves = []
    for lev in np.unique(level):
        h = int(2**lev)
        sel = level == lev
        sig = _prefilter_sigma(h)
        img = ndimage.gaussian_filter(gray, sig) if sig > 0 else gray
        coef = ndimage.spline_filter(img, order=3)
        e = uc[sel] / speed[sel, None]
        across = np.stack([e[:, 0], -e[:, 1]], 1)  # (y, x) of the direction across the motion
        centre = np.stack([ys[sel], xs[sel]], 1).astype(np.float64)
        k = (np.arange(lines) - (lines - 1) / 2) * h
        starts = (centre[:, None, :] + k[None, :, None] * across[:, None, :]).reshape(-1, 2)
        pts = _streamlines(flow, starts, np.repeat(h / speed[sel], lines), length + 1)
        inside = (
            (pts[..., 0] >= 1)
            & (pts[..., 0] <= height - 2)
            & (pts[..., 1] >= 1)
            & (pts[..., 1] <= width - 2)
        ).all(axis=1)
        coords = [pts[..., 0].ravel(), pts[..., 1].ravel()]
        prof = ndimage.map_coordinates(coef, coords, order=3, prefilter=False)
        tex, nt = _templates(length, h)
        nsel = int(sel.sum())
        prof = prof.reshape(nsel, lines, -1)
        inside = inside.reshape(nsel, lines)
        samples_per_duty = speed[sel] / h  # blur in samples = duty cycle x this
        for i in range(nsel):
            ok = inside[i]
            if ok.sum() < max(2, lines // 2):
                continue
            p_hat = _periodogram(prof[i][ok]).mean(axis=0)
            nu = ok.sum() / 2.0
            lidx = np.abs(_L_GRID[None, :] - (cand * samples_per_duty[i])[:, None]).argmin(1)
            nll, dev = _window_curve(p_hat, tex[lidx], sigma_n**2 * nt, nu)
            curves.append(nll / max(1.0, dev[nll.argmin()] * 2 * nu))
    return np.array(curves, dtype=np.float64).reshape(-1, cand.size)


def duty_cycle_from_curves(curves, candidates=None, *, cap: float = CAP) -> DutyEstimate:
    """The candidate whose windows' curves, each capped at ``cap`` nats above its minimum
    (so that a window with a wrong flow cannot outvote the others), add up least.

    ``curves``: :func:`duty_cycle_curves`' rows, of one frame or of several (e.g. both views).
    NaN with no window.
    """
    cand = _candidates(candidates)
    c = np.asarray(curves, dtype=np.float64).reshape(-1, cand.size)
    if not len(c):
        return DutyEstimate(float("nan"), cand, np.full(cand.shape, np.nan), 0.0, 0)
    c = np.minimum(c - c.min(axis=1, keepdims=True), cap)
    total = c.sum(axis=0)
    best = int(total.argmin())
    return DutyEstimate(
        float(cand[best]), cand, total - total[best], _confidence(cand, c, best), len(c)
    )


def estimate_duty_cycle(blurred, flow, *, candidates=None, **options) -> DutyEstimate:
    """The duty cycle (exposure x frame rate) of ``blurred`` given its optical flow.

    Parameters as :func:`duty_cycle_curves` (``options`` passed on).

    Returns
    -------
    DutyEstimate
    """
    curves = duty_cycle_curves(blurred, flow, candidates=candidates, **options)
    return duty_cycle_from_curves(curves, candidates)


def _candidates(candidates) -> np.ndarray:
    if candidates is None:
        return DEFAULT_CANDIDATES
    cand = np.asarray(candidates, dtype=np.float64).ravel()
    if not cand.size or not np.all((cand >= 0) & (cand <= 1)):
        raise ValueError(f"candidate duty cycles must be in [0, 1], got {candidates!r}")
    return cand


def _window_curve(p_hat, shapes, noise_spec, nu, iterations: int = 6):
    """Whittle negative log-likelihood and deviance per candidate.

    ``shapes``: candidates x exponents x bins. The amplitude is fitted per candidate and
    exponent (fixed-point iterations), the exponent minimised over.
    """
    s = shapes
    a = np.maximum(np.mean(np.maximum(p_hat - noise_spec, 1e-3 * p_hat) / s, axis=-1), 1e-20)
    for _ in range(iterations):
        model = a[..., None] * s + noise_spec
        a = a * np.sum(p_hat * s / model**2, -1) / np.sum(s / model, -1)
        a = np.maximum(a, 1e-20)
    model = a[..., None] * s + noise_spec
    r = p_hat / model
    dev = np.mean(r - 1 - np.log(r), axis=-1)
    nll = nu * np.sum(np.log(model) + r, axis=-1)
    b = nll.argmin(axis=-1)
    rows = np.arange(nll.shape[0])
    return nll[rows, b], dev[rows, b]


def _confidence(cand, capped, best, draws: int = 200) -> float:
    """Share of bootstrap resamplings of the windows whose estimate is within 20 % of ``best``."""
    rng = np.random.default_rng(0)
    n = capped.shape[0]
    picks = rng.integers(0, n, size=(draws, n))
    counts = np.stack([np.bincount(p, minlength=n) for p in picks])
    est = cand[(counts @ capped).argmin(axis=1)]
    d = cand[best]
    if d == 0:
        return float(np.mean(est <= 0.05))
    return float(np.mean(np.abs(est - d) <= 0.2 * d))
