"""Ternary census transform and its Hamming matching cost (the data term of PRSF).

The census descriptor of a pixel compares its grey value with ``NUM_OFFSETS`` = 24
neighbours on a checkerboard pattern of a 7x7 window (offsets ``(dx, dy)`` with
``|dx|, |dy| <= 3`` and ``dx + dy`` odd). Each comparison is ternary: brighter
than the centre by more than ``threshold``, darker by more than ``threshold``, or
similar (the threshold may differ per centre pixel, see :func:`census_thresholds`);
two bits per neighbour are packed into one ``uint64``. The cost of
matching two descriptors is the fraction of neighbours whose comparison differs,
in [0, 1]. It depends only on the order of grey values, so it tolerates gain,
bias and the mild contrast loss of motion blur. Pixels outside the image are
replicated from the border.

Costs at non-integer positions interpolate the costs of the four surrounding
integer pixels bilinearly, so that sub-pixel displacements change the cost
smoothly.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

RADIUS = 3
OFFSETS = np.array(
    [
        (dx, dy)
        for dy in range(-RADIUS, RADIUS + 1)
        for dx in range(-RADIUS, RADIUS + 1)
        if (dx + dy) % 2 == 1
    ],
    dtype=np.int64,
)
NUM_OFFSETS = len(OFFSETS)
# Mask of the low bit of every 2-bit field.
_LOW_BITS = np.uint64(sum(1 << (2 * k) for k in range(NUM_OFFSETS)))
# Shot-noise test (:func:`shot_noise_flattens_the_dark`): the darkest share of the image and
# how far below the image's noise level its own must be.
DARK_SHARE = 0.1
DARK_NOISE_RATIO = 3.0


def _blocks(image: np.ndarray, name: str) -> tuple[np.ndarray, ...]:
    """The four pixels ``a, b, c, d`` (top left, top right, bottom left, bottom right) of the
    image's whole 2x2 blocks, float64."""
    g = np.asarray(image, dtype=np.float64)
    if g.ndim != 2:
        raise ValueError(f"{name} needs a grey (H, W) image, got shape {g.shape}")
    g = g[: (g.shape[0] // 2) * 2, : (g.shape[1] // 2) * 2]
    return g[0::2, 0::2], g[0::2, 1::2], g[1::2, 0::2], g[1::2, 1::2]


def _level(detail: np.ndarray) -> float:
    """Noise deviation from the absolute diagonal Haar details of its blocks (lower quartile
    over that of ``|N(0, 1)|``); 0 without blocks."""
    return float(np.quantile(detail, 0.25) / 0.3186) if detail.size else 0.0


def noise_level(image: np.ndarray) -> float:
    """Standard deviation of white noise in a grey image, robustly estimated.

    The lower quartile of the absolute finest diagonal Haar detail
    ``(a - b - c + d) / 2`` of 2x2 blocks, divided by 0.3186 (the lower quartile
    of ``|N(0, 1)|``; as Donoho & Johnstone's 1994 median estimator, but less
    sensitive to texture): the detail of white noise has the noise's standard
    deviation, that of smooth (and motion-blurred) image content is small, so
    the quartile sees the noise. Sharp fine texture gives an overestimate.
    """
    a, b, c, d = _blocks(image, "noise_level")
    return _level(np.abs(a - b - c + d) / 2.0)


def dark_noise_level(image: np.ndarray, share: float = DARK_SHARE) -> float:
    """Noise level (as :func:`noise_level`) of the darkest ``share`` of the 2x2 blocks that
    have no pixel at or below 0 (noise clipped at black reads weaker than it is)."""
    a, b, c, d = _blocks(image, "dark_noise_level")
    lit = np.minimum(np.minimum(a, b), np.minimum(c, d)) > 0
    detail, mean = np.abs(a - b - c + d)[lit] / 2.0, (a + b + c + d)[lit] / 4.0
    if not mean.size:
        return 0.0
    count = max(1, int(share * mean.size))
    return _level(detail[np.argpartition(mean, count - 1)[:count]])


def shot_noise_flattens_the_dark(
    image: np.ndarray, *, threshold: float = 0.008, noise_factor: float = 1.0
) -> bool:
    """Whether the image's one noise level would flatten the texture of its darkest parts.

    True when the noise of the darkest tenth of the image (:func:`dark_noise_level`) is below
    ``1 / DARK_NOISE_RATIO`` of the image's (:func:`noise_level`) and that level, not the
    relative band, sets the census band of those dark pixels (:func:`census_thresholds`).
    Shot noise does this: it grows with the brightness, so the bright parts set the level.
    Additive noise does not; where the image is smooth in the dark and finely textured in the
    light, the texture alone may pass the test, which then changes little (without noise
    both encodings compare the same differences).
    """
    level = noise_level(image)
    if level <= 0.0:
        return False
    dark = np.array([np.quantile(image, DARK_SHARE / 2.0)])  # ~ the darkest tenth's median
    relative = census_thresholds(dark, threshold=threshold)
    band = census_thresholds(dark, threshold=threshold, noise=level, noise_factor=noise_factor)
    if band[0] <= relative[0]:
        return False
    return dark_noise_level(image) * DARK_NOISE_RATIO < level


def census_thresholds(
    image: np.ndarray,
    *,
    threshold: float = 0.008,
    noise: float = 0.0,
    noise_factor: float = 1.0,
    relative: bool = True,
) -> np.ndarray:
    """Per-pixel census thresholds: relative to the brightness and above the noise.

    ``max(threshold * sqrt(I / 0.25), noise_factor * sqrt(2) * noise)`` for the
    pixel's grey value ``I``. The first term is ``threshold`` at a quarter
    of full scale and shrinks in dark regions like the contrast of linear
    intensities does (as a fixed threshold on ``sqrt(I)`` would), so that dark
    texture still counts; the second keeps comparisons from flipping with
    sensor noise (``noise``, its standard deviation, e.g. from
    :func:`noise_level`; ``sqrt(2) noise`` is that of a difference of two pixels).
    ``relative=False``: ``threshold`` at every brightness (for an image that is already
    the square root of linear light, where that is the same band).
    """
    image = np.asarray(image, dtype=np.float64)
    scale = np.sqrt(np.clip(image, 0.0, None) / 0.25) if relative else np.ones_like(image)
    return np.maximum(threshold * scale, noise_factor * np.sqrt(2.0) * float(noise)).astype(
        np.float32
    )


def census_transform(image: np.ndarray, *, threshold: float | np.ndarray = 0.008) -> np.ndarray:
    """Ternary census descriptors of a grey image, shape (H, W), dtype uint64.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey values, float in [0, 1].
    threshold : float or ndarray, shape (H, W)
        Differences within ``threshold`` count as "similar" (default about 2 grey
        levels of 255); an array gives each centre pixel its own threshold (see
        :func:`census_thresholds`).
    """
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 2:
        raise ValueError(f"census_transform needs a grey (H, W) image, got shape {image.shape}")
    limit = np.broadcast_to(np.asarray(threshold, dtype=np.float32), image.shape)
    padded = np.pad(image, RADIUS, mode="edge")
    return _census(padded, image.shape[0], image.shape[1], np.ascontiguousarray(limit))


def census_descriptors(
    gray: np.ndarray,
    *,
    threshold: float = 0.008,
    noise_factor: float = 1.0,
    denoise: float = 1.5,
    relative: bool = True,
) -> np.ndarray:
    """Census descriptors of a grey image with thresholds from its own noise level.

    ``relative``: the band scales with the brightness (:func:`census_thresholds`); False
    for the square root of linear light (``SceneFlowSettings.census_gamma = 0.5``), where
    one band is the linear rule's at every brightness and shot noise is equally strong
    everywhere, so that the bright parts' noise does not flatten a dark region's texture.

    Where the noise of a pixel difference (``sqrt(2)`` times :func:`noise_level`, times
    ``noise_factor``) exceeds ``threshold``, the image is first smoothed by a Gaussian of
    ``denoise`` px (white noise drops to ``1 / (2 sqrt(pi) denoise)`` of its level, and a
    motion-blurred frame loses little): texture is then matched with fewer flipped
    comparisons, and a flat noisy region (a dark coat, the rim of a dark sphere) reads as
    flat, where every candidate match is cheap and the smoothness of the fusion decides,
    instead of as random texture, where every candidate costs about 0.5 give or take
    chance differences that pick a wrong motion. Thresholds: :func:`census_thresholds`.
    On the benchmark's noisy object scenes (sigma = 0.01) this lowered the scene flow's
    mean AEP from 1.09 to 0.64 px (``stereodeblur bench sceneflow``).
    """
    gray = np.asarray(gray, dtype=np.float32)
    noise = noise_level(gray)
    if denoise > 0 and noise_factor * np.sqrt(2.0) * noise > threshold:
        gray = ndimage.gaussian_filter(gray, denoise, mode="nearest")
        noise = noise / (2.0 * np.sqrt(np.pi) * denoise)
    limits = census_thresholds(
        gray, threshold=threshold, noise=noise, noise_factor=noise_factor, relative=relative
    )
    return census_transform(gray, threshold=limits)


@numba.njit(cache=True, nogil=True)
def _census(padded, height, width, thresholds):
    out = np.zeros((height, width), dtype=np.uint64)
    for y in range(height):
        for x in range(width):
            centre = padded[y + RADIUS, x + RADIUS]
            threshold = thresholds[y, x]
            code = np.uint64(0)
            bit = 0
            for dy in range(-RADIUS, RADIUS + 1):
                for dx in range(-RADIUS, RADIUS + 1):
                    if (dx + dy) % 2 != 1:
                        continue
                    diff = padded[y + RADIUS + dy, x + RADIUS + dx] - centre
                    if diff > threshold:
                        code |= np.uint64(1) << np.uint64(bit)
                    elif diff < -threshold:
                        code |= np.uint64(2) << np.uint64(bit)
                    bit += 2
            out[y, x] = code
    return out


@numba.njit(inline="always")
def _popcount(v):
    v = v - ((v >> np.uint64(1)) & np.uint64(0x5555555555555555))
    v = (v & np.uint64(0x3333333333333333)) + ((v >> np.uint64(2)) & np.uint64(0x3333333333333333))
    v = (v + (v >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (v * np.uint64(0x0101010101010101)) >> np.uint64(56)


@numba.njit(inline="always")
def hamming(a, b):
    """Number of census neighbours whose ternary comparison differs."""
    d = a ^ b
    return _popcount((d | (d >> np.uint64(1))) & _LOW_BITS)


@numba.njit(inline="always")
def texture_fraction(code):
    """Fraction of census neighbours that differ from the centre (0 in flat regions)."""
    return _popcount((code | (code >> np.uint64(1))) & _LOW_BITS) / NUM_OFFSETS


@numba.njit(inline="always")
def census_cost_at(reference_code, target, x, y):
    """Bilinearly interpolated cost of ``reference_code`` against ``target`` at ``(x, y)``.

    Returns -1.0 when ``(x, y)`` lies outside the target image.
    """
    height, width = target.shape
    if not (x >= 0.0 and y >= 0.0 and x <= width - 1 and y <= height - 1):
        return -1.0
    x0 = min(int(x), width - 2) if width > 1 else 0
    y0 = min(int(y), height - 2) if height > 1 else 0
    fx = x - x0
    fy = y - y0
    x1 = min(x0 + 1, width - 1)
    y1 = min(y0 + 1, height - 1)
    c00 = hamming(reference_code, target[y0, x0])
    c01 = hamming(reference_code, target[y0, x1])
    c10 = hamming(reference_code, target[y1, x0])
    c11 = hamming(reference_code, target[y1, x1])
    value = (1 - fy) * ((1 - fx) * c00 + fx * c01) + fy * ((1 - fx) * c10 + fx * c11)
    return value / NUM_OFFSETS


@numba.njit(cache=True, nogil=True, inline="always")
def leave_cost(target, x, y, leave, near, reach):
    """Cost of a match at ``(x, y)`` outside ``target``: ``near`` if it lies at most ``reach``
    px outside, else ``leave``."""
    height, width = target.shape
    beyond = max(-x, x - (width - 1), -y, y - (height - 1))
    return near if beyond <= reach else leave


def wrong_match_cost(codes: np.ndarray, *, distance: int = 4) -> np.ndarray:
    """What a wrong match costs at every pixel, shape (H, W), float64 in [0, 1].

    The mean census cost of each pixel's descriptor against those of the pixels
    ``distance`` pixels left, right, above and below it (clamped at the border):
    about 0.5 or more in texture and in noise, near 0 in clean flat regions.
    """
    codes = np.ascontiguousarray(codes, dtype=np.uint64)
    if codes.ndim != 2:
        raise ValueError(f"wrong_match_cost needs (H, W) descriptors, got shape {codes.shape}")
    return _wrong_match_cost(codes, int(distance))


@numba.njit(cache=True, nogil=True)
def _wrong_match_cost(codes, distance):
    height, width = codes.shape
    out = np.empty((height, width))
    for y in range(height):
        for x in range(width):
            c = codes[y, x]
            total = hamming(c, codes[y, max(x - distance, 0)])
            total += hamming(c, codes[y, min(x + distance, width - 1)])
            total += hamming(c, codes[max(y - distance, 0), x])
            total += hamming(c, codes[min(y + distance, height - 1), x])
            out[y, x] = total / (4.0 * NUM_OFFSETS)
    return out


def leave_costs_near(lt, lt1, x, y, x1, y1, window: float) -> np.ndarray:
    """What leaving the view costs a dominant motion at every pixel, shape (H, W): the mean of
    the census costs at t + 1 of the initial matches ``(x, y) -> (x1, y1)`` (left t codes
    ``lt``, left t + 1 codes ``lt1``; NaN positions skipped) in a Gaussian window of ``window``
    px, never above :func:`wrong_match_cost` (a correct match's cost there, so that
    leaving the view is neither favoured nor penalised against one)."""
    from scipy.ndimage import gaussian_filter

    leave = wrong_match_cost(lt)
    known = np.isfinite(x1) & np.isfinite(y1)
    cost = census_cost(lt, lt1, x[known], y[known], x1[known], y1[known])
    inside = np.isfinite(cost)
    sums, counts = np.zeros(leave.shape), np.zeros(leave.shape)
    rows, cols = y[known][inside].astype(np.int64), x[known][inside].astype(np.int64)
    np.add.at(sums, (rows, cols), cost[inside])
    np.add.at(counts, (rows, cols), 1.0)
    sums, counts = gaussian_filter(sums, window), gaussian_filter(counts, window)
    mean = np.divide(sums, counts, out=leave.copy(), where=counts > 1e-6 * counts.max())
    return np.minimum(leave, mean)


def census_cost(
    reference: np.ndarray,
    target: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    xt: np.ndarray,
    yt: np.ndarray,
) -> np.ndarray:
    """Census cost in [0, 1] of reference pixels ``(x, y)`` matched at target ``(xt, yt)``.

    Parameters
    ----------
    reference, target : ndarray of uint64, shape (H, W)
        Descriptors from :func:`census_transform`.
    x, y : ndarray of int
        Reference pixels.
    xt, yt : ndarray of float
        Matching positions in the target image.

    Returns
    -------
    ndarray of float64
        The cost, NaN where the target position lies outside the image.
    """
    x, y = np.asarray(x, dtype=np.int64).ravel(), np.asarray(y, dtype=np.int64).ravel()
    xt, yt = np.asarray(xt, dtype=np.float64).ravel(), np.asarray(yt, dtype=np.float64).ravel()
    out = _census_cost_many(reference, target, x, y, xt, yt)
    return np.where(out < 0, np.nan, out)


@numba.njit(cache=True, nogil=True)
def _census_cost_many(reference, target, x, y, xt, yt):
    out = np.empty(x.size)
    for i in range(x.size):
        out[i] = census_cost_at(reference[y[i], x[i]], target, xt[i], yt[i])
    return out
