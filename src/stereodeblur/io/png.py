"""PNG images and masks: header and structure checks before decoding, and writing.

Conventions
-----------
Images are float32 arrays in [0, 1], shape (H, W) grey or (H, W, 3) RGB; PNG
integers are scaled by the maximum of their type (255 or 65535); alpha is
dropped. Masks are (H, W) bool, stored as 8-bit grey 0 / 255. A file is checked
from its header and chunk lengths (:func:`check_png_file`) before any decoder
allocates memory for it, so a bad file raises
:class:`~stereodeblur.errors.InputError` naming it, never an OpenCV error.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np

from ..errors import InputError
from .files import _read_bytes, atomic_write, quiet_stderr

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# Largest image read (from its header, before any memory is spent): below OpenCV's own
# limits (2**30 pixels, 2**20 per side), so the error names the file.
MAX_PIXELS = 2**28
MAX_SIDE = 2**20
# Samples per pixel of each PNG colour type, and the most deflate can compress.
_PNG_SAMPLES = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
_DEFLATE_MAX_RATIO = 1032
# Allowed PNG bit depths per colour type, and channels after dropping alpha.
_PNG_COLOR_TYPES = {
    0: ((1, 2, 4, 8, 16), 1),  # grey
    2: ((8, 16), 3),  # RGB
    3: ((1, 2, 4, 8), 3),  # palette
    4: ((8, 16), 1),  # grey + alpha
    6: ((8, 16), 3),  # RGB + alpha
}


@dataclass(frozen=True)
class PngInfo:
    """Size and type of a PNG file from its IHDR chunk.

    ``channels`` counts colour channels after dropping alpha (1 grey, 3 RGB),
    i.e. the channels :func:`read_png` returns.
    """

    width: int
    height: int
    bit_depth: int
    channels: int


def _parse_ihdr(head: bytes, path) -> tuple[PngInfo, int]:
    if len(head) < 8 or head[:8] != PNG_SIGNATURE:
        raise InputError(f"not a PNG file: {path}")
    if len(head) < 33:
        raise InputError(f"truncated PNG header in {path}")
    length, kind = struct.unpack(">I4s", head[8:16])
    if kind != b"IHDR" or length != 13:
        raise InputError(f"corrupt PNG file {path}: first chunk is not a 13-byte IHDR")
    data, crc = head[16:29], struct.unpack(">I", head[29:33])[0]
    if zlib.crc32(b"IHDR" + data) != crc:
        raise InputError(f"corrupt PNG file {path}: IHDR checksum mismatch")
    width, height, bit_depth, color_type = struct.unpack(">IIBB", data[:10])
    if width == 0 or height == 0 or width >= 2**31 or height >= 2**31:
        raise InputError(f"corrupt PNG file {path}: invalid size {width}x{height}")
    if width * height > MAX_PIXELS or max(width, height) > MAX_SIDE:
        raise InputError(
            f"{path} is {width}x{height}: images may have at most {MAX_PIXELS} pixels "
            f"and {MAX_SIDE} per side"
        )
    if color_type not in _PNG_COLOR_TYPES or bit_depth not in _PNG_COLOR_TYPES[color_type][0]:
        raise InputError(
            f"corrupt PNG file {path}: invalid colour type {color_type} with bit depth {bit_depth}"
        )
    return PngInfo(width, height, bit_depth, _PNG_COLOR_TYPES[color_type][1]), color_type


def read_png_header(path: str | os.PathLike) -> PngInfo:
    """Read width, height, bit depth and channels of a PNG without decoding it.

    Parses only the signature and the IHDR chunk (33 bytes).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        with open(path, "rb") as handle:
            head = handle.read(33)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc
    return _parse_ihdr(head, path)[0]


def png_data_length(handle: BinaryIO, size: int, path) -> int:
    """Walk a PNG's chunks by their lengths (no decoding); the total IDAT bytes.

    ``handle`` is positioned at the start of the file, which has ``size`` bytes.
    Raises :class:`InputError` naming ``path`` when the file is truncated, has no
    image data or no end chunk.
    """
    if handle.read(8) != PNG_SIGNATURE:
        raise InputError(f"not a PNG file: {path}")
    position, data_length = 8, 0
    while True:
        head = handle.read(8)
        if len(head) < 8:
            what = "no image data (IDAT)" if not data_length else "no end chunk (IEND)"
            raise InputError(f"truncated PNG file {path}: {what} in its {size} bytes")
        length, kind = struct.unpack(">I4s", head)
        end = position + 12 + length
        if length >= 2**31 or end > size:
            raise InputError(
                f"truncated PNG file {path}: chunk {kind!r} at byte {position} needs "
                f"{12 + length} bytes, the file has {size - position} left"
            )
        if kind == b"IDAT":
            data_length += length
        elif kind == b"IEND":
            if not data_length:
                raise InputError(f"corrupt PNG file {path}: no image data (IDAT)")
            return data_length
        handle.seek(end)
        position = end


def _png_structure(handle: BinaryIO, size: int, path) -> PngInfo:
    """Header and chunk layout of a PNG, and enough image data for its declared size.

    Deflate compresses at most ~1032:1, so image data too short for the declared
    size is refused here, before a decoder allocates the image.
    """
    info, color_type = _parse_ihdr(handle.read(33), path)
    handle.seek(0)
    compressed = png_data_length(handle, size, path)
    samples = _PNG_SAMPLES[color_type]
    raw_bytes = info.height * (1 + (info.width * samples * info.bit_depth + 7) // 8)
    if compressed * _DEFLATE_MAX_RATIO < raw_bytes:
        raise InputError(
            f"corrupt PNG file {path}: {compressed} bytes of image data cannot hold "
            f"{info.width}x{info.height} pixels"
        )
    return info


def check_png_file(path: str | os.PathLike) -> PngInfo:
    """Check a PNG without decoding it: header, chunks, enough data; returns its header.

    Raises
    ------
    FileNotFoundError
        If ``path`` is not a file.
    InputError
        Naming ``path``: not a PNG, truncated, or corrupt.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        with open(path, "rb") as handle:
            return _png_structure(handle, os.fstat(handle.fileno()).st_size, path)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None


def _decode_png(path) -> tuple[np.ndarray, PngInfo]:
    """Decode a PNG to its integer array, (H, W) or (H, W, 3) RGB, alpha dropped."""
    data = _read_bytes(path)
    info = _png_structure(io.BytesIO(data), len(data), path)
    with quiet_stderr():
        raw = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise InputError(f"cannot decode PNG file {path} (corrupt or truncated)")
    if raw.ndim == 3 and info.channels == 1:
        raw = raw[..., 0]
    elif raw.ndim == 3:
        raw = np.ascontiguousarray(raw[..., 2::-1])  # BGR(A) -> RGB
    elif info.channels == 3:
        raw = np.repeat(raw[..., None], 3, axis=2)
    if raw.shape[:2] != (info.height, info.width):
        raise InputError(
            f"corrupt PNG file {path}: header says {info.width}x{info.height}, "
            f"decoded {raw.shape[1]}x{raw.shape[0]}"
        )
    return raw, info


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read an 8- or 16-bit PNG as float32 in [0, 1].

    Returns
    -------
    ndarray
        (H, W) for grey or (H, W, 3) RGB; alpha is dropped.
    """
    raw, _ = _decode_png(path)
    scale = np.float32(np.iinfo(raw.dtype).max)
    return raw.astype(np.float32) / scale


def _check_image(image, name: str = "image") -> np.ndarray:
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)) or image.size == 0:
        raise InputError(f"{name} must have shape (H, W) or (H, W, 3), got {image.shape}")
    if not np.issubdtype(image.dtype, np.number) or np.issubdtype(image.dtype, np.complexfloating):
        raise InputError(f"{name} must be real-valued, got dtype {image.dtype}")
    if not np.all(np.isfinite(image)):
        raise InputError(f"{name} has non-finite values")
    return image


def write_png(path: str | os.PathLike, image: np.ndarray, *, bit_depth: int = 16) -> Path:
    """Write a float image in [0, 1] (clipped) as an 8- or 16-bit grey or RGB PNG.

    Values are rounded to the nearest integer level.
    """
    if bit_depth not in (8, 16):
        raise InputError(f"bit_depth must be 8 or 16, got {bit_depth!r}")
    image = _check_image(image)
    top = 255 if bit_depth == 8 else 65535
    levels = np.rint(np.clip(image.astype(np.float64), 0.0, 1.0) * top)
    levels = levels.astype(np.uint8 if bit_depth == 8 else np.uint16)
    return _write_png_levels(path, levels)


def _write_png_levels(path, levels: np.ndarray) -> Path:
    if levels.ndim == 3:
        levels = np.ascontiguousarray(levels[..., ::-1])  # RGB -> BGR for OpenCV
    ok, buffer = cv2.imencode(".png", levels)
    if not ok:
        raise InputError(f"cannot encode PNG for {path}")
    return atomic_write(path, buffer.tobytes())


# --------------------------------------------------------------------------- masks


def read_mask(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG mask as (H, W) bool: True where any channel is nonzero."""
    raw, _ = _decode_png(path)
    return raw.any(axis=2) if raw.ndim == 3 else raw != 0


def write_mask(path: str | os.PathLike, mask: np.ndarray) -> Path:
    """Write an (H, W) mask as an 8-bit grey PNG, 255 where True and 0 elsewhere."""
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.size == 0:
        raise InputError(f"mask must have shape (H, W), got {mask.shape}")
    return _write_png_levels(path, np.where(mask.astype(bool), 255, 0).astype(np.uint8))
