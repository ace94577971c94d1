"""Textures for synthetic scenes, from the images bundled with scikit-image.

Only images that ship inside the scikit-image wheel are used (no downloads). A
texture is an ``(h, w, 3)`` float32 array in [0, 1] of *linear* values: the 8-bit
images are sRGB encoded, so they are decoded with the sRGB curve; grey images
are repeated into three channels. Texel ``(row, col)`` has its centre at the
texture coordinate ``(u, v) = (col, row)``, as for image pixels.
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import InputError
from ..io.formats import srgb_to_linear

# Name -> skimage.data loader. All of these are files inside the scikit-image wheel
# and at least 500 x 400 texels, so that they cover a 640 x 480 view at a modest
# magnification.
_LOADERS = {
    "astronaut": "astronaut",
    "coffee": "coffee",
    "rocket": "rocket",
    "camera": "camera",
    "brick": "brick",
    "grass": "grass",
    "gravel": "gravel",
    "immunohistochemistry": "immunohistochemistry",
    "motorcycle": "stereo_motorcycle",
}

TEXTURE_NAMES: tuple[str, ...] = tuple(_LOADERS)
"""Large textures, in the order the planar set cycles through."""

# Further photographs shipped with the wheel (some smaller than 500 x 400), for the
# randomised scene family (:mod:`stereodeblur.synth.family`).
_LOADERS.update(
    {
        "chelsea": "chelsea",
        "coins": "coins",
        "moon": "moon",
        "retina": "retina",
        "page": "page",
    }
)

PHOTO_NAMES: tuple[str, ...] = tuple(_LOADERS)
"""Every name accepted by :func:`load_texture`: :data:`TEXTURE_NAMES` first."""


@functools.cache
def _load(name: str, decode_srgb: bool) -> np.ndarray:
    import skimage.data

    image = getattr(skimage.data, _LOADERS[name])()
    if isinstance(image, tuple):  # stereo_motorcycle returns (left, right, disparity)
        image = image[0]
    image = np.asarray(image)
    scale = float(np.iinfo(image.dtype).max) if image.dtype.kind in "ui" else 1.0
    values = image.astype(np.float64) / scale
    if values.ndim == 2:
        values = np.repeat(values[..., None], 3, axis=2)
    values = values[..., :3]
    if decode_srgb:
        values = srgb_to_linear(values)
    out = np.clip(values, 0.0, 1.0).astype(np.float32)
    out.flags.writeable = False
    return out


def load_texture(name: str, *, decode_srgb: bool = True) -> np.ndarray:
    """One bundled texture as an ``(h, w, 3)`` float32 RGB array in [0, 1].

    Parameters
    ----------
    name : str
        One of :data:`PHOTO_NAMES`.
    decode_srgb : bool
        Decode the sRGB curve of the stored 8-bit image to linear values (default).

    Returns
    -------
    ndarray, shape (h, w, 3), float32
        A fresh, writeable copy.
    """
    if name not in _LOADERS:
        raise InputError(f"unknown texture {name!r}, expected one of {', '.join(PHOTO_NAMES)}")
    return _load(name, bool(decode_srgb)).copy()
