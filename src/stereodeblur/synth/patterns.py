"""Surface textures of the randomised scene family: procedural patterns and photographs.

A :class:`SurfaceTexture` describes a texture; :func:`make_texture` draws it as an
``(height, width, 3)`` float32 array of *linear* values in [0, 1] (texel ``(row, col)``
centred at texture coordinate ``(u, v) = (col, row)``, as in
:mod:`stereodeblur.synth.render`). The kinds (:data:`TEXTURE_KINDS`):

``stripes``
    A square wave of period ``period`` texels across the direction ``angle`` (radians
    from the texture's ``u`` axis), between ``level - contrast / 2`` and
    ``level + contrast / 2``.
``hatching``
    Two such square waves at ``angle`` and ``angle + pi / 2`` (the darker one wins).
``photo``
    The photograph ``photo`` of :data:`~stereodeblur.synth.textures.PHOTO_NAMES`, cropped
    to the aspect ratio and resized (area filter when shrinking), mirrored where the
    surface needs more texels than a ``repeat`` times enlarged copy has.
``flat``
    Nearly uniform: ``level`` plus a smooth variation of amplitude ``contrast`` (a few
    percent at most).
``edges``
    Random axis-aligned and rotated rectangles, each dark (``level - contrast / 2``) or
    bright (``level + contrast / 2``): high-contrast straight edges.
``bright``
    Nearly saturated: ``level`` (0.85 to 0.97) with a weak photograph texture of
    amplitude ``contrast`` on top.

Procedural patterns are box filtered over each texel (``SUPERSAMPLING`` squared point
samples), so a texel holds the mean of the pattern over its area. ``seed`` draws the
random details (rectangles, smooth variation) with ``np.random.default_rng(seed)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .textures import PHOTO_NAMES, load_texture

TEXTURE_KINDS = ("stripes", "hatching", "photo", "flat", "edges", "bright")
"""The kinds of :class:`SurfaceTexture`, in the order :func:`draw_texture` knows them."""

SUPERSAMPLING = 4
"""Point samples per texel side of the procedural patterns (box filter)."""

MIN_PERIOD, MAX_PERIOD = 2.0, 8.0
"""Range of stripe and hatching periods in texels (one texel is about one pixel)."""


@dataclass(frozen=True)
class SurfaceTexture:
    """What a surface of the family shows (see the module docstring for each kind).

    Attributes
    ----------
    kind : str
        One of :data:`TEXTURE_KINDS`.
    period : float
        Stripe period in texels (``stripes``, ``hatching``).
    angle : float
        Stripe direction in radians.
    photo : str
        Photograph name (``photo``, ``bright``).
    level, contrast : float
        Mean value and peak-to-peak amplitude (linear intensity).
    seed : int
        Seed of the random details.
    """

    kind: str
    period: float = 0.0
    angle: float = 0.0
    photo: str = ""
    level: float = 0.5
    contrast: float = 1.0
    seed: int = 0

    def __post_init__(self):
        if self.kind not in TEXTURE_KINDS:
            raise InputError(
                f"texture kind must be one of {', '.join(TEXTURE_KINDS)}, got {self.kind!r}"
            )
        if self.kind in ("stripes", "hatching") and not self.period >= 1.0:
            raise InputError(f"stripe period must be at least 1 texel, got {self.period!r}")
        if self.kind in ("photo", "bright") and self.photo not in PHOTO_NAMES:
            raise InputError(f"unknown photograph {self.photo!r} for a {self.kind} texture")
        low, high = self.level - self.contrast / 2, self.level + self.contrast / 2
        if not (0.0 <= low <= high <= 1.0):
            raise InputError(
                f"level {self.level} and contrast {self.contrast} leave [0, 1] "
                f"for a {self.kind} texture"
            )

    def label(self) -> str:
        """A short description, e.g. ``'stripes 3.2px 45deg'``."""
        if self.kind in ("stripes", "hatching"):
            return f"{self.kind} {self.period:.1f}px {np.degrees(self.angle):.0f}deg"
        if self.kind in ("photo", "bright"):
            return f"{self.kind} {self.photo}"
        return self.kind


def draw_texture(rng: np.random.Generator, kind: str | None = None) -> SurfaceTexture:
    """A random :class:`SurfaceTexture` of ``kind`` (a random kind if None)."""
    if kind is None:
        kind = TEXTURE_KINDS[int(rng.integers(len(TEXTURE_KINDS)))]
    seed = int(rng.integers(2**31))
    photo = PHOTO_NAMES[int(rng.integers(len(PHOTO_NAMES)))]
    if kind in ("stripes", "hatching"):
        period = float(np.exp(rng.uniform(np.log(MIN_PERIOD), np.log(MAX_PERIOD))))
        angle = float(rng.uniform(0.0, np.pi))
        contrast = float(rng.uniform(0.4, 0.9))
        level = float(rng.uniform(contrast / 2 + 0.03, 1.0 - contrast / 2 - 0.03))
        return SurfaceTexture(kind, period, angle, level=level, contrast=contrast, seed=seed)
    if kind == "photo":
        return SurfaceTexture(kind, photo=photo, seed=seed)
    if kind == "flat":
        level = float(rng.uniform(0.1, 0.8))
        return SurfaceTexture(kind, level=level, contrast=float(rng.uniform(0.0, 0.03)), seed=seed)
    if kind == "edges":
        contrast = float(rng.uniform(0.7, 0.94))
        return SurfaceTexture(kind, level=0.5, contrast=contrast, seed=seed)
    level = float(rng.uniform(0.85, 0.95))
    contrast = float(rng.uniform(0.02, 2 * min(level, 1.0 - level) - 0.02))
    return SurfaceTexture("bright", photo=photo, level=level, contrast=contrast, seed=seed)


def _supersampled(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Point-sample coordinates ``(u, v)`` of shape (height, width, S*S) inside each texel."""
    offsets = (np.arange(SUPERSAMPLING) + 0.5) / SUPERSAMPLING - 0.5
    du, dv = (a.ravel() for a in np.meshgrid(offsets, offsets))
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    return u[..., None] + du, v[..., None] + dv


def _square_wave(u, v, period: float, angle: float) -> np.ndarray:
    """1 on the first half of each period across direction ``angle``, else 0."""
    across = u * np.cos(angle) + v * np.sin(angle)
    return (np.mod(across / period, 1.0) < 0.5).astype(np.float32)


def _rectangles(width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """Mean over each texel of a {0, 1} picture: a background and rectangles painted on it."""
    import cv2

    s = SUPERSAMPLING
    canvas = np.full((height * s, width * s), float(rng.integers(2)), dtype=np.float32)
    count = min(80, max(6, int(width * height / 1500)))
    for _ in range(count):
        cu, cv_ = rng.uniform(0, width), rng.uniform(0, height)
        half_u, half_v = rng.uniform(3, 0.25 * width + 4), rng.uniform(3, 0.25 * height + 4)
        turn = rng.uniform(0, np.pi) if rng.random() < 0.5 else 0.0
        value = float(rng.integers(2))
        c, n = np.cos(turn), np.sin(turn)
        corners = np.array(
            [[-half_u, -half_v], [half_u, -half_v], [half_u, half_v], [-half_u, half_v]]
        )
        points = corners @ np.array([[c, n], [-n, c]]) + [cu + 0.5, cv_ + 0.5]
        cv2.fillPoly(canvas, [np.round(points * s).astype(np.int32)], value)
    return canvas.reshape(height, s, width, s).mean(axis=(1, 3))


def _smooth_noise(width: int, height: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth random variation in [-0.5, 0.5], shape (height, width)."""
    from scipy import ndimage

    field = ndimage.gaussian_filter(rng.standard_normal((height, width)), sigma=12.0)
    span = float(np.ptp(field))
    return (field - field.mean()) / span if span > 0 else field * 0.0


def photo_patch(name: str, width: int, height: int, *, repeat: float = 1.0) -> np.ndarray:
    """Photograph ``name`` cropped to ``width : height`` and resized to that many texels.

    The photograph is first cropped to the aspect ratio; with ``repeat > 1`` a crop of
    ``1 / repeat`` of its size is mirrored (reflected) to cover the patch instead, so
    that large surfaces keep a detailed texture.
    """
    import cv2

    texture = load_texture(name)
    h, w = texture.shape[:2]
    width, height = max(2, int(round(width))), max(2, int(round(height)))
    tile_w = max(2, int(round(width / max(repeat, 1.0))))
    tile_h = max(2, int(round(height / max(repeat, 1.0))))
    scale = min(w / tile_w, h / tile_h)
    crop_w, crop_h = max(2, int(tile_w * scale)), max(2, int(tile_h * scale))
    top, left = (h - crop_h) // 2, (w - crop_w) // 2
    texture = texture[top : top + crop_h, left : left + crop_w]
    shrink = tile_w <= crop_w
    mode = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
    tile = cv2.resize(texture, (tile_w, tile_h), interpolation=mode)
    if (tile_w, tile_h) != (width, height):
        tile = np.pad(tile, ((0, height - tile_h), (0, width - tile_w), (0, 0)), mode="symmetric")
    return np.ascontiguousarray(tile[:height, :width], dtype=np.float32)


def make_texture(texture: SurfaceTexture, width: int, height: int) -> np.ndarray:
    """Draw ``texture`` as an ``(height, width, 3)`` float32 array in [0, 1]."""
    width, height = max(2, int(round(width))), max(2, int(round(height)))
    rng = np.random.default_rng(texture.seed)
    kind = texture.kind
    if kind == "photo":
        return photo_patch(texture.photo, width, height, repeat=max(1.0, width / 600))
    if kind == "bright":
        photo = photo_patch(texture.photo, width, height, repeat=max(1.0, width / 600))
        grey = photo.mean(axis=2, keepdims=True)
        span = max(float(np.ptp(grey)), 1e-6)
        values = texture.level + texture.contrast * ((grey - grey.mean()) / span)
        values = values + 0.02 * (photo - grey)  # a trace of colour
        return np.clip(values, 0.0, 1.0).astype(np.float32).repeat(3, axis=2)[..., :3]
    if kind == "flat":
        values = texture.level + texture.contrast * _smooth_noise(width, height, rng)
        return np.repeat(values[..., None], 3, axis=2).astype(np.float32)
    if kind == "edges":
        covered = _rectangles(width, height, rng)
    else:
        u, v = _supersampled(width, height)
        binary = _square_wave(u, v, texture.period, texture.angle)
        if kind == "hatching":
            binary *= _square_wave(u, v, texture.period, texture.angle + np.pi / 2)
        covered = binary.mean(axis=-1)
    low = texture.level - texture.contrast / 2
    values = low + texture.contrast * covered
    tint = 1.0 + 0.05 * rng.uniform(-1, 1, 3)  # a slight colour, still in range
    return np.clip(values[..., None] * tint, 0.0, 1.0).astype(np.float32)
