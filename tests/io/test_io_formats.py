"""Tests of stereodeblur.io.formats: PNG, PFM, FLO, masks, sRGB."""

import struct
import zlib

import cv2
import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io import (
    PngInfo,
    linear_to_srgb,
    read_flo,
    read_mask,
    read_pfm,
    read_png,
    read_png_header,
    srgb_to_linear,
    write_flo,
    write_mask,
    write_pfm,
    write_png,
)


def _png_bytes(width, height, color_type, bit_depth, rows):
    """A minimal PNG built by hand (independent of OpenCV)."""

    def chunk(kind, data):
        crc = struct.pack(">I", zlib.crc32(kind + data))
        return struct.pack(">I", len(data)) + kind + data + crc

    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, color_type, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(rows))
        + chunk(b"IEND", b"")
    )


def _no_temporaries(folder):
    return [p.name for p in folder.iterdir() if p.name.startswith(".")] == []


# --------------------------------------------------------------------------- PNG


@pytest.mark.parametrize("bit_depth", [8, 16])
@pytest.mark.parametrize("channels", [1, 3])
def test_png_round_trip(tmp_path, bit_depth, channels):
    rng = np.random.default_rng(bit_depth + channels)
    shape = (48, 64) if channels == 1 else (48, 64, 3)
    image = rng.random(shape)
    image[0, 0] = 0.0
    image[0, 1] = 1.0
    path = write_png(tmp_path / "sub" / "a.png", image, bit_depth=bit_depth)
    assert path == tmp_path / "sub" / "a.png"
    back = read_png(path)
    top = 2**bit_depth - 1
    assert back.dtype == np.float32 and back.shape == shape
    assert np.max(np.abs(back - image)) <= 0.5 / top + 1e-7
    # Independent decoding: OpenCV gives BGR integers.
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == (np.uint8 if bit_depth == 8 else np.uint16)
    if channels == 3:
        raw = raw[..., ::-1]
    np.testing.assert_array_equal(raw, np.rint(image * top))
    np.testing.assert_array_equal(back, raw.astype(np.float32) / top)
    assert read_png_header(path) == PngInfo(64, 48, bit_depth, channels)
    assert _no_temporaries(path.parent)


def test_png_clips_and_overwrites(tmp_path):
    path = tmp_path / "a.png"
    write_png(path, np.full((4, 5), 0.5), bit_depth=8)
    write_png(path, np.array([[-1.0, 2.0, 0.25]]), bit_depth=8)
    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), [[0, 255, 64]])
    assert _no_temporaries(tmp_path)


def test_png_drops_alpha(tmp_path):
    rgba = np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4) * 5
    cv2.imwrite(str(tmp_path / "rgba.png"), rgba)  # stored as BGRA
    np.testing.assert_array_equal(read_png(tmp_path / "rgba.png") * 255, rgba[..., 2::-1])
    assert read_png_header(tmp_path / "rgba.png").channels == 3
    rows = b"".join(
        b"\x00" + b"".join(bytes([10 * x + 50 * y, 128]) for x in range(3)) for y in range(2)
    )
    (tmp_path / "ga.png").write_bytes(_png_bytes(3, 2, 4, 8, rows))
    grey = read_png(tmp_path / "ga.png")
    np.testing.assert_array_equal(grey * 255, [[0, 10, 20], [50, 60, 70]])
    assert read_png_header(tmp_path / "ga.png") == PngInfo(3, 2, 8, 1)


def test_png_header_is_parsed_without_opencv(tmp_path):
    rows = b"".join(b"\x00" + bytes(7 * 6) for _ in range(5))
    (tmp_path / "a.png").write_bytes(_png_bytes(7, 5, 2, 16, rows))
    assert read_png_header(tmp_path / "a.png") == PngInfo(7, 5, 16, 3)
    assert read_png(tmp_path / "a.png").shape == (5, 7, 3)


def test_png_bad_inputs_name_the_file(tmp_path):
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(np.random.default_rng(0).bytes(200))
    for reader in (read_png, read_png_header, read_mask):
        with pytest.raises(InputError, match="not a PNG file.*garbage.png"):
            reader(garbage)
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_png(tmp_path / "missing.png")
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_png_header(tmp_path / "missing.png")
    # Valid header, truncated image data.
    good = write_png(tmp_path / "good.png", np.random.default_rng(1).random((40, 50, 3)))
    truncated = tmp_path / "truncated.png"
    truncated.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    assert read_png_header(truncated) == PngInfo(50, 40, 16, 3)
    with pytest.raises(InputError, match="truncated PNG file .*truncated.png: chunk b'IDAT'"):
        read_png(truncated)
    # Complete chunks, corrupt compressed data: OpenCV fails, quietly, and we say so.
    data = good.read_bytes()
    start = data.index(b"IDAT") + 4
    (tmp_path / "scrambled.png").write_bytes(data[:start] + bytes(200) + data[start + 200 :])
    with pytest.raises(InputError, match="cannot decode PNG file .*scrambled.png"):
        read_png(tmp_path / "scrambled.png")
    # A header declaring far more pixels than the data can hold: refused before decoding.
    big = bytearray(data)
    big[16:24] = (4000).to_bytes(4, "big") + (3000).to_bytes(4, "big")
    big[29:33] = zlib.crc32(bytes(big[12:29])).to_bytes(4, "big")
    (tmp_path / "big.png").write_bytes(bytes(big))
    with pytest.raises(InputError, match="image data cannot hold 4000x3000 pixels"):
        read_png(tmp_path / "big.png")
    # Corrupt IHDR checksum.
    data = bytearray(good.read_bytes())
    data[20] ^= 0xFF
    (tmp_path / "crc.png").write_bytes(bytes(data))
    with pytest.raises(InputError, match="crc.png.*checksum"):
        read_png_header(tmp_path / "crc.png")


def test_png_rejects_bad_arrays(tmp_path):
    with pytest.raises(InputError, match="shape"):
        write_png(tmp_path / "a.png", np.zeros((4, 5, 2)))
    with pytest.raises(InputError, match="non-finite"):
        write_png(tmp_path / "a.png", np.full((4, 5), np.nan))
    with pytest.raises(InputError, match="bit_depth"):
        write_png(tmp_path / "a.png", np.zeros((4, 5)), bit_depth=12)
    assert not (tmp_path / "a.png").exists()


# --------------------------------------------------------------------------- masks


def test_mask_round_trip(tmp_path):
    mask = np.random.default_rng(2).random((48, 64)) > 0.5
    path = write_mask(tmp_path / "m.png", mask)
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint8 and set(np.unique(raw)) == {0, 255}
    np.testing.assert_array_equal(raw == 255, mask)
    back = read_mask(path)
    assert back.dtype == bool
    np.testing.assert_array_equal(back, mask)
    with pytest.raises(InputError, match="shape"):
        write_mask(tmp_path / "m.png", np.zeros((4, 5, 3)))


# --------------------------------------------------------------------------- PFM


def _special_floats(shape, seed):
    rng = np.random.default_rng(seed)
    array = (rng.standard_normal(shape) * 100).astype(np.float32)
    flat = array.reshape(-1)
    flat[:6] = [np.nan, np.inf, -np.inf, 0.0, -0.0, np.float32(1e-42)]  # incl. a denormal
    return array


def _bits(array):
    return np.ascontiguousarray(array, dtype=np.float32).view(np.uint32)


@pytest.mark.parametrize("shape", [(48, 64), (48, 64, 3), (1, 7)])
def test_pfm_round_trip_bit_exact(tmp_path, shape):
    array = _special_floats(shape, seed=len(shape))
    path = write_pfm(tmp_path / "a.pfm", array)
    back = read_pfm(path)
    assert back.dtype == np.float32 and back.shape == shape
    np.testing.assert_array_equal(_bits(back), _bits(array))
    back[0, 0] = 1.0  # the result is a writable copy
    assert _no_temporaries(tmp_path)


@pytest.mark.parametrize("byte_order", ["<", ">"])
@pytest.mark.parametrize("channels", [1, 3])
def test_pfm_hand_made_both_endiannesses(tmp_path, byte_order, channels):
    shape = (6, 7) if channels == 1 else (6, 7, 3)
    array = _special_floats(shape, seed=channels)
    scale = "-1.0" if byte_order == "<" else "1.0"
    header = f"{'Pf' if channels == 1 else 'PF'}\n7 6\n{scale}\n".encode()
    body = np.ascontiguousarray(array[::-1], dtype=byte_order + "f4").tobytes()
    (tmp_path / "a.pfm").write_bytes(header + body)
    np.testing.assert_array_equal(_bits(read_pfm(tmp_path / "a.pfm")), _bits(array))


@pytest.mark.parametrize("channels", [1, 3])
def test_pfm_agrees_with_opencv(tmp_path, channels):
    shape = (48, 64) if channels == 1 else (48, 64, 3)
    array = np.random.default_rng(3).standard_normal(shape).astype(np.float32)
    bgr = array if channels == 1 else array[..., ::-1]
    # OpenCV writes, we read.
    assert cv2.imwrite(str(tmp_path / "cv.pfm"), np.ascontiguousarray(bgr))
    np.testing.assert_array_equal(_bits(read_pfm(tmp_path / "cv.pfm")), _bits(array))
    # We write, OpenCV reads.
    write_pfm(tmp_path / "ours.pfm", array)
    decoded = cv2.imread(str(tmp_path / "ours.pfm"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(_bits(decoded), _bits(bgr))


def test_pfm_bad_files_name_the_file(tmp_path):
    good = write_pfm(tmp_path / "good.pfm", np.ones((4, 5), np.float32)).read_bytes()
    cases = {
        "magic.pfm": (b"P6\n5 4\n255\n" + bytes(60), "not a PFM file"),
        "header.pfm": (b"Pf\nfive 4\n-1\n" + bytes(80), "not 'width height scale'"),
        "size.pfm": (b"Pf\n0 4\n-1\n", "invalid size"),
        "scale.pfm": (b"Pf\n5 4\n0\n" + bytes(80), "scale"),
        "short.pfm": (good[:-4], "expected 80 data bytes"),
        "long.pfm": (good + b"xxxx", "expected 80 data bytes"),
        "empty.pfm": (b"", "not a PFM file"),
    }
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError, match=message) as info:
            read_pfm(tmp_path / name)
        assert name in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(FileNotFoundError, match="nothere.pfm"):
        read_pfm(tmp_path / "nothere.pfm")
    with pytest.raises(InputError, match="shape"):
        write_pfm(tmp_path / "x.pfm", np.zeros((4, 5, 2)))


# --------------------------------------------------------------------------- FLO


def test_flo_round_trip_and_opencv(tmp_path):
    flow = _special_floats((48, 64, 2), seed=4)
    path = write_flo(tmp_path / "f" / "a.flo", flow)
    back = read_flo(path)
    assert back.dtype == np.float32 and back.shape == (48, 64, 2)
    np.testing.assert_array_equal(_bits(back), _bits(flow))
    raw = path.read_bytes()
    assert raw[:4] == b"PIEH" and struct.unpack("<fii", raw[:12]) == (202021.25, 64, 48)
    assert len(raw) == 12 + 48 * 64 * 2 * 4
    finite = np.random.default_rng(5).standard_normal((30, 40, 2)).astype(np.float32)
    write_flo(tmp_path / "b.flo", finite)
    np.testing.assert_array_equal(cv2.readOpticalFlow(str(tmp_path / "b.flo")), finite)
    assert cv2.writeOpticalFlow(str(tmp_path / "cv.flo"), finite)
    np.testing.assert_array_equal(read_flo(tmp_path / "cv.flo"), finite)


def test_flo_bad_files_name_the_file(tmp_path):
    good = write_flo(tmp_path / "good.flo", np.zeros((4, 5, 2), np.float32)).read_bytes()
    cases = {
        "magic.flo": (b"PIEX" + good[4:], "not a FLO file"),
        "header.flo": (good[:8], "header"),
        "size.flo": (good[:4] + struct.pack("<ii", -5, 4) + good[12:], "invalid size"),
        "short.flo": (good[:-1], "expected 160 data bytes"),
        "long.flo": (good + bytes(8), "expected 160 data bytes"),
    }
    for name, (data, message) in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError, match=message) as info:
            read_flo(tmp_path / name)
        assert name in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="shape"):
        write_flo(tmp_path / "x.flo", np.zeros((4, 5, 3)))


# --------------------------------------------------------------------------- sRGB


def test_srgb_curve_values():
    # IEC 61966-2-1 reference points, computed from the formula by hand.
    assert float(srgb_to_linear(0.5)) == pytest.approx(((0.5 + 0.055) / 1.055) ** 2.4, rel=1e-15)
    assert float(srgb_to_linear(0.5)) == pytest.approx(0.21404114048223255, rel=1e-12)
    assert float(srgb_to_linear(0.02)) == pytest.approx(0.02 / 12.92, rel=1e-15)
    assert float(linear_to_srgb(0.001)) == pytest.approx(0.01292, rel=1e-12)
    assert float(linear_to_srgb(0.5)) == pytest.approx(1.055 * 0.5 ** (1 / 2.4) - 0.055)
    assert float(linear_to_srgb(1.0)) == pytest.approx(1.0, abs=1e-12)
    assert float(srgb_to_linear(1.0)) == pytest.approx(1.0, abs=1e-12)
    # Nearly continuous at the thresholds (the standard's constants are rounded).
    assert float(linear_to_srgb(0.0031308)) == pytest.approx(0.04045, abs=1e-6)
    assert float(srgb_to_linear(0.04045)) == pytest.approx(0.0031308, abs=1e-6)


def test_srgb_round_trip_and_dtypes():
    x = np.linspace(-0.1, 1.1, 10001)
    np.testing.assert_allclose(srgb_to_linear(linear_to_srgb(x)), x, atol=1e-12)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-12)
    assert np.all(np.diff(linear_to_srgb(x)) > 0) and np.all(np.diff(srgb_to_linear(x)) > 0)
    image = np.random.default_rng(6).random((8, 9, 3)).astype(np.float32)
    encoded = linear_to_srgb(image)
    assert encoded.dtype == np.float32 and encoded.shape == image.shape
    np.testing.assert_allclose(srgb_to_linear(encoded), image, atol=2e-6)
    assert srgb_to_linear(np.array([0, 128, 255])).dtype == np.float64
