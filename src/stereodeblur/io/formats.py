"""Single-file formats of the scene layout: PFM and FLO here, PNG in :mod:`.png`.

This module is also the one place to import every single-file reader and writer
from (PNG, masks, the sRGB curve and the atomic writer are re-exported).

Conventions
-----------
Rows run top to bottom in every array, whatever the file stores. Flow is
(H, W, 2) float32 with u along x and v along y. Every writer is atomic
(:func:`~stereodeblur.io.files.atomic_write`). Bad files raise
:class:`~stereodeblur.errors.InputError` (or ``FileNotFoundError``) with a
one-line message naming the file.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError
from .files import _atomic_write as _atomic_write
from .files import _read_bytes, quiet_stderr
from .png import (
    MAX_PIXELS,
    MAX_SIDE,
    PNG_SIGNATURE,
    PngInfo,
    check_png_file,
    png_data_length,
    read_mask,
    read_png,
    read_png_header,
    write_mask,
    write_png,
)
from .png import _check_image as _check_image
from .srgb import linear_to_srgb, srgb_to_linear

__all__ = [
    "FLO_MAGIC",
    "MAX_PIXELS",
    "MAX_SIDE",
    "PNG_SIGNATURE",
    "PngInfo",
    "check_png_file",
    "linear_to_srgb",
    "png_data_length",
    "quiet_stderr",
    "read_flo",
    "read_flo_header",
    "read_mask",
    "read_pfm",
    "read_pfm_header",
    "read_png",
    "read_png_header",
    "srgb_to_linear",
    "write_flo",
    "write_mask",
    "write_pfm",
    "write_png",
]

FLO_MAGIC = 202021.25
_PFM_HEADER_MAX = 4096  # bytes read for a PFM header check


# --------------------------------------------------------------------------- PFM


def _pfm_token(data: bytes, pos: int, path) -> tuple[bytes, int]:
    """Next whitespace-delimited header token and the index just past it."""
    while pos < len(data) and data[pos : pos + 1].isspace():
        pos += 1
    end = pos
    while end < len(data) and not data[end : end + 1].isspace():
        end += 1
        if end - pos > 32:
            raise InputError(f"corrupt PFM file {path}: header token longer than 32 bytes")
    if end == pos or end >= len(data):
        raise InputError(f"corrupt PFM file {path}: truncated header")
    return data[pos:end], end


def _pfm_header(data: bytes, size: int, path) -> tuple[int, int, int, float, int]:
    """``(width, height, channels, scale, data start)`` of a PFM whose first bytes are
    ``data`` and whose size is ``size``; checks the size against the header."""
    if data[:2] not in (b"PF", b"Pf") or not data[2:3].isspace():
        raise InputError(f"not a PFM file: {path} (expected a 'PF' or 'Pf' header line)")
    channels = 3 if data[:2] == b"PF" else 1
    tokens, pos = [], 2
    for _ in range(3):
        token, pos = _pfm_token(data, pos, path)
        tokens.append(token)
    try:
        width, height, scale = int(tokens[0]), int(tokens[1]), float(tokens[2])
    except ValueError:
        header = b" ".join(tokens).decode("ascii", "replace")
        raise InputError(
            f"corrupt PFM file {path}: header {header!r} is not 'width height scale'"
        ) from None
    if width <= 0 or height <= 0:
        raise InputError(f"corrupt PFM file {path}: invalid size {width}x{height}")
    if not np.isfinite(scale) or scale == 0:
        raise InputError(f"corrupt PFM file {path}: scale must be a nonzero number, got {scale}")
    # The header ends with whitespace after the scale; the data are the last bytes.
    count = width * height * channels
    start = size - 4 * count
    if start <= pos or not data[pos : min(start, len(data))].isspace():
        raise InputError(
            f"corrupt PFM file {path}: expected {4 * count} data bytes for "
            f"{width}x{height}x{channels}, found {size - pos - 1}"
        )
    return width, height, channels, scale, start


def read_pfm_header(path: str | os.PathLike) -> tuple[int, int, int]:
    """``(width, height, channels)`` of a PFM file from its header and size, without
    reading its data (the header must fit in its first 4 KiB)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        with open(path, "rb") as handle:
            head = handle.read(_PFM_HEADER_MAX)
            size = os.fstat(handle.fileno()).st_size
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc
    return _pfm_header(head, size, path)[:3]


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a Portable Float Map as float32, (H, W) or (H, W, 3), rows top to bottom.

    The sign of the scale gives the byte order (negative = little-endian); its
    magnitude is ignored.
    """
    data = _read_bytes(path)
    width, height, channels, scale, start = _pfm_header(data, len(data), path)
    dtype = np.dtype("<f4" if scale < 0 else ">f4")
    array = np.frombuffer(data, dtype=dtype, count=width * height * channels, offset=start)
    shape = (height, width, channels) if channels == 3 else (height, width)
    return np.array(array.reshape(shape)[::-1], dtype=np.float32, order="C")


def write_pfm(path: str | os.PathLike, array: np.ndarray) -> Path:
    """Write a float32 (H, W) or (H, W, 3) array as a little-endian PFM (rows bottom up)."""
    array = np.asarray(array)
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[..., 0]
    if not (array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 3)) or array.size == 0:
        raise InputError(f"PFM array must have shape (H, W) or (H, W, 3), got {array.shape}")
    height, width = array.shape[:2]
    header = f"{'PF' if array.ndim == 3 else 'Pf'}\n{width} {height}\n-1.0\n".encode("ascii")
    body = np.ascontiguousarray(array[::-1], dtype="<f4").tobytes()
    return _atomic_write(path, header + body)


# --------------------------------------------------------------------------- FLO


def _flo_header(data: bytes, size: int, path) -> tuple[int, int]:
    """``(width, height)`` of a FLO file whose first bytes are ``data`` and size ``size``."""
    if len(data) < 12:
        raise InputError(f"corrupt FLO file {path}: shorter than its 12-byte header")
    magic = np.frombuffer(data, dtype="<f4", count=1)[0]
    if magic != np.float32(FLO_MAGIC):
        raise InputError(f"not a FLO file: {path} (magic {magic}, expected {FLO_MAGIC})")
    width, height = (int(v) for v in np.frombuffer(data, dtype="<i4", count=2, offset=4))
    if width <= 0 or height <= 0:
        raise InputError(f"corrupt FLO file {path}: invalid size {width}x{height}")
    expected = width * height * 2 * 4
    if size - 12 != expected:
        raise InputError(
            f"corrupt FLO file {path}: expected {expected} data bytes for {width}x{height}, "
            f"found {size - 12}"
        )
    return width, height


def read_flo_header(path: str | os.PathLike) -> tuple[int, int]:
    """``(width, height)`` of a ``.flo`` file from its header and size, without its data."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        with open(path, "rb") as handle:
            head = handle.read(12)
            size = os.fstat(handle.fileno()).st_size
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc
    return _flo_header(head, size, path)


def read_flo(path: str | os.PathLike) -> np.ndarray:
    """Read a Middlebury ``.flo`` file as (H, W, 2) float32 (u, v)."""
    data = _read_bytes(path)
    width, height = _flo_header(data, len(data), path)
    flow = np.frombuffer(data, dtype="<f4", count=width * height * 2, offset=12)
    return flow.reshape(height, width, 2).astype(np.float32)


def write_flo(path: str | os.PathLike, flow: np.ndarray) -> Path:
    """Write an (H, W, 2) flow (u, v) as a Middlebury ``.flo`` file."""
    flow = np.asarray(flow)
    if flow.ndim != 3 or flow.shape[2] != 2 or flow.size == 0:
        raise InputError(f"flow must have shape (H, W, 2), got {flow.shape}")
    height, width = flow.shape[:2]
    header = np.array([FLO_MAGIC], "<f4").tobytes() + np.array([width, height], "<i4").tobytes()
    return _atomic_write(path, header + np.ascontiguousarray(flow, dtype="<f4").tobytes())
