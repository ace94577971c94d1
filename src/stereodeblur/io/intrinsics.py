"""The one rule for camera intrinsics, whatever file they come from.

``camera.json``, OpenCV YAML / JSON calibrations and KITTI calibration files all
pass through :func:`check_intrinsics` once the image size is known. The ranges
are those a real (rectified pinhole) camera can have, for images of ``W x H``
pixels:

- focal lengths: ``W / 20 <= fx <= 1000 W`` and ``H / 20 <= fy <= 1000 H``
  (a field of view between about 0.06 and 169 degrees along each axis);
- principal point: ``-0.5 W <= cx <= 1.5 W`` and ``-0.5 H <= cy <= 1.5 H``
  (inside the image or at most half an image beyond its border, as rectification
  or cropping can put it);
- skew: ``|s| <= fx`` (image axes at least 45 degrees apart).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

MIN_FOCAL = 1 / 20  # times the image size: a field of view of at most ~169 degrees
MAX_FOCAL = 1000.0  # times the image size: a field of view of at least ~0.06 degrees
PRINCIPAL_MARGIN = 0.5  # times the image size beyond each border


def intrinsics_ranges(width: int, height: int) -> dict[str, tuple[float, float]]:
    """Accepted ``[low, high]`` of fx, fy, cx and cy for images of ``width x height``."""
    return {
        "fx": (MIN_FOCAL * width, MAX_FOCAL * width),
        "fy": (MIN_FOCAL * height, MAX_FOCAL * height),
        "cx": (-PRINCIPAL_MARGIN * width, (1 + PRINCIPAL_MARGIN) * width),
        "cy": (-PRINCIPAL_MARGIN * height, (1 + PRINCIPAL_MARGIN) * height),
    }


def camera_matrix(K, where) -> np.ndarray:
    """``K`` as a float64 ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with positive focal lengths.

    Raises
    ------
    InputError
        Naming ``where`` and what is wrong (shape, a non-finite value, the form, a focal length).
    """
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise InputError(f"{where} must be a 3x3 camera matrix, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise InputError(f"{where} has a value that is not a finite number")
    if not np.allclose(K[2], [0, 0, 1], atol=1e-9) or K[1, 0] != 0:
        raise InputError(
            f"{where} is not a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]], "
            f"got {np.round(K, 6).tolist()}"
        )
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError(f"{where}: focal lengths must be positive, got {K[0, 0]}, {K[1, 1]}")
    return K


def check_intrinsics(K, size: tuple[int, int], where) -> None:
    """Fail unless the 3x3 intrinsics ``K`` fit images of ``size = (width, height)``.

    Parameters
    ----------
    K : array_like
        ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    size : tuple of int
        ``(width, height)`` of the images the camera is used with.
    where : str or Path
        Names the file (and keys) in the message.

    Raises
    ------
    InputError
        Naming the value, the file and the accepted range (module docstring).
    """
    width, height = size
    values = {"fx": K[0][0], "fy": K[1][1], "cx": K[0][2], "cy": K[1][2]}
    for name, (low, high) in intrinsics_ranges(width, height).items():
        value = float(values[name])
        if not low <= value <= high:
            scale = "W" if name in ("fx", "cx") else "H"
            factors = {
                "f": (f"{scale}/{round(1 / MIN_FOCAL)}", f"{MAX_FOCAL:g} {scale}"),
                "c": (f"-{PRINCIPAL_MARGIN:g} {scale}", f"{1 + PRINCIPAL_MARGIN:g} {scale}"),
            }[name[0]]
            raise InputError(
                f"{where}: {name} = {value:.6g} is outside [{factors[0]}, {factors[1]}] = "
                f"[{low:.6g}, {high:.6g}] for {width}x{height} images"
            )
    skew, fx = float(K[0][1]), float(K[0][0])
    if abs(skew) > fx:
        raise InputError(
            f"{where}: skew K[0][1] = {skew:.6g} is outside [-fx, fx] = [-{fx:.6g}, {fx:.6g}]"
        )
