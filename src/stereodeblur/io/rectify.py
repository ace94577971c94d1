"""Rectification of an unrectified stereo rig's frames, computed once and applied on reading.

:func:`rectify_rig` computes the rectification of a :class:`~stereodeblur.io.rig.StereoRig`
for its frame size once per source: ``cv2.stereoRectify`` (``cv2.fisheye.stereoRectify``
for the fisheye model) with ``alpha = 0`` (``balance = 0``: every rectified pixel sees
the scene, none is black) and ``CALIB_ZERO_DISPARITY`` (both views share one camera
matrix, so a point at infinity has disparity 0), then a pair of maps per view
(``cv2.initUndistortRectifyMap``). The rectified frames have the raw frames' size.
:func:`rectify_view` remaps one frame with bicubic interpolation: bilinear interpolation
softens a frame about as much as a blur, which the deblurring then cannot undo
(``tests/io/test_rectify_end_to_end.py`` compares the results). Callers pass values in
linear light (interpolating encoded values would darken edges).

The rectified camera follows :mod:`~stereodeblur.io.calibration`'s conventions: the right
rectified camera sits at ``(baseline, 0, 0)`` in the left rectified camera's frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS
from .calibration import StereoCalibration, check_image_size, stereo_from_projections
from .intrinsics import check_intrinsics
from .rig import StereoRig

MAX_OUTSIDE = 0.01  # largest share of rectified pixels whose raw position is off the frame


@dataclass(frozen=True)
class Rectification:
    """The rectification of a raw rig for one frame size.

    Attributes
    ----------
    calibration : StereoCalibration
        The rectified camera, the frame size and the raw calibration's path.
    maps : dict of str to tuple of ndarray
        Per view, ``(map_x, map_y)`` float32 (H, W): the raw pixel each rectified pixel
        samples.
    rotations : dict of str to ndarray
        Per view, the 3x3 rotation from the raw camera's frame to the rectified one.
    kind : str
        The raw calibration's kind (``'OpenCV'``, ``'ROS camera_info'``, ``'Kalibr camchain'``).
    """

    calibration: StereoCalibration
    maps: dict
    rotations: dict
    kind: str


def _stereo_rectify(rig: StereoRig, size: tuple[int, int]):
    """``R1, R2, P1, P2`` of OpenCV's rectification of ``rig`` at ``size``."""
    import cv2

    K1, K2 = rig.left.K, rig.right.K
    R, T = rig.rotation, rig.translation.reshape(3, 1)
    if rig.model == "fisheye":
        D1, D2 = (c.distortion.reshape(4, 1) for c in (rig.left, rig.right))
        R1, R2, P1, P2, _ = cv2.fisheye.stereoRectify(
            K1, D1, K2, D2, size, R, T, cv2.CALIB_ZERO_DISPARITY,
            newImageSize=size, balance=0.0, fov_scale=1.0,
        )  # fmt: skip
    else:
        D1, D2 = rig.left.distortion, rig.right.distortion
        R1, R2, P1, P2, *_ = cv2.stereoRectify(
            K1, D1, K2, D2, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=0
        )
    return R1, R2, P1, P2


def _maps(rig: StereoRig, camera, rotation, projection, size) -> tuple[np.ndarray, np.ndarray]:
    import cv2

    if rig.model == "fisheye":
        map_x, map_y = cv2.fisheye.initUndistortRectifyMap(
            camera.K, camera.distortion.reshape(4, 1), rotation, projection, size, cv2.CV_32FC1
        )
    else:
        map_x, map_y = cv2.initUndistortRectifyMap(
            camera.K, camera.distortion, rotation, projection, size, cv2.CV_32FC1
        )
    width, height = size
    inside = (
        np.isfinite(map_x)
        & np.isfinite(map_y)
        & (map_x >= -0.5)
        & (map_x <= width - 0.5)
        & (map_y >= -0.5)
        & (map_y <= height - 0.5)
    )
    if np.mean(~inside) > MAX_OUTSIDE:
        raise InputError(
            f"{camera.where} with its distortion coefficients: {np.mean(~inside):.0%} of the "
            "rectified frame falls outside the raw frame; the distortion is not one a "
            "rectification can undo"
        )
    return map_x, map_y


def rectify_rig(rig: StereoRig, size: tuple[int, int], what: str) -> Rectification:
    """The rectification of ``rig`` for frames of ``size = (width, height)``.

    ``what`` names the frames in messages, e.g. ``'video left.mkv'``.

    Raises
    ------
    InputError
        Naming the file and key: frames of another size than the calibration's,
        intrinsics that do not fit the frames, a rig whose rectified baseline is not
        horizontal (or has the views swapped), distortion that no rectification undoes.
    """
    import cv2

    width, height = size
    if rig.image_size is not None and tuple(rig.image_size) != (width, height):
        cw, ch = rig.image_size
        raise InputError(f"{rig.path} is for {cw}x{ch} images but {what} is {width}x{height}")
    for camera in (rig.left, rig.right):
        check_intrinsics(camera.K, size, camera.where)
    try:
        R1, R2, P1, P2 = _stereo_rectify(rig, (width, height))
    except cv2.error as exc:
        reason = (exc.err or str(exc)).strip().splitlines()[0][:80]
        raise InputError(f"{rig.path}: OpenCV cannot rectify this rig ({reason})") from None
    where = f"{rig.pose_where} (the rig rectified)"
    if not (np.all(np.isfinite(P1)) and np.all(np.isfinite(P2))):
        raise InputError(f"{where}: the rectified projections are not finite")
    camera = stereo_from_projections(P1, P2, where)
    calibration = StereoCalibration(camera, image_size=(width, height), path=rig.path)
    check_image_size(calibration, size, what)
    rotations = {"left": R1, "right": R2}
    projections = {"left": P1, "right": P2}
    cameras = {"left": rig.left, "right": rig.right}
    maps = {
        view: _maps(rig, cameras[view], rotations[view], projections[view], (width, height))
        for view in VIEWS
    }
    return Rectification(calibration, maps, rotations, rig.kind)


def rectify_view(rectification: Rectification, view: str, image: np.ndarray) -> np.ndarray:
    """Frame ``image`` (H, W) or (H, W, C) of ``view``, raw, as the rectified frame.

    Bicubic interpolation, clipped to [0, 1] (values in [0, 1] in); a rectified pixel whose
    raw position is just off the frame takes the nearest border value. Keeps the dtype
    (float32 in, float32 out).
    """
    import cv2

    map_x, map_y = rectification.maps[view]
    if image.shape[:2] != map_x.shape:
        raise InputError(
            f"the {view} frame is {image.shape[1]}x{image.shape[0]} but the rectification is "
            f"for {map_x.shape[1]}x{map_x.shape[0]}"
        )
    rectified = cv2.remap(
        np.ascontiguousarray(image),
        map_x,
        map_y,
        interpolation=cv2.INTER_CUBIC,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return np.clip(rectified, 0.0, 1.0, out=rectified)
