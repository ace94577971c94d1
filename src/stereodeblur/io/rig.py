"""Calibration files of unrectified stereo rigs: lens distortion and the pose between cameras.

Accepted files
--------------
- **OpenCV** (what ``cv2.stereoCalibrate`` returns): one FileStorage YAML (or JSON) file with
  ``M1``, ``D1``, ``M2``, ``D2``, ``R`` and ``T`` (OpenCV's stereo sample writes them to
  ``intrinsics.yml`` and ``extrinsics.yml``: merge the two files, or give the folder
  holding both). A file with ``M2`` or ``D2`` and none of the rectified ``P1``, ``P2``
  and ``Q`` describes raw frames; a file with ``P1``/``P2`` or ``Q`` (``extrinsics.yml``
  alone, or everything ``cv2.stereoRectify`` returns) describes frames that are already
  rectified (:mod:`.calibration`). The folder with ``intrinsics.yml`` and
  ``extrinsics.yml`` describes raw frames.
- **ROS** ``camera_info`` (what ``camera_calibration`` writes for a stereo pair): the
  folder holding ``left.yaml`` and ``right.yaml``, each with ``image_width``,
  ``image_height``, ``camera_matrix``, ``distortion_model``, ``distortion_coefficients``,
  ``rectification_matrix`` and ``projection_matrix``. The pose between the cameras comes
  from the last two: ``R = R_rightᵀ R_left`` and ``T = R_rightᵀ (t_right - t_left)`` with
  ``t = K_rect⁻¹ P[:, 3]``.
- **Kalibr** ``camchain.yaml``: ``cam0`` (left) and ``cam1`` (right), each with
  ``camera_model: pinhole``, ``intrinsics: [fu, fv, pu, pv]``, ``distortion_model``
  (``radtan``, ``equidistant`` or ``none``), ``distortion_coeffs`` and ``resolution:
  [width, height]``; ``cam1`` with ``T_cn_cnm1``, the 4x4 transform of points from cam0's
  frame to cam1's.

Conventions
-----------
``R`` and ``T`` map a point from the left camera's frame to the right's,
``X_right = R X_left + T``, as ``cv2.stereoCalibrate`` returns them: a rig with the right
camera on the right has ``T`` close to ``(-baseline, 0, 0)``, in the calibration's units.
Distortion coefficients are OpenCV's: model ``'pinhole'`` with ``(k1, k2, p1, p2[, k3[, k4,
k5, k6[, s1, s2, s3, s4[, tx, ty]]]])`` (radtan, plumb_bob, rational_polynomial) or
``'fisheye'`` with ``(k1, k2, k3, k4)`` (equidistant).

Bad files raise :class:`~stereodeblur.errors.InputError` with one line naming the file and
the key.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .calibration import (
    StereoCalibration,
    _image_size,
    _matrix,
    _read_text,
    _top_level_entries,
    opencv_json_text,
    read_opencv_calibration,
    read_stereo_calibration,
)
from .camera_json import json_object
from .intrinsics import camera_matrix

MODELS = ("pinhole", "fisheye")
PINHOLE_COEFFICIENTS = (4, 5, 8, 12, 14)  # the lengths cv2.undistort accepts
ROTATION_TOLERANCE = 1e-4  # largest |RᵀR - I| entry of a rotation read from a file
_TOP_KEY = re.compile(r"^([A-Za-z_][\w.-]*)\s*:", re.MULTILINE)
_OPENCV_RIG_KEYS = ("M1", "D1", "M2", "D2", "R", "T")
_ROS_FILES = ("left.yaml", "right.yaml")
# Keys of a rectified pair: a file holding any of them describes frames already rectified.
RECTIFIED_KEYS = frozenset({"P1", "P2", "Q"})
_ROS_MODELS = {
    "plumb_bob": "pinhole",
    "rational_polynomial": "pinhole",
    "equidistant": "fisheye",
    "fisheye": "fisheye",
}
_KALIBR_MODELS = {"radtan": "pinhole", "equidistant": "fisheye", "none": "pinhole"}


@dataclass(frozen=True)
class RawCamera:
    """One camera of a raw rig: its intrinsics and lens distortion.

    Attributes
    ----------
    K : ndarray
        3x3 ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    distortion : ndarray
        1-D OpenCV coefficients of the rig's model (module docstring).
    where : str
        The file and key it was read from, for messages.
    """

    K: np.ndarray
    distortion: np.ndarray
    where: str


@dataclass(frozen=True)
class StereoRig:
    """An unrectified stereo rig: two raw cameras and the pose of the right one.

    Attributes
    ----------
    left, right : RawCamera
    rotation : ndarray
        3x3 ``R`` of ``X_right = R X_left + T``.
    translation : ndarray
        ``T``, shape (3,).
    model : str
        ``'pinhole'`` or ``'fisheye'`` (both cameras).
    image_size : tuple of int or None
        ``(width, height)`` the calibration is for, when the file says.
    path : Path
        The file or folder read.
    kind : str
        ``'OpenCV'``, ``'ROS camera_info'`` or ``'Kalibr camchain'``.
    pose_where : str
        The file and key of the pose, for messages.
    """

    left: RawCamera
    right: RawCamera
    rotation: np.ndarray
    translation: np.ndarray
    model: str
    image_size: tuple[int, int] | None
    path: Path
    kind: str
    pose_where: str

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS}, got {self.model!r}")
        if np.shape(self.rotation) != (3, 3) or np.shape(self.translation) != (3,):
            raise ValueError("rotation must be 3x3 and translation of length 3")


# --------------------------------------------------------------------------- values


def _distortion(values, model: str, where: str) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 2 and 1 not in values.shape:
        raise InputError(f"{where} must be one row or column of coefficients, got {values.shape}")
    values = values.ravel()
    lengths = PINHOLE_COEFFICIENTS if model == "pinhole" else (4,)
    if values.size not in lengths:
        expected = ", ".join(map(str, lengths))
        raise InputError(
            f"{where} has {values.size} distortion coefficients, expected {expected} "
            f"for the {model} model"
        )
    if not np.all(np.isfinite(values)):
        raise InputError(f"{where} has a coefficient that is not a finite number")
    return values


def _rotation(R, where: str) -> np.ndarray:
    """A 3x3 rotation (or a rotation vector of 3 values), checked and made orthonormal."""
    import cv2

    R = np.asarray(R, dtype=np.float64)
    if not np.all(np.isfinite(R)):
        raise InputError(f"{where} has a value that is not a finite number")
    if R.size == 3:
        R = cv2.Rodrigues(R.reshape(3, 1))[0]
    if R.shape != (3, 3):
        raise InputError(f"{where} must be a 3x3 rotation matrix, got shape {R.shape}")
    if np.max(np.abs(R.T @ R - np.eye(3))) > ROTATION_TOLERANCE or np.linalg.det(R) <= 0:
        raise InputError(
            f"{where} is not a rotation matrix (orthonormal, determinant +1): "
            f"{np.round(R, 6).tolist()}"
        )
    u, _, vt = np.linalg.svd(R)
    return u @ vt


def _translation(T, where: str) -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    if T.size != 3 or (T.ndim == 2 and 1 not in T.shape):
        raise InputError(f"{where} must be 3 values (3x1), got shape {T.shape}")
    T = T.ravel()
    if not np.all(np.isfinite(T)):
        raise InputError(f"{where} has a value that is not a finite number")
    if not np.any(T):
        raise InputError(f"{where} is zero: both cameras at the same place (baseline 0)")
    return T


# --------------------------------------------------------------------------- OpenCV


def _opencv_rig(found: dict[str, tuple[dict, Path]], path: Path) -> StereoRig:
    """The rig of OpenCV entries; ``found`` maps each key to (entries, file it is in)."""
    for key in _OPENCV_RIG_KEYS:
        if key not in found:
            files = sorted({str(p) for _, p in found.values()})
            raise InputError(
                f"{' + '.join(files)}: missing {key!r}; an unrectified rig needs M1, D1, M2, "
                "D2, R and T as cv2.stereoCalibrate names them"
            )

    def matrix(key):
        entries, file = found[key]
        return _matrix(entries, key, file), f"{file}: {key!r}"

    cameras = []
    for side in "12":
        K, k_where = matrix(f"M{side}")
        D, d_where = matrix(f"D{side}")
        cameras.append(
            RawCamera(camera_matrix(K, k_where), _distortion(D, "pinhole", d_where), k_where)
        )
    R, r_where = matrix("R")
    T, t_where = matrix("T")
    files = {id(entries): (entries, file) for entries, file in found.values()}
    sizes = {_image_size(entries, file) for entries, file in files.values()} - {None}
    if len(sizes) > 1:
        raise InputError(f"{path}: the files state different image sizes {sorted(sizes)}")
    return StereoRig(
        *cameras,
        _rotation(R, r_where),
        _translation(T, t_where),
        "pinhole",
        sizes.pop() if sizes else None,
        path,
        "OpenCV",
        t_where,
    )


def _opencv_folder(folder: Path) -> StereoRig:
    found: dict[str, tuple[dict, Path]] = {}
    for stem in ("intrinsics", "extrinsics"):
        names = [folder / f"{stem}{suffix}" for suffix in (".yml", ".yaml")]
        file = next((name for name in names if name.is_file()), None)
        if file is None:
            raise InputError(f"{folder}: has no {stem}.yml (OpenCV stereo calibration)")
        entries = _top_level_entries(_read_text(file), file)
        for key in entries:
            if key in found and key in _OPENCV_RIG_KEYS:
                raise InputError(
                    f"{folder}: {key!r} is in both {found[key][1].name} and {file.name}"
                )
            found.setdefault(key, (entries, file))
    return _opencv_rig(found, folder)


# --------------------------------------------------------------------------- YAML (ROS, Kalibr)


def _yaml(path: Path) -> dict:
    import yaml

    text = _read_text(path)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "not YAML"
        raise InputError(f"{path}: invalid YAML ({problem}{line})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected YAML keys, got {type(data).__name__}")
    return data


def _get(data: dict, key: str, where: str):
    if key not in data:
        raise InputError(f"{where}: missing {key!r}")
    return data[key]


def _number_array(value, where: str) -> np.ndarray:
    """A (nested) list of numbers as float64; InputError naming ``where`` otherwise."""

    def ok(v):
        if isinstance(v, list):
            return all(ok(x) for x in v)
        return isinstance(v, int | float) and not isinstance(v, bool)

    if not isinstance(value, list) or not ok(value):
        raise InputError(f"{where} must be a list of numbers, got {str(value)[:40]!r}")
    try:
        array = np.array(value, dtype=np.float64)
    except (ValueError, OverflowError):
        raise InputError(f"{where} must be a list of numbers in rows of equal length") from None
    if not np.all(np.isfinite(array)):
        raise InputError(f"{where} has a value that is not a finite number")
    return array


def _ros_matrix(data: dict, key: str, shape, where: str) -> np.ndarray:
    entry = _get(data, key, where)
    at = f"{where}: {key!r}"
    if not isinstance(entry, dict):
        raise InputError(f"{at} must have rows, cols and data")
    values = _number_array(_get(entry, "data", at), f"{at} data").ravel()
    rows, cols = entry.get("rows"), entry.get("cols")
    if shape is None:  # distortion: any length, one row
        return values
    if (rows, cols) != shape or values.size != shape[0] * shape[1]:
        raise InputError(
            f"{at} must be {shape[0]}x{shape[1]}, got rows {rows}, cols {cols} and "
            f"{values.size} values"
        )
    return values.reshape(shape)


def _distortion_model(data: dict, models: dict, where: str) -> tuple[str, str]:
    """The file's ``distortion_model`` and the OpenCV model (``models``) it stands for."""
    name = _get(data, "distortion_model", where)
    if name not in models:
        raise InputError(
            f"{where}: 'distortion_model' {str(name)[:30]!r} is not supported, expected "
            f"{', '.join(models)}"
        )
    return name, models[name]


def _ros_camera(path: Path) -> dict:
    data = _yaml(path)
    where = str(path)
    model = _distortion_model(data, _ROS_MODELS, where)[1]
    size = []
    for key in ("image_width", "image_height"):
        value = _get(data, key, where)
        if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
            raise InputError(f"{where}: {key!r} must be a positive integer, got {value!r}")
        size.append(value)
    K_where = f"{where}: 'camera_matrix'"
    return {
        "camera": RawCamera(
            camera_matrix(_ros_matrix(data, "camera_matrix", (3, 3), where), K_where),
            _distortion(
                _ros_matrix(data, "distortion_coefficients", None, where),
                model,
                f"{where}: 'distortion_coefficients'",
            ),
            K_where,
        ),
        "model": model,
        "size": tuple(size),
        "R": _rotation(
            _ros_matrix(data, "rectification_matrix", (3, 3), where),
            f"{where}: 'rectification_matrix'",
        ),
        "P": _ros_matrix(data, "projection_matrix", (3, 4), where),
    }


def _ros_pair(folder: Path) -> StereoRig:
    left, right = (_ros_camera(folder / name) for name in _ROS_FILES)
    where = f"{folder / 'right.yaml'}: 'projection_matrix'"
    for key, what in (("size", "image size"), ("model", "distortion model")):
        if left[key] != right[key]:
            raise InputError(
                f"{folder}: left.yaml and right.yaml have different {what}s "
                f"({left[key]} and {right[key]})"
            )
    P_left, P_right = left["P"], right["P"]
    K_rect = camera_matrix(P_left[:, :3], f"{folder / 'left.yaml'}: 'projection_matrix'")
    offset = np.linalg.solve(K_rect, P_right[:, 3] - P_left[:, 3])
    if not np.any(np.abs(offset) > 1e-12):
        raise InputError(
            f"{where} has no baseline (P[0][3] = 0): a stereo calibration has the right "
            "camera's -fx * baseline there"
        )
    R = right["R"].T @ left["R"]
    T = right["R"].T @ offset
    return StereoRig(
        left["camera"],
        right["camera"],
        R,
        T,
        left["model"],
        left["size"],
        folder,
        "ROS camera_info",
        where,
    )


def _kalibr_camera(data: dict, name: str, path: Path) -> dict:
    where = f"{path}: {name!r}"
    camera = _get(data, name, str(path))
    if not isinstance(camera, dict):
        raise InputError(f"{where} must hold the camera's keys")
    kind = camera.get("camera_model", "pinhole")
    if kind != "pinhole":
        raise InputError(f"{where}: camera_model {str(kind)[:20]!r} is not supported, only pinhole")
    distortion_model, model = _distortion_model(camera, _KALIBR_MODELS, where)
    values = _number_array(_get(camera, "intrinsics", where), f"{where} intrinsics").ravel()
    if values.size != 4:
        raise InputError(f"{where} intrinsics must be [fu, fv, pu, pv], got {values.size} values")
    fu, fv, pu, pv = values
    K_where = f"{where} intrinsics"
    K = camera_matrix([[fu, 0, pu], [0, fv, pv], [0, 0, 1]], K_where)
    if distortion_model == "none":
        coefficients = np.zeros(4)
    else:
        coefficients = _number_array(
            _get(camera, "distortion_coeffs", where), f"{where} distortion_coeffs"
        )
    distortion = _distortion(coefficients, model, f"{where} distortion_coeffs")
    if model == "pinhole" and distortion.size != 4:
        raise InputError(f"{where} distortion_coeffs: radtan has 4 values [k1, k2, r1, r2]")
    size = _number_array(_get(camera, "resolution", where), f"{where} resolution").ravel()
    if size.size != 2 or np.any(size <= 0) or np.any(size != np.round(size)):
        raise InputError(f"{where} resolution must be [width, height], got {size.tolist()}")
    return {
        "camera": RawCamera(K, distortion, K_where),
        "model": model,
        "size": (int(size[0]), int(size[1])),
        "raw": camera,
    }


def _kalibr(path: Path) -> StereoRig:
    data = _yaml(path)
    left, right = (_kalibr_camera(data, name, path) for name in ("cam0", "cam1"))
    for key, what in (("size", "resolution"), ("model", "distortion model")):
        if left[key] != right[key]:
            raise InputError(
                f"{path}: cam0 and cam1 have different {what}s ({left[key]} and {right[key]})"
            )
    where = f"{path}: 'cam1' T_cn_cnm1"
    transform = _number_array(_get(right["raw"], "T_cn_cnm1", f"{path}: 'cam1'"), where)
    if transform.shape != (4, 4):
        raise InputError(f"{where} must be a 4x4 matrix, got shape {transform.shape}")
    if not np.allclose(transform[3], [0, 0, 0, 1], atol=1e-9):
        raise InputError(f"{where}: the last row must be [0, 0, 0, 1]")
    return StereoRig(
        left["camera"],
        right["camera"],
        _rotation(transform[:3, :3], where),
        _translation(transform[:3, 3], where),
        left["model"],
        left["size"],
        path,
        "Kalibr camchain",
        where,
    )


# --------------------------------------------------------------------------- any calibration


def read_calibration(path: str | os.PathLike) -> StereoCalibration | StereoRig:
    """Read the calibration of a stereo pair: rectified, or a raw rig to rectify.

    Parameters
    ----------
    path : path
        A file (OpenCV YAML or JSON, ``camera.json``, Kalibr ``camchain.yaml``) or a
        folder (ROS ``left.yaml`` and ``right.yaml``; OpenCV ``intrinsics.yml`` and
        ``extrinsics.yml``); see the module docstring.

    Returns
    -------
    StereoCalibration or StereoRig
        A :class:`~stereodeblur.io.calibration.StereoCalibration` for frames already
        rectified, a :class:`StereoRig` for raw frames.
    """
    path = Path(path)
    if path.is_dir():
        if all((path / name).is_file() for name in _ROS_FILES):
            return _ros_pair(path)
        if any((path / f"intrinsics{s}").is_file() for s in (".yml", ".yaml")):
            return _opencv_folder(path)
        raise InputError(
            f"{path} is a folder without left.yaml and right.yaml (ROS camera_info) or "
            "intrinsics.yml and extrinsics.yml (OpenCV): expected a calibration file or one "
            "of these folders"
        )
    text = _read_text(path)
    keys = set(_TOP_KEY.findall(text))
    if {"cam0", "cam1"} <= keys:
        return _kalibr(path)
    if "camera_matrix" in keys and "projection_matrix" in keys:
        raise InputError(
            f"{path} is a ROS camera_info file of one camera: give the folder holding the "
            "pair's left.yaml and right.yaml"
        )
    stripped = text.lstrip()
    if stripped.startswith("{"):
        data = json_object(text, path)
        if "format" in data or "K" in data:
            return read_stereo_calibration(path)
        text = opencv_json_text(data)
    elif stripped.startswith("<"):
        return read_stereo_calibration(path)  # refuses XML in one line
    entries = _top_level_entries(text, path)
    if ("M2" in entries or "D2" in entries) and not RECTIFIED_KEYS & set(entries):
        return _opencv_rig({key: (entries, path) for key in entries}, path)
    return read_opencv_calibration(path, text)
