"""Property-based fuzzing of every parser in stereodeblur.io: on arbitrary bytes and on
structured-but-wrong values each returns a valid value or raises InputError, never anything
else (no ValueError, struct.error, UnicodeDecodeError, OverflowError, MemoryError, cv2.error,
and no numpy warning, which pytest turns into an error)."""

import json
import math
import struct
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereodeblur.errors import InputError
from stereodeblur.io.calibration import (
    StereoCalibration,
    check_image_size,
    read_stereo_calibration,
    stereo_from_projections,
)
from stereodeblur.io.camera_json import CameraInfo, read_camera
from stereodeblur.io.formats import (
    PNG_SIGNATURE,
    PngInfo,
    check_png_file,
    read_flo,
    read_flo_header,
    read_mask,
    read_pfm,
    read_pfm_header,
    read_png,
    read_png_header,
)
from stereodeblur.io.intrinsics import check_intrinsics
from stereodeblur.io.kitti import (
    _rectified_size,
    kitti_camera,
    read_kitti_calibration,
    read_timestamps,
)

FUZZ = settings(
    max_examples=200,
    deadline=None,
    derandomize=True,  # the same examples on every run
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def _parse(reader, path, data: bytes):
    """``reader(path)`` on a file holding ``data``: its value, or None after an InputError."""
    path.write_bytes(data)
    try:
        return reader(path)
    except InputError as error:
        text = str(error)
        assert text and "\n" not in text and str(path) in text, text
        return None


# --------------------------------------------------------------------------- values

BAD_TOKENS = ["nan", "NaN", "inf", "-inf", "1e999", "-1e999", "1e-320", "0", "-0", "", "x", "1_0"]
huge_ints = st.integers(min_value=-(10**400), max_value=10**400)
numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**70), max_value=2**70),
    huge_ints,
    st.sampled_from([0, 1e-9, 1e300, -5000.0, 0.5, 32.0, 1e7]),
)
json_scalars = st.one_of(numbers, st.booleans(), st.none(), st.text(max_size=6))
token_text = st.one_of(
    numbers.map(lambda v: repr(float(v)) if isinstance(v, float) else str(v)),
    st.sampled_from(BAD_TOKENS),
)


# Values a careless or hostile file holds where a number belongs.
WEIRD_VALUES = [10**400, -(10**400), math.nan, math.inf, -math.inf, 0, -0.0, 1e-320, 1e308,
                -1e308, 1e-9, -5000.0, 2**64, True, None, "1", "", [], {}, [[1.0]]]  # fmt: skip
weird = st.one_of(st.sampled_from(WEIRD_VALUES), numbers)
WEIRD_TOKENS = ["nan", ".nan", ".Inf", "-.inf", "inf", "1e999", "-1e999", "1e308", "-1e308",
                "1e-320", "0", "-0", "1e-9", "-5000", "0x10", "1_0", "", "x", "[", "]", ",", "{",
                "}", ":", "#", "10" * 200]  # fmt: skip
weird_token = st.one_of(st.sampled_from(WEIRD_TOKENS), token_text)


# --------------------------------------------------------------------------- camera.json


def _json_text(value) -> str:
    return json.dumps(value, allow_nan=True, default=str)


camera_dicts = st.fixed_dictionaries(
    {
        "format": st.sampled_from(["stereo-video/1", "stereo-video/2", 1, None]),
        "K": st.one_of(
            st.lists(st.lists(json_scalars, min_size=3, max_size=3), min_size=3, max_size=3),
            st.lists(st.lists(numbers, max_size=4), max_size=4),
            json_scalars,
        ),
        "baseline": json_scalars,
        "frame_rate": json_scalars,
        "exposure": json_scalars,
    },
    optional={"color": st.sampled_from(["linear", "srgb", "sRGB", 3]), "extra": json_scalars},
)


@FUZZ
@given(data=st.binary(max_size=600))
def test_camera_json_arbitrary_bytes(folder, data):
    value = _parse(read_camera, folder / "camera.json", data)
    assert value is None or isinstance(value, CameraInfo)


@FUZZ
@given(camera=camera_dicts)
def test_camera_json_structured_values(folder, camera):
    value = _parse(read_camera, folder / "camera.json", _json_text(camera).encode())
    if value is not None:
        K = value.camera.K
        assert np.all(np.isfinite(K)) and K[0, 0] > 0 and value.camera.baseline > 0
        assert value.exposure.exposure <= 1 / value.exposure.frame_rate


GOOD_CAMERA = {
    "format": "stereo-video/1",
    "K": [[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]],
    "baseline": 0.12,
    "frame_rate": 20.0,
    "exposure": 0.04,
    "color": "linear",
}
CAMERA_PLACES = ["format", "K", "baseline", "frame_rate", "exposure", "color", "extra"] + [
    (r, c) for r in range(3) for c in range(3)
]


@FUZZ
@given(changes=st.lists(st.tuples(st.sampled_from(CAMERA_PLACES), weird), min_size=1, max_size=3))
def test_camera_json_one_value_wrong(folder, changes):
    camera = json.loads(json.dumps(GOOD_CAMERA))
    for place, value in sorted(changes, key=lambda change: not isinstance(change[0], tuple)):
        if isinstance(place, tuple):  # entries of K first, then whole keys
            camera["K"][place[0]][place[1]] = value
        else:
            camera[place] = value
    value = _parse(read_camera, folder / "camera.json", _json_text(camera).encode())
    if value is not None:
        try:  # the scene's rule for its frame size: passes or raises InputError
            check_intrinsics(value.camera.K, (32, 24), "camera.json")
        except InputError:
            pass


@pytest.mark.parametrize(
    "text",
    ["[" * 100000, '{"K": ' + "[" * 100000, '{"a": 1e999999}'],
    ids=["nested list", "nested K", "huge exponent"],
)
def test_camera_json_pathological_nesting(folder, text):
    assert _parse(read_camera, folder / "camera.json", text.encode()) is None


# --------------------------------------------------------------------------- calibrations


def _matrix_text(key, rows, cols, dt, values, flow) -> str:
    data = "[" + ", ".join(values) + "]"
    if flow:
        return f"{key}: !!opencv-matrix {{rows: {rows}, cols: {cols}, dt: {dt}, data: {data}}}"
    return f"{key}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: {dt}\n   data: {data}"


def _good_projection(baseline_pixels: float) -> list[str]:
    return [str(v) for v in [40, 0, 15.5, baseline_pixels, 0, 40, 11.5, 0, 0, 0, 1, 0]]


yaml_entries = st.lists(
    st.one_of(
        st.builds(
            _matrix_text,
            st.sampled_from(["P1", "P2", "Q", "M1", "imageSize", "R"]),
            st.sampled_from(["3", "4", "1", "0", "-3", "x", "1e3"]),
            st.sampled_from(["3", "4", "2", "0", "9999999999"]),
            st.sampled_from(["d", "f", "u", "q", '"d"']),
            st.one_of(
                st.lists(token_text, max_size=17),
                st.sampled_from([_good_projection(0.0), _good_projection(-4.8)]),
            ),
            st.booleans(),
        ),
        st.builds(
            lambda key, values: f"{key}: [" + ", ".join(values) + "]",
            st.sampled_from(["imageSize", "image_size", "D1"]),
            st.lists(token_text, max_size=3),
        ),
        st.builds(
            lambda key, value: f"{key}: {value}",
            st.sampled_from(["image_width", "image_height", "%YAML:1.0", "---", "  indented"]),
            token_text,
        ),
    ),
    max_size=6,
)


def _check_calibration(value):
    if value is None:
        return
    assert isinstance(value, StereoCalibration)
    assert np.all(np.isfinite(value.camera.K)) and value.camera.baseline > 0
    try:  # the intrinsics rule for 32x24 images: passes or raises InputError
        check_image_size(value, (32, 24), "fuzz video")
    except InputError:
        pass


@FUZZ
@given(data=st.binary(max_size=600))
def test_calibration_arbitrary_bytes(folder, data):
    _check_calibration(_parse(read_stereo_calibration, folder / "calib.yml", data))


@FUZZ
@given(entries=yaml_entries)
def test_opencv_yaml_structured_values(folder, entries):
    text = "%YAML:1.0\n---\n" + "\n".join(entries) + "\n"
    _check_calibration(_parse(read_stereo_calibration, folder / "calib.yml", text.encode()))


GOOD_MATRICES = {
    "M1": ("3", "3", "d", ["40", "0", "15.5", "0", "40", "11.5", "0", "0", "1"]),
    "P1": ("3", "4", "d", _good_projection(0.0)),
    "P2": ("3", "4", "d", _good_projection(-4.8)),
    "Q": ("4", "4", "d", ["1", "0", "0", "-15.5", "0", "1", "0", "-11.5", "0", "0", "0", "40",
                          "0", "0", "8.333333333333334", "0"]),
}  # fmt: skip
YAML_PLACES = [(key, field) for key in GOOD_MATRICES for field in range(3)] + [
    (key, 3 + i) for key, matrix in GOOD_MATRICES.items() for i in range(len(matrix[3]))
]


@FUZZ
@given(
    changes=st.lists(st.tuples(st.sampled_from(YAML_PLACES), weird_token), min_size=1, max_size=3),
    drop=st.sampled_from([None, "M1", "P1", "P2", "Q"]),
    flow=st.booleans(),
    size=st.sampled_from(
        ["imageSize: [ 32, 24 ]", "imageSize: [ 0, 24 ]", "", "imageSize: [ 1e999, 2 ]"]
    ),
)
def test_opencv_yaml_one_value_wrong(folder, changes, drop, flow, size):
    matrices = {key: [*m[:3], list(m[3])] for key, m in GOOD_MATRICES.items() if key != drop}
    for (key, field), token in changes:
        if key in matrices:
            if field < 3:
                matrices[key][field] = token
            else:
                matrices[key][3][field - 3] = token
    lines = [_matrix_text(key, *m, flow) for key, m in matrices.items()]
    text = "%YAML:1.0\n---\n" + "\n".join([*lines, size]) + "\n"
    _check_calibration(_parse(read_stereo_calibration, folder / "calib.yml", text.encode()))


@FUZZ
@given(
    matrices=st.dictionaries(
        st.sampled_from(["P1", "P2", "Q", "M1", "imageSize"]),
        st.fixed_dictionaries(
            {
                "type_id": st.sampled_from(["opencv-matrix", "x"]),
                "rows": json_scalars,
                "cols": json_scalars,
                "dt": st.sampled_from(["d", "f", 1]),
                "data": st.one_of(st.lists(numbers, max_size=16), json_scalars),
            }
        ),
        max_size=4,
    ),
    camera=camera_dicts,
    as_camera=st.booleans(),
)
def test_json_calibrations_structured_values(folder, matrices, camera, as_camera):
    text = _json_text(camera if as_camera else matrices)
    _check_calibration(_parse(read_stereo_calibration, folder / "calib.json", text.encode()))


# --------------------------------------------------------------------------- KITTI


kitti_lines = st.lists(
    st.builds(
        lambda key, values: f"{key}: " + " ".join(values),
        st.sampled_from(["P_rect_02", "P_rect_03", "S_rect_02", "calib_time", "P_rect_02 x"]),
        st.one_of(
            st.lists(token_text, max_size=13),
            st.sampled_from([_good_projection(0.0), _good_projection(-21.6)]),
        ),
    ),
    max_size=5,
)


def _kitti(path):
    camera, entries = kitti_camera(path, "P_rect_02", "P_rect_03")
    return camera, entries


@FUZZ
@given(data=st.binary(max_size=600))
def test_kitti_calibration_arbitrary_bytes(folder, data):
    _parse(read_kitti_calibration, folder / "calib.txt", data)
    _parse(_kitti, folder / "calib.txt", data)


@FUZZ
@given(lines=kitti_lines)
def test_kitti_calibration_structured_values(folder, lines):
    value = _parse(_kitti, folder / "calib.txt", ("\n".join(lines) + "\n").encode())
    if value is not None:
        camera, _ = value
        assert np.all(np.isfinite(camera.K)) and camera.baseline > 0


GOOD_KITTI = {
    "P_rect_02": [str(v) for v in [721.5, 0, 609.6, 44.9, 0, 721.5, 172.9, 0.2, 0, 0, 1, 0.003]],
    "P_rect_03": [str(v) for v in [721.5, 0, 609.6, -339.5, 0, 721.5, 172.9, 2.2, 0, 0, 1, 0.003]],
    "S_rect_02": ["1242", "375"],
}
KITTI_PLACES = [(key, i) for key, values in GOOD_KITTI.items() for i in range(len(values))]


@FUZZ
@given(
    changes=st.lists(st.tuples(st.sampled_from(KITTI_PLACES), weird_token), min_size=1, max_size=3)
)
def test_kitti_calibration_one_value_wrong(folder, changes):
    entries = {key: list(values) for key, values in GOOD_KITTI.items()}
    for (key, index), token in changes:
        entries[key][index] = token
    text = "".join(f"{key}: {' '.join(values)}\n" for key, values in entries.items())
    value = _parse(_kitti, folder / "calib.txt", text.encode())
    if value is not None:
        camera, parsed = value
        try:
            size = _rectified_size(parsed, "S_rect_02", folder / "calib.txt")
            check_intrinsics(camera.K, size, "calib.txt")
        except InputError:
            pass


@FUZZ
@given(
    lines=st.lists(
        st.one_of(
            st.builds(
                lambda y, mo, d, h, mi, s, f: (
                    f"{y:04d}-{mo:02d}-{d:02d} {h:02d}:{mi:02d}:{s:02d}{f}"
                ),
                st.integers(0, 9999), st.integers(0, 99), st.integers(0, 99),
                st.integers(0, 99), st.integers(0, 99), st.integers(0, 99),
                st.sampled_from(["", ".5", ".964389445", "." + "9" * 400, ".x"]),
            ),
            st.text(max_size=30),
        ),
        max_size=5,
    )
)  # fmt: skip
def test_kitti_timestamps(folder, lines):
    value = _parse(read_timestamps, folder / "timestamps.txt", "\n".join(lines).encode())
    if value is not None:
        assert value.size >= 2 and np.all(np.diff(value) > 0) and np.all(np.isfinite(value))


# --------------------------------------------------------------------------- PFM and FLO


def _check_pfm_flo(folder, data):
    """The full readers and the header-only readers agree on every file."""
    for reader, header_reader, name in (
        (read_pfm, read_pfm_header, "a.pfm"),
        (read_flo, read_flo_header, "a.flo"),
    ):
        value = _parse(reader, folder / name, data)
        header = _parse(header_reader, folder / name, data)
        assert (value is None) == (header is None)
        if value is not None:
            assert value.shape[:2] == (header[1], header[0])
    return value


@FUZZ
@given(data=st.binary(max_size=400))
def test_pfm_and_flo_arbitrary_bytes(folder, data):
    _check_pfm_flo(folder, data)


@FUZZ
@given(
    kind=st.sampled_from([b"Pf", b"PF", b"P5", b"pf"]),
    width=st.one_of(st.integers(-3, 6).map(str), token_text),
    height=st.one_of(st.integers(-3, 6).map(str), token_text),
    scale=st.one_of(st.sampled_from(["-1.0", "1.0", "-0.5"]), token_text),
    separators=st.lists(st.sampled_from([b"\n", b" ", b"\t", b"\r\n", b""]), min_size=4,
                        max_size=4),
    extra=st.sampled_from([0, 0, 0, -4, -1, 1, 4, 400]),
)  # fmt: skip
def test_pfm_structured_headers(folder, kind, width, height, scale, separators, extra):
    header = kind + separators[0]
    for token, sep in zip((width, height, scale), separators[1:], strict=True):
        header += token.encode() + sep
    try:
        count = int(width) * int(height) * (3 if kind == b"PF" else 1)
    except ValueError:
        count = 4
    body = bytes(np.arange(max(0, min(4 * count + extra, 4000)), dtype=np.uint8) % 251)
    value = _parse(read_pfm, folder / "b.pfm", header + body)
    assert (value is None) == (_parse(read_pfm_header, folder / "b.pfm", header + body) is None)
    if value is not None:
        assert value.dtype == np.float32 and value.shape[:2] == (int(height), int(width))


@FUZZ
@given(
    magic=st.sampled_from([202021.25, 202021.0, float("nan")]),
    width=st.integers(-(2**31), 2**31 - 1) | st.integers(-2, 6),
    height=st.integers(-(2**31), 2**31 - 1) | st.integers(-2, 6),
    extra=st.sampled_from([0, 0, 0, -8, -1, 1, 8]),
)
def test_flo_structured_headers(folder, magic, width, height, extra):
    header = struct.pack("<fii", magic, width, height)
    count = max(0, min(width * height * 8 + extra, 4000)) if width > 0 and height > 0 else 8
    value = _parse(read_flo, folder / "b.flo", header + bytes(count))
    assert (value is None) == (
        _parse(read_flo_header, folder / "b.flo", header + bytes(count)) is None
    )
    if value is not None:
        assert value.shape == (height, width, 2) and value.dtype == np.float32


# --------------------------------------------------------------------------- PNG


def _chunk(kind: bytes, data: bytes, *, crc_ok: bool = True) -> bytes:
    crc = zlib.crc32(kind + data) ^ (0 if crc_ok else 1)
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


png_files = st.builds(
    lambda width, height, depth, color, interlace, crc_ok, rows, payload, cut, trailer: (
        PNG_SIGNATURE
        + _chunk(
            b"IHDR", struct.pack(">IIBBBBB", width, height, depth, color, 0, 0, interlace),
            crc_ok=crc_ok,
        )
        + (_chunk(b"PLTE", bytes(range(48))) if color == 3 else b"")
        + _chunk(b"IDAT", zlib.compress(rows if payload is None else payload))
        + trailer
    )[: None if cut == 0 else -cut],
    width=st.integers(0, 40) | st.sampled_from([60000, 2**31 - 1, 2**32 - 1, 2**20 + 1]),
    height=st.integers(0, 40) | st.sampled_from([60000, 2**31 - 1, 2**16]),
    depth=st.sampled_from([1, 2, 4, 8, 16, 3, 0]),
    color=st.sampled_from([0, 2, 3, 4, 6, 1, 7]),
    interlace=st.sampled_from([0, 0, 1, 2]),
    crc_ok=st.booleans() | st.just(True),
    rows=st.binary(max_size=3000),
    payload=st.none() | st.binary(max_size=64),
    cut=st.sampled_from([0, 0, 0, 1, 12, 30]),
    trailer=st.sampled_from(
        [_chunk(b"IEND", b""), b"", _chunk(b"tEXt", b"a\x00b") + _chunk(b"IEND", b"")]
    ),
)  # fmt: skip


def _check_png(folder, data):
    path = folder / "a.png"
    header = _parse(read_png_header, path, data)
    _parse(check_png_file, path, data)
    image = _parse(read_png, path, data)
    mask = _parse(read_mask, path, data)
    if header is not None:
        assert isinstance(header, PngInfo) and header.width > 0 and header.height > 0
    for value in (image, mask):
        if value is not None:
            assert header is not None and value.shape[:2] == (header.height, header.width)
    if image is not None:
        assert image.dtype == np.float32 and math.isfinite(float(image.max()))


@FUZZ
@given(data=st.binary(max_size=300))
def test_png_arbitrary_bytes(folder, data):
    _check_png(folder, data)
    _check_png(folder, PNG_SIGNATURE + data)


@FUZZ
@given(data=png_files)
def test_png_structured_headers_and_chunks(folder, data):
    _check_png(folder, data)


# --------------------------------------------------------------------------- the camera arithmetic

extreme_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e-320, 1e-300, 1e300, 1e308, -1e308, 1.0, 40.0, -4.8]),
)


@FUZZ
@given(
    left=st.lists(extreme_floats, min_size=12, max_size=12),
    right=st.lists(extreme_floats, min_size=12, max_size=12),
    keep=st.lists(st.booleans(), min_size=12, max_size=12),
)
def test_cameras_from_any_projection_matrices(left, right, keep):
    # Mostly a good rig with some entries replaced, so the later checks are reached too.
    good_left, good_right = _good_projection(0.0), _good_projection(-4.8)
    P_left = [float(g) if k else v for g, v, k in zip(good_left, left, keep, strict=True)]
    P_right = [float(g) if k else v for g, v, k in zip(good_right, right, keep, strict=True)]
    try:
        camera = stereo_from_projections(
            np.reshape(P_left, (3, 4)), np.reshape(P_right, (3, 4)), "fuzz"
        )
    except InputError:
        return
    assert np.all(np.isfinite(camera.K)) and math.isfinite(camera.baseline) and camera.baseline > 0
    try:
        check_intrinsics(camera.K, (32, 24), "fuzz")
    except InputError:
        pass


@FUZZ
@given(values=st.lists(extreme_floats, min_size=16, max_size=16), keep=st.lists(st.booleans(),
       min_size=16, max_size=16))  # fmt: skip
def test_cameras_from_any_q_matrix(folder, values, keep):
    good = [float(v) for v in GOOD_MATRICES["Q"][3]]
    Q = [g if k else v for g, v, k in zip(good, values, keep, strict=True)]
    text = (
        "Q: !!opencv-matrix\n  rows: 4\n  cols: 4\n  dt: d\n  data: ["
        + ", ".join(repr(v).replace("nan", ".nan").replace("inf", ".Inf") for v in Q)
        + "]\n"
    )
    _check_calibration(_parse(read_stereo_calibration, folder / "q.yml", text.encode()))
