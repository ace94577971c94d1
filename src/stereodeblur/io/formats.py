"""Single-file formats of the scene layout: PNG, PFM, FLO, masks, and the sRGB curve.

Conventions
-----------
Images are float32 arrays in [0, 1], shape (H, W) grey or (H, W, 3) RGB; PNG
integers are scaled by the maximum of their type (255 or 65535). Rows run top to
bottom in every array, whatever the file stores. Flow is (H, W, 2) float32 with
u along x and v along y. Masks are (H, W) bool.

Every writer is atomic: it writes a hidden temporary file in the target folder
(creating the folder) and renames it over the target, so a reader never sees a
half-written file. Bad files raise :class:`~stereodeblur.errors.InputError` (or
``FileNotFoundError``) with a one-line message naming the file.
"""

from __future__ import annotations

import contextlib
import io
import os
import secrets
import struct
import threading
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np

from ..errors import InputError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
FLO_MAGIC = 202021.25
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


# --------------------------------------------------------------------------- helpers


def _atomic_write(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _read_bytes(path: str | os.PathLike) -> bytes:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc


# --------------------------------------------------------------------------- PNG


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


_QUIET_LOCK = threading.Lock()
_quiet_state = {"depth": 0, "saved": None, "level": None}


@contextlib.contextmanager
def quiet_stderr():
    """Keep C libraries' messages (OpenCV, libpng, FFmpeg) off the terminal (fd 2).

    For calls whose failure the caller reports itself, in one line. Nested and
    concurrent uses (threads) share one redirection: the first to enter redirects,
    the last to leave restores.
    """
    with _QUIET_LOCK:
        if _quiet_state["depth"] == 0:
            _quiet_state["level"] = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
            try:
                saved = os.dup(2)
                with open(os.devnull, "wb") as null:
                    os.dup2(null.fileno(), 2)
            except OSError:  # no fd 2 (detached process): nothing to silence
                saved = None
            _quiet_state["saved"] = saved
        _quiet_state["depth"] += 1
    try:
        yield
    finally:
        with _QUIET_LOCK:
            _quiet_state["depth"] -= 1
            if _quiet_state["depth"] == 0:
                saved = _quiet_state["saved"]
                if saved is not None:
                    os.dup2(saved, 2)
                    os.close(saved)
                cv2.utils.logging.setLogLevel(_quiet_state["level"])


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
    return _atomic_write(path, buffer.tobytes())


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


def read_pfm(path: str | os.PathLike) -> np.ndarray:
    """Read a Portable Float Map as float32, (H, W) or (H, W, 3), rows top to bottom.

    The sign of the scale gives the byte order (negative = little-endian); its
    magnitude is ignored.
    """
    data = _read_bytes(path)
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
    start = len(data) - 4 * count
    if start <= pos or not data[pos:start].isspace():
        raise InputError(
            f"corrupt PFM file {path}: expected {4 * count} data bytes for "
            f"{width}x{height}x{channels}, found {len(data) - pos - 1}"
        )
    dtype = np.dtype("<f4" if scale < 0 else ">f4")
    array = np.frombuffer(data, dtype=dtype, count=count, offset=start)
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


def read_flo(path: str | os.PathLike) -> np.ndarray:
    """Read a Middlebury ``.flo`` file as (H, W, 2) float32 (u, v)."""
    data = _read_bytes(path)
    if len(data) < 12:
        raise InputError(f"corrupt FLO file {path}: shorter than its 12-byte header")
    magic = np.frombuffer(data, dtype="<f4", count=1)[0]
    if magic != np.float32(FLO_MAGIC):
        raise InputError(f"not a FLO file: {path} (magic {magic}, expected {FLO_MAGIC})")
    width, height = (int(v) for v in np.frombuffer(data, dtype="<i4", count=2, offset=4))
    if width <= 0 or height <= 0:
        raise InputError(f"corrupt FLO file {path}: invalid size {width}x{height}")
    expected = width * height * 2 * 4
    if len(data) - 12 != expected:
        raise InputError(
            f"corrupt FLO file {path}: expected {expected} data bytes for {width}x{height}, "
            f"found {len(data) - 12}"
        )
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


# --------------------------------------------------------------------------- sRGB


def _float_out(x) -> tuple[np.ndarray, np.dtype]:
    x = np.asarray(x)
    dtype = x.dtype if np.issubdtype(x.dtype, np.floating) else np.dtype(np.float64)
    return x.astype(np.float64), dtype


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """Decode the sRGB curve (IEC 61966-2-1): values in [0, 1] to linear [0, 1].

    Keeps a floating input's dtype (float64 otherwise).
    """
    x, dtype = _float_out(x)
    curve = ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4
    return np.where(x <= 0.04045, x / 12.92, curve).astype(dtype)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Encode the sRGB curve (IEC 61966-2-1): linear [0, 1] to sRGB [0, 1].

    Keeps a floating input's dtype (float64 otherwise).
    """
    x, dtype = _float_out(x)
    curve = 1.055 * np.maximum(x, 0.0031308) ** (1 / 2.4) - 0.055
    return np.where(x <= 0.0031308, x * 12.92, curve).astype(dtype)
