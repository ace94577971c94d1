"""Pictures of flows, disparities, segments and masks, as uint8 RGB arrays.

Every function is pure: it takes arrays and returns an ``(H, W, 3)`` uint8 image.

* Flow uses the Middlebury colour wheel (Baker et al., IJCV 2011) as in the
  Middlebury ``flowToColor`` code (angle ``atan2(-v, -u)``): the hue gives the
  direction, the saturation the magnitude relative to ``max_flow``; flow to the
  right ``(1, 0)`` is red, down ``(0, 1)`` yellow, left cyan-blue, up blue-violet;
  zero flow is white, beyond ``max_flow`` the colour is darkened, non-finite flow
  is black.
* Disparity uses the "turbo" colour map (Mikhailov 2019, polynomial fit): near
  (large disparity) is red, far is blue; holes (non-finite or <= 0) are black.
* :func:`with_caption` puts a picture under a strip of text (OpenCV's Hershey font) saying
  what it shows, with a colour key: :func:`disparity_key` (a bar with its two end values)
  or :func:`flow_key` (the colour wheel with the length at full colour).
"""

from __future__ import annotations

import numpy as np

# Middlebury colour wheel: segment lengths red-yellow, yellow-green, ...
_WHEEL_SEGMENTS = (("RY", 15), ("YG", 6), ("GC", 4), ("CB", 11), ("BM", 13), ("MR", 6))


def color_wheel() -> np.ndarray:
    """The Middlebury colour wheel, shape (55, 3), float in [0, 255]."""
    ry, yg, gc, cb, bm, mr = (n for _, n in _WHEEL_SEGMENTS)
    wheel = np.zeros((ry + yg + gc + cb + bm + mr, 3))
    col = 0
    wheel[col : col + ry, 0] = 255
    wheel[col : col + ry, 1] = np.floor(255 * np.arange(ry) / ry)
    col += ry
    wheel[col : col + yg, 0] = 255 - np.floor(255 * np.arange(yg) / yg)
    wheel[col : col + yg, 1] = 255
    col += yg
    wheel[col : col + gc, 1] = 255
    wheel[col : col + gc, 2] = np.floor(255 * np.arange(gc) / gc)
    col += gc
    wheel[col : col + cb, 1] = 255 - np.floor(255 * np.arange(cb) / cb)
    wheel[col : col + cb, 2] = 255
    col += cb
    wheel[col : col + bm, 2] = 255
    wheel[col : col + bm, 0] = np.floor(255 * np.arange(bm) / bm)
    col += bm
    wheel[col : col + mr, 2] = 255 - np.floor(255 * np.arange(mr) / mr)
    wheel[col : col + mr, 0] = 255
    return wheel


def flow_to_color(flow: np.ndarray, *, max_flow: float | None = None) -> np.ndarray:
    """Middlebury colour coding of a flow field.

    Parameters
    ----------
    flow : ndarray, shape (H, W, 2)
        ``(u, v)`` in pixels.
    max_flow : float, optional
        Magnitude shown at full saturation; default the largest finite magnitude.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    flow = np.asarray(flow, dtype=np.float64)
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise ValueError(f"flow must have shape (H, W, 2), got {flow.shape}")
    known = np.all(np.isfinite(flow), axis=-1)
    u = np.where(known, flow[..., 0], 0.0)
    v = np.where(known, flow[..., 1], 0.0)
    radius = np.hypot(u, v)
    if max_flow is None:
        max_flow = float(radius.max()) if radius.size else 0.0
    if not max_flow > 0:
        max_flow = 1.0
    u, v, radius = u / max_flow, v / max_flow, radius / max_flow
    wheel = color_wheel()
    ncols = len(wheel)
    angle = np.arctan2(-v, -u) / np.pi  # in [-1, 1]
    fk = (angle + 1) / 2 * (ncols - 1)
    k0 = np.floor(fk).astype(np.int64)
    k1 = (k0 + 1) % ncols
    f = (fk - k0)[..., None]
    col = ((1 - f) * wheel[k0] + f * wheel[k1]) / 255.0
    r = radius[..., None]
    inside = r <= 1
    col = np.where(inside, 1 - r * (1 - col), col * 0.75)
    out = np.floor(255 * col)
    out[~known] = 0
    return np.clip(out, 0, 255).astype(np.uint8)


# Turbo colour map: polynomial approximation (Mikhailov, Google AI blog 2019).
_TURBO_R = (0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943)
_TURBO_G = (0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604)
_TURBO_B = (0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973)


def _turbo(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    powers = np.stack([t**k for k in range(6)], axis=-1)
    rgb = np.stack([powers @ np.array(c) for c in (_TURBO_R, _TURBO_G, _TURBO_B)], axis=-1)
    return np.clip(rgb, 0.0, 1.0)


def disparity_to_color(
    disparity: np.ndarray, *, max_disparity: float | None = None, min_disparity: float = 0.0
) -> np.ndarray:
    """Turbo colour map of a disparity map (red near, blue far, black holes).

    Parameters
    ----------
    disparity : ndarray, shape (H, W)
        Pixels; non-finite or <= 0 are holes.
    max_disparity, min_disparity : float
        Range mapped onto the colour map; default maximum: the largest known value.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    d = np.asarray(disparity, dtype=np.float64)
    if d.ndim != 2:
        raise ValueError(f"disparity must have shape (H, W), got {d.shape}")
    known = np.isfinite(d) & (d > 0)
    if max_disparity is None:
        max_disparity = float(d[known].max()) if known.any() else 1.0
    span = max(float(max_disparity) - float(min_disparity), 1e-12)
    t = (np.where(known, d, min_disparity) - min_disparity) / span
    rgb = np.rint(_turbo(t) * 255)
    rgb[~known] = 0
    return rgb.astype(np.uint8)


def _to_rgb_u8(image: np.ndarray) -> np.ndarray:
    a = np.asarray(image)
    if a.dtype != np.uint8:
        a = np.rint(np.clip(np.nan_to_num(a.astype(np.float64)), 0.0, 1.0) * 255).astype(np.uint8)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"image must have shape (H, W) or (H, W, 3), got {np.shape(image)}")
    return a


def segment_overlay(
    image: np.ndarray, labels: np.ndarray, *, color: tuple[int, int, int] = (255, 255, 0)
) -> np.ndarray:
    """``image`` (float in [0, 1] or uint8, grey or RGB) with segment boundaries drawn in ``color``.

    A pixel is drawn when its right or lower neighbour belongs to another segment
    (one-pixel lines).
    """
    rgb = _to_rgb_u8(image).copy()
    labels = np.asarray(labels)
    if labels.shape != rgb.shape[:2]:
        raise ValueError(f"labels have shape {labels.shape}, image {rgb.shape[:2]}")
    edge = np.zeros(labels.shape, dtype=bool)
    edge[:, :-1] |= labels[:, :-1] != labels[:, 1:]
    edge[:-1, :] |= labels[:-1, :] != labels[1:, :]
    rgb[edge] = color
    return rgb


def mask_to_image(
    mask: np.ndarray,
    image: np.ndarray | None = None,
    *,
    color: tuple[int, int, int] = (255, 0, 0),
    opacity: float = 0.6,
) -> np.ndarray:
    """A boolean mask as a picture: white on black, or tinted over ``image`` if given."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2:
        raise ValueError(f"mask must have shape (H, W), got {mask.shape}")
    if image is None:
        return np.repeat(np.where(mask, 255, 0).astype(np.uint8)[..., None], 3, axis=2)
    rgb = _to_rgb_u8(image).astype(np.float64)
    if rgb.shape[:2] != mask.shape:
        raise ValueError(f"mask has shape {mask.shape}, image {rgb.shape[:2]}")
    tint = (1 - opacity) * rgb + opacity * np.array(color, dtype=np.float64)
    rgb[mask] = tint[mask]
    return np.rint(rgb).astype(np.uint8)


# --------------------------------------------------------------------------- captions

# OpenCV's Hershey simplex font at this scale: capitals about 9 px high, about 6 px per letter.
CAPTION_SCALE = 0.4
CAPTION_MARGIN = 4
_CAPTION_BACKGROUND = (40, 40, 40)
_CAPTION_TEXT = (255, 255, 255)


def _text_size(text: str) -> tuple[int, int, int]:
    """``(width, height, baseline)`` of ``text`` in the caption font."""
    import cv2

    (width, height), baseline = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, CAPTION_SCALE, 1)
    return width, height, baseline


def _wrap(text: str, width: int) -> list[str]:
    """``text`` broken into lines of at most ``width`` pixels (a longer word keeps its line)."""
    lines: list[str] = []
    for word in text.split():
        if lines and _text_size(f"{lines[-1]} {word}")[0] <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines


def _put_text(rgb: np.ndarray, text: str, x: int, top: int) -> None:
    """Draw ``text`` into ``rgb`` (in place) with its top-left corner at ``(x, top)``."""
    import cv2

    _, height, _ = _text_size("Hg")
    cv2.putText(
        rgb,
        text,
        (x, top + height),
        cv2.FONT_HERSHEY_SIMPLEX,
        CAPTION_SCALE,
        _CAPTION_TEXT,
        1,
        cv2.LINE_AA,
    )


def caption_strip(lines, width: int, *, key: np.ndarray | None = None) -> np.ndarray:
    """A dark strip ``width`` pixels wide holding ``lines`` of white text and, below them, a
    ``key`` picture (a colour scale), as an ``(h, width, 3)`` uint8 image.

    Each line is wrapped to the width; a key wider than the strip is cut at its right edge.
    """
    width = int(width)
    _, height, baseline = _text_size("Hg")
    step = height + baseline + 3
    wrapped = [part for line in lines for part in _wrap(line, width - 2 * CAPTION_MARGIN)]
    key_height = 0 if key is None else key.shape[0] + CAPTION_MARGIN
    strip = np.empty((2 * CAPTION_MARGIN + step * len(wrapped) + key_height, width, 3), np.uint8)
    strip[...] = _CAPTION_BACKGROUND
    for k, line in enumerate(wrapped):
        _put_text(strip, line, CAPTION_MARGIN, CAPTION_MARGIN + k * step)
    if key is not None:
        top = CAPTION_MARGIN + step * len(wrapped)
        shown = _to_rgb_u8(key)[:, : max(width - 2 * CAPTION_MARGIN, 0)]
        strip[top : top + shown.shape[0], CAPTION_MARGIN : CAPTION_MARGIN + shown.shape[1]] = shown
    return strip


def with_caption(picture: np.ndarray, lines, *, key: np.ndarray | None = None) -> np.ndarray:
    """``picture`` (grey or RGB) below a :func:`caption_strip` of its width: the picture's
    pixels unchanged, ``(strip height + H, W, 3)`` uint8."""
    rgb = _to_rgb_u8(picture)
    return np.concatenate([caption_strip(lines, rgb.shape[1], key=key), rgb], axis=0)


def disparity_key(max_disparity: float, width: int, *, min_disparity: float = 0.0) -> np.ndarray:
    """The colour scale of :func:`disparity_to_color`: a bar from ``min_disparity`` (left) to
    ``max_disparity`` (right), at most ``width`` (and 256) pixels long, with the two values in
    pixels written under its ends."""
    length = int(max(min(width, 256), 2))
    values = np.linspace(min_disparity, max_disparity, length)
    # Zero and below is a hole for disparity_to_color: start the bar just above it.
    values[0] = max(values[0], 1e-9 * max(abs(max_disparity), 1.0))
    bar = disparity_to_color(
        np.repeat(values[None], 10, axis=0),
        max_disparity=max_disparity,
        min_disparity=min_disparity,
    )
    low, high = f"{min_disparity:.3g} px (far)", f"{max_disparity:.3g} px (near)"
    _, height, baseline = _text_size("Hg")
    low_width, high_width = _text_size(low)[0], _text_size(high)[0]
    key_width = max(length, low_width + 6 + high_width)
    key = np.empty((bar.shape[0] + 2 + height + baseline, key_width, 3), np.uint8)
    key[...] = _CAPTION_BACKGROUND
    key[: bar.shape[0], :length] = bar
    _put_text(key, low, 0, bar.shape[0] + 2)
    _put_text(key, high, max(length, key_width) - high_width, bar.shape[0] + 2)
    return key


def flow_key(max_flow: float, *, size: int = 41) -> np.ndarray:
    """The colour wheel of :func:`flow_to_color` at ``max_flow``: each pixel of a ``size`` x
    ``size`` square shows the flow from the square's centre to it, scaled so that the grey
    circle is ``max_flow`` long (white at the centre, full colour on the circle, darker
    beyond), with the length of the circle written beside it."""
    half = (size - 1) / 2
    reach = 1.25  # the square's half side, in units of max_flow
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)
    flow = np.stack([x - half, y - half], axis=-1) / half * reach * max_flow
    wheel = flow_to_color(flow, max_flow=max_flow)
    radius = np.hypot(x - half, y - half) / half * reach
    wheel[np.abs(radius - 1.0) < 0.5 * reach / half] = 128
    label = f"circle: {max_flow:.3g} px"
    _, height, _ = _text_size(label)
    key = np.empty((size, size + 6 + _text_size(label)[0], 3), np.uint8)
    key[...] = _CAPTION_BACKGROUND
    key[:, :size] = wheel
    _put_text(key, label, size + 6, (size - height) // 2)
    return key
