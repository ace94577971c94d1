"""Stereo calibration files for rectified video pairs: OpenCV YAML and ``camera.json``.

Conventions
-----------
The rectified projection matrices are ``P1 = K [I | t1]`` (left) and
``P2 = K [I | t2]`` (right) as :func:`cv2.stereoRectify` returns them; the
camera centre of view ``i`` is ``-t_i``, so the right camera sits at
``t1 - t2 = (baseline, 0, 0)`` in left-camera coordinates and the baseline is in
the units of the calibration (those of the pattern's square size). ``Q`` is the
4x4 disparity-to-depth matrix of :func:`cv2.stereoRectify`:
``Q = [[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, 1/baseline, 0]]``.
``M1`` (the unrectified intrinsics of the left camera) is read only to check it.

OpenCV files are the YAML that :class:`cv2.FileStorage` writes (``%YAML:1.0`` or
``%YAML 1.2`` header optional); hand-edited files with blank lines, comments,
tabs, Windows line ends, reordered keys or lists broken over lines still parse.
Bad files raise :class:`~stereodeblur.errors.InputError` (or ``FileNotFoundError``)
with one line naming the file and what is wrong.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import StereoCamera
from .camera_json import json_object, read_camera
from .intrinsics import camera_matrix, check_intrinsics

HORIZONTAL_TOLERANCE = 0.02  # |baseline y, z| / baseline x above this: not a horizontal pair
SAME_TOLERANCE = 1e-6  # relative difference allowed between intrinsics that must agree
_KEY_LINE = re.compile(r"^([A-Za-z_][\w.-]*)\s*:(.*)$")
_MATRIX_FIELDS = ("rows", "cols", "dt", "data")
_DTYPES = set("ucswifdh")


@dataclass(frozen=True)
class StereoCalibration:
    """A rectified stereo camera with what a calibration file says about timing.

    Attributes
    ----------
    camera : StereoCamera
    image_size : tuple of int or None
        ``(width, height)`` the calibration is for, when the file says.
    frame_rate, exposure : float or None
        Frames per second and exposure time in seconds, when the file says
        (``camera.json`` does; OpenCV files do not).
    color : str or None
        ``'linear'`` or ``'srgb'`` when the file says.
    path : Path or None
        The file read.
    """

    camera: StereoCamera
    image_size: tuple[int, int] | None = None
    frame_rate: float | None = None
    exposure: float | None = None
    color: str | None = None
    path: Path | None = None


# --------------------------------------------------------------------------- geometry


def _relative_difference(a: float, b: float) -> float:
    a, b = float(a), float(b)  # Python floats: inf on overflow, no numpy warning
    return abs(a - b) / max(abs(a), abs(b), 1e-12)


def _checked_camera(derive, where: str) -> StereoCamera:
    """``derive()`` with float overflow or invalid results and bad cameras as InputError."""
    try:
        with np.errstate(over="raise", divide="raise", invalid="raise", under="ignore"):
            return derive()
    except FloatingPointError:
        raise InputError(f"{where}: numbers out of range for a camera") from None
    except np.linalg.LinAlgError:
        raise InputError(f"{where}: the camera matrix is singular") from None
    except InputError:
        raise
    except ValueError as exc:  # StereoCamera's own checks
        raise InputError(f"{where}: {exc}") from None


def stereo_from_projections(P_left, P_right, where: str) -> StereoCamera:
    """The rectified stereo camera of two 3x4 projection matrices ``K [I | t]``.

    ``where`` names the file and keys in error messages, e.g. ``'calib.txt: P0/P1'``.
    """
    return _checked_camera(lambda: _from_projections(P_left, P_right, where), where)


def _from_projections(P_left, P_right, where: str) -> StereoCamera:
    P_left = np.asarray(P_left, dtype=np.float64)
    P_right = np.asarray(P_right, dtype=np.float64)
    for name, P in (("left", P_left), ("right", P_right)):
        if P.shape != (3, 4) or not np.all(np.isfinite(P)):
            raise InputError(f"{where}: the {name} projection matrix must be a finite 3x4 matrix")
    K, K_right = P_left[:, :3], P_right[:, :3]
    if abs(K[2, 2]) < 1e-12:
        raise InputError(f"{where}: the left projection matrix has P[2][2] = 0")
    scale = K[2, 2]
    K, K_right, P_left, P_right = (m / scale for m in (K, K_right, P_left, P_right))
    camera_matrix(K, f"{where}: the K of the left projection matrix K [I | t]")
    for (r, c), name in {(0, 0): "fx", (1, 1): "fy", (0, 2): "cx", (1, 2): "cy"}.items():
        if _relative_difference(K[r, c], K_right[r, c]) > SAME_TOLERANCE:
            raise InputError(
                f"{where}: the views have different {name} ({K[r, c]:.6g} and "
                f"{K_right[r, c]:.6g}); rectify with a common camera matrix "
                "(cv2.stereoRectify with CALIB_ZERO_DISPARITY)"
            )
    K_inv = np.linalg.inv(K)
    offset = K_inv @ P_left[:, 3] - K_inv @ P_right[:, 3]  # right centre in left coordinates
    baseline = float(offset[0])
    if not np.any(offset):
        raise InputError(f"{where}: both cameras are at the same place (baseline 0)")
    if max(abs(offset[1]), abs(offset[2])) > HORIZONTAL_TOLERANCE * abs(baseline):
        raise InputError(
            f"{where}: the cameras are offset by {np.round(offset, 6).tolist()}, not along x: "
            "only horizontal rectified stereo pairs are supported"
        )
    if baseline < 0:
        raise InputError(
            f"{where}: the right camera is left of the left one (baseline {baseline:.6g}); "
            "are the views swapped?"
        )
    return StereoCamera(K, baseline)


# --------------------------------------------------------------------------- OpenCV YAML


def _strip_comment(line: str) -> str:
    quote = None
    for i, char in enumerate(line):
        if quote:
            if char == quote:
                quote = None
        elif char in "\"'":
            quote = char
        elif char == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i]
    return line


def _top_level_entries(text: str, path: Path) -> dict[str, tuple[str, int]]:
    """Top-level ``key: value`` blocks of an OpenCV YAML file: key -> (text, line number)."""
    entries: dict[str, tuple[str, int]] = {}
    current, lines, start = None, [], 0

    def close():
        if current is not None:
            entries[current] = ("\n".join(lines), start)

    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw).rstrip()
        if not line.strip():
            continue
        if line[0] not in " \t":
            if line.startswith("%") or line.strip() in ("---", "..."):
                continue
            match = _KEY_LINE.match(line)
            if match is None:
                raise InputError(
                    f"{path}, line {number}: expected 'key: value' as written by "
                    f"cv2.FileStorage, got {line.strip()[:40]!r}"
                )
            close()
            current, start = match.group(1), number
            if current in entries:
                raise InputError(
                    f"{path}: key {current!r} appears twice (lines {entries[current][1]} "
                    f"and {number})"
                )
            lines = [match.group(2)]
        elif current is None:
            raise InputError(f"{path}, line {number}: indented text before the first key")
        else:
            lines.append(line)
    close()
    return entries


def _split_top(text: str, separators: str) -> list[str]:
    """Split ``text`` at ``separators`` outside brackets and braces."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        if char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char in separators and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts if p.strip()]


def _numbers(text: str, what: str) -> np.ndarray:
    """Numbers of a bracketed list ``[a, b, ...]`` (commas and/or whitespace)."""
    text = text.strip()
    if not text.startswith("["):
        raise InputError(f"{what} must be a list like [1, 2, 3], got {text[:30]!r}")
    if text.count("[") != text.count("]") or not text.endswith("]"):
        raise InputError(f"{what} is not closed with ']' (truncated file?)")
    values = []
    for token in re.split(r"[\s,]+", text[1:-1].strip()):
        if not token:
            continue
        if token.lower().lstrip("+-") in (".inf", ".nan"):  # how FileStorage writes them
            raise InputError(f"{what}: {token!r} is not a finite number")
        try:
            value = float(token)
        except ValueError:
            raise InputError(f"{what}: {token[:20]!r} is not a number") from None
        if not np.isfinite(value):
            raise InputError(f"{what}: {token!r} is not a finite number")
        values.append(value)
    return np.array(values, dtype=np.float64)


def _matrix(entries, key: str, path: Path) -> np.ndarray:
    """Parse the ``!!opencv-matrix`` entry ``key`` (block or flow style)."""
    text, line = entries[key]
    text = text.strip()
    where = f"{path}: matrix {key!r} (line {line})"
    if not text.startswith("!!opencv-matrix"):
        raise InputError(f"{where} must be an !!opencv-matrix with rows, cols, dt and data")
    body = text[len("!!opencv-matrix") :].strip()
    if body.startswith("{"):
        if not body.endswith("}"):
            raise InputError(f"{where} is not closed with '}}' (truncated file?)")
        body = body[1:-1]
    fields: dict[str, str] = {}
    for item in _split_top(body, ",\n"):
        name, colon, value = item.partition(":")
        name = name.strip()
        if not colon or name not in _MATRIX_FIELDS:
            raise InputError(
                f"{where}: unexpected {item.strip()[:30]!r}, expected rows, cols, dt and data"
            )
        if name in fields:
            raise InputError(f"{where}: {name!r} appears twice")
        fields[name] = value.strip()
    for name in _MATRIX_FIELDS:
        if name not in fields:
            raise InputError(f"{where} has no {name!r}")
    size = {}
    for name in ("rows", "cols"):
        try:
            size[name] = int(fields[name])
        except ValueError:
            size[name] = 0
        if size[name] <= 0:
            raise InputError(f"{where}: {name!r} must be a positive integer, got {fields[name]!r}")
    dtype = fields["dt"].strip("\"'")
    if not dtype or dtype[-1] not in _DTYPES:
        raise InputError(f"{where}: 'dt' must be an OpenCV type letter like d or f, got {dtype!r}")
    data = _numbers(fields["data"], f"{where}: 'data'")
    rows, cols = size["rows"], size["cols"]
    if data.size != rows * cols:
        raise InputError(
            f"{where}: 'data' has {data.size} values, expected rows x cols = "
            f"{rows} x {cols} = {rows * cols}"
        )
    return data.reshape(rows, cols)


def _shaped(entries, key: str, shape: tuple[int, int], path: Path) -> np.ndarray:
    matrix = _matrix(entries, key, path)
    if matrix.shape != shape:
        raise InputError(
            f"{path}: {key!r} must be {shape[0]}x{shape[1]}, "
            f"got {matrix.shape[0]}x{matrix.shape[1]}"
        )
    return matrix


def _image_size(entries, path: Path) -> tuple[int, int] | None:
    """``imageSize: [w, h]`` (or ``image_size``, or ``image_width`` / ``image_height``)."""
    for key in ("imageSize", "image_size"):
        if key in entries:
            if entries[key][0].strip().startswith("!!opencv-matrix"):
                values = _matrix(entries, key, path).ravel()
            else:
                values = _numbers(entries[key][0], f"{path}: {key!r}")
            if values.size != 2 or np.any(values <= 0) or np.any(values != np.round(values)):
                raise InputError(f"{path}: {key!r} must be [width, height], got {entries[key][0]}")
            return int(values[0]), int(values[1])
    if "image_width" in entries and "image_height" in entries:
        try:
            size = int(entries["image_width"][0]), int(entries["image_height"][0])
        except ValueError:
            raise InputError(f"{path}: image_width and image_height must be integers") from None
        if min(size) <= 0:
            raise InputError(f"{path}: image size must be positive, got {size}")
        return size
    return None


def _camera_from_q(Q: np.ndarray, path: Path) -> StereoCamera:
    where = f"{path}: 'Q'"
    return _checked_camera(lambda: _from_q(Q, where), where)


def _from_q(Q: np.ndarray, where: str) -> StereoCamera:
    pattern = np.array([[1, 0], [0, 1], [0, 0], [0, 0]], dtype=np.float64)
    if not np.allclose(Q[:, :2], pattern, atol=1e-9) or Q[0, 2] != 0 or Q[1, 2] != 0 or Q[2, 2]:
        raise InputError(
            f"{where} is not the disparity-to-depth matrix of cv2.stereoRectify "
            "([[1, 0, 0, -cx], [0, 1, 0, -cy], [0, 0, 0, f], [0, 0, -1/Tx, (cx - cx')/Tx]])"
        )
    f, inverse_baseline = Q[2, 3], Q[3, 2]
    if f <= 0:
        raise InputError(f"{where}: focal length Q[2][3] must be positive, got {f}")
    if not inverse_baseline > 0:
        raise InputError(
            f"{where}: Q[3][2] = 1/baseline must be positive, got {inverse_baseline} "
            "(are the views swapped?)"
        )
    if abs(Q[3, 3]) > SAME_TOLERANCE * inverse_baseline * max(f, 1.0):
        raise InputError(
            f"{where}: Q[3][3] = {Q[3, 3]:.6g} means the views have different principal "
            "points; rectify with CALIB_ZERO_DISPARITY"
        )
    K = np.array([[f, 0.0, -Q[0, 3]], [0.0, f, -Q[1, 3]], [0.0, 0.0, 1.0]])
    return StereoCamera(K, 1.0 / inverse_baseline)


def read_opencv_calibration(path: str | os.PathLike, text: str | None = None) -> StereoCalibration:
    """Read a rectified stereo calibration from an OpenCV FileStorage YAML file.

    Uses ``P1`` and ``P2`` (3x4) when present, else ``Q`` (4x4); when both are
    present they must agree. ``M1``, if present, must be 3x3.
    """
    path = Path(path)
    if text is None:
        text = _read_text(path)
    entries = _top_level_entries(text, path)
    if not entries:
        raise InputError(f"{path}: no entries; expected P1, P2 (or Q) as cv2.FileStorage writes")
    if "M1" in entries:
        _shaped(entries, "M1", (3, 3), path)
    have_p = [key for key in ("P1", "P2") if key in entries]
    if len(have_p) == 1:
        missing = "P2" if have_p == ["P1"] else "P1"
        raise InputError(f"{path}: has {have_p[0]!r} but no {missing!r}")
    camera = None
    if have_p:
        P1 = _shaped(entries, "P1", (3, 4), path)
        P2 = _shaped(entries, "P2", (3, 4), path)
        camera = stereo_from_projections(P1, P2, f"{path}: P1/P2")
    if "Q" in entries:
        from_q = _camera_from_q(_shaped(entries, "Q", (4, 4), path), path)
        if camera is None:
            camera = from_q
        else:
            pairs = [
                ("focal length", camera.fx, from_q.fx),
                ("cx", camera.K[0, 2], from_q.K[0, 2]),
                ("cy", camera.K[1, 2], from_q.K[1, 2]),
                ("baseline", camera.baseline, from_q.baseline),
            ]
            for name, a, b in pairs:
                if _relative_difference(a, b) > 1e-4:
                    raise InputError(
                        f"{path}: P1/P2 and Q disagree on the {name} ({a:.6g} and {b:.6g})"
                    )
    if camera is None:
        found = ", ".join(sorted(entries)[:8])
        raise InputError(
            f"{path}: no rectified projection matrices: expected P1 and P2 (or Q) as "
            f"cv2.stereoRectify names them, found {found}"
        )
    return StereoCalibration(camera, image_size=_image_size(entries, path), path=path)


# --------------------------------------------------------------------------- any file


def _read_text(path: Path) -> str:
    if not path.is_file():
        raise FileNotFoundError(f"calibration file not found: {path}")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file (expected YAML or JSON)") from None
    if "\x00" in text:
        raise InputError(f"{path}: not a text file (expected YAML or JSON)")
    if not text.strip():
        raise InputError(f"{path}: the calibration file is empty")
    return text


def opencv_json_text(data: dict) -> str:
    """An OpenCV FileStorage JSON object as the YAML text FileStorage would write."""
    lines = []
    for key, value in data.items():
        if isinstance(value, dict) and value.get("type_id") == "opencv-matrix":
            fields = {k: v for k, v in value.items() if k != "type_id"}
            lines.append(f"{key}: !!opencv-matrix")
            lines.extend(f"  {k}: {json.dumps(v)}" for k, v in fields.items())
        elif isinstance(value, list | int | float) and not isinstance(value, bool):
            lines.append(f"{key}: {json.dumps(value)}")
    return "\n".join(lines) + "\n"


def read_stereo_calibration(path: str | os.PathLike) -> StereoCalibration:
    """Read a stereo calibration: OpenCV FileStorage YAML (or JSON), or our ``camera.json``.

    A JSON object with a ``"format"`` key is read as ``camera.json`` (SCENE_FORMAT.md),
    which also gives frame rate, exposure and colour (``color`` None when it has no
    ``"color"`` key: the source's own default applies).
    """
    path = Path(path)
    text = _read_text(path)
    stripped = text.lstrip()
    if stripped.startswith("<"):
        raise InputError(f"{path}: XML calibration files are not supported; save it as YAML")
    if stripped.startswith("{"):
        data = json_object(text, path)
        if "format" in data or "K" in data:
            info = read_camera(path)
            return StereoCalibration(
                info.camera,
                frame_rate=info.exposure.frame_rate,
                exposure=info.exposure.exposure,
                color=info.color if "color" in data else None,
                path=path,
            )
        return read_opencv_calibration(path, opencv_json_text(data))
    return read_opencv_calibration(path, text)


def check_image_size(calibration: StereoCalibration, size: tuple[int, int], what: str) -> None:
    """Fail unless images of ``size = (width, height)`` fit the calibration.

    The calibration's own image size, when it states one, must match, and the
    intrinsics must be those of a real camera for that size
    (:func:`~stereodeblur.io.intrinsics.check_intrinsics`).
    """
    width, height = size
    where = calibration.path or "calibration"
    if calibration.image_size is not None and tuple(calibration.image_size) != (width, height):
        cw, ch = calibration.image_size
        raise InputError(f"{where} is for {cw}x{ch} images but {what} is {width}x{height}")
    check_intrinsics(calibration.camera.K, (width, height), where)
