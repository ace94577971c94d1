"""``camera.json``: the stereo camera, frame timing and colour encoding of a scene.

The keys and their meaning are in SCENE_FORMAT.md. :func:`read_camera` validates
every value and raises :class:`~stereodeblur.errors.InputError` with one line
naming the file and the key; the intrinsics' plausibility for the frame size is
checked by the scene that knows that size
(:func:`~stereodeblur.io.intrinsics.check_intrinsics`).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import Exposure, StereoCamera
from .files import atomic_write

FORMAT = "stereo-video/1"
COLORS = ("linear", "srgb")
_CAMERA_KEYS = ("format", "K", "baseline", "frame_rate", "exposure", "color")


def _short(value, limit: int = 60) -> str:
    """One-line, length-limited rendering of a value for error messages."""
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


# --------------------------------------------------------------------------- camera.json


@dataclass(frozen=True)
class CameraInfo:
    """Contents of ``camera.json``: stereo camera, frame timing and colour encoding."""

    camera: StereoCamera
    exposure: Exposure
    color: str = "linear"

    def __post_init__(self):
        if self.color not in COLORS:
            raise InputError(f"color must be 'linear' or 'srgb', got {self.color!r}")


def _number(path, key: str, value) -> float:
    number = math.nan
    if isinstance(value, int | float) and not isinstance(value, bool):
        try:
            number = float(value)
        except OverflowError:  # an integer beyond float range
            pass
    if not math.isfinite(number):
        raise InputError(f"{path}: {key!r} must be a finite number, got {_short(value)}")
    return number


def json_object(text: str, path) -> dict:
    """``text`` parsed as a JSON object; a one-line :class:`InputError` naming ``path`` if not."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}: invalid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})"
        ) from None
    except RecursionError:
        raise InputError(f"{path}: invalid JSON (nested too deeply)") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object, got {type(data).__name__}")
    return data


def read_camera(path: str | os.PathLike) -> CameraInfo:
    """Read and validate ``camera.json`` (the file, or a scene folder holding it)."""
    path = Path(path)
    if path.is_dir() and path.name != "camera.json":
        path = path / "camera.json"
    if path.is_dir():
        raise InputError(f"{path} is a directory, expected a JSON file")
    if not path.is_file():
        raise FileNotFoundError(f"camera file not found: {path}")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {exc}") from exc
    data = json_object(text, path)
    unknown = sorted(set(data) - set(_CAMERA_KEYS))
    if unknown:
        raise InputError(
            f"{path}: unknown key {unknown[0]!r}, expected only {', '.join(_CAMERA_KEYS)}"
        )
    for key in _CAMERA_KEYS[:-1]:
        if key not in data:
            raise InputError(f"{path}: missing key {key!r}")
    if data["format"] != FORMAT:
        raise InputError(f"{path}: 'format' must be {FORMAT!r}, got {_short(data['format'])}")
    K = data["K"]
    if not (
        isinstance(K, list)
        and len(K) == 3
        and all(isinstance(row, list) and len(row) == 3 for row in K)
    ):
        raise InputError(f"{path}: 'K' must be a 3x3 list of numbers, got {_short(K)}")
    K = [[_number(path, f"K[{r}][{c}]", v) for c, v in enumerate(row)] for r, row in enumerate(K)]
    baseline = _number(path, "baseline", data["baseline"])
    frame_rate = _number(path, "frame_rate", data["frame_rate"])
    exposure = _number(path, "exposure", data["exposure"])
    color = data.get("color", "linear")
    if baseline <= 0:
        raise InputError(f"{path}: 'baseline' must be > 0, got {baseline}")
    if frame_rate <= 0:
        raise InputError(f"{path}: 'frame_rate' must be > 0, got {frame_rate}")
    if exposure < 0:
        raise InputError(f"{path}: 'exposure' must be >= 0, got {exposure}")
    if color not in COLORS:
        raise InputError(f"{path}: 'color' must be 'linear' or 'srgb', got {_short(color)}")
    try:
        camera = StereoCamera(np.array(K), baseline)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    try:
        timing = Exposure(frame_rate, exposure)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None
    return CameraInfo(camera, timing, color)


def _camera_json(info: CameraInfo) -> str:
    data = {
        "format": FORMAT,
        "K": [[float(v) for v in row] for row in info.camera.K],
        "baseline": float(info.camera.baseline),
        "frame_rate": float(info.exposure.frame_rate),
        "exposure": float(info.exposure.exposure),
        "color": info.color,
    }
    return json.dumps(data, indent=2) + "\n"


def write_camera(path: str | os.PathLike, info: CameraInfo) -> Path:
    """Write ``info`` to ``camera.json`` at ``path`` (atomically)."""
    if not isinstance(info, CameraInfo):
        raise InputError(f"info must be a CameraInfo, got {type(info).__name__}")
    return atomic_write(path, _camera_json(info).encode("utf-8"))
