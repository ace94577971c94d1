"""A synthetic unrectified stereo rig, its calibration in each accepted format, and raw frames
made from rectified renders."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from tests.io.stereo_layouts import write_opencv_yaml


@dataclass(frozen=True)
class SyntheticRig:
    """Two distorted cameras, the right one turned by about a degree, and their rectification."""

    size: tuple[int, int]
    K1: np.ndarray
    D1: np.ndarray
    K2: np.ndarray
    D2: np.ndarray
    R: np.ndarray
    T: np.ndarray
    R1: np.ndarray
    R2: np.ndarray
    P1: np.ndarray
    P2: np.ndarray

    @property
    def rectified_K(self) -> np.ndarray:
        return self.P1[:, :3]

    @property
    def rectified_baseline(self) -> float:
        return float(-self.P2[0, 3] / self.P2[0, 0])


def make_rig(
    size=(128, 96),
    *,
    focal_per_width=0.8,
    baseline=0.12,
    distortion=(-0.12, 0.03),
    degrees=(0.4, 1.0, 0.3),
) -> SyntheticRig:
    """A rig with radial distortion ``(k1, k2)`` (the right camera's a little different), a
    rotation of the right camera by ``degrees`` about x, y, z, and OpenCV's rectification."""
    width, height = size
    f = focal_per_width * width
    K1 = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])
    K2 = K1 + np.array([[0.01 * f, 0.0, 1.0], [0.0, 0.01 * f, -0.7], [0.0, 0.0, 0.0]])
    k1, k2 = distortion
    D1 = np.array([k1, k2, 0.0, 0.0, 0.0])
    D2 = np.array([0.8 * k1, 0.7 * k2, 5e-4, -4e-4, 0.0])
    R = cv2.Rodrigues(np.deg2rad(np.asarray(degrees, dtype=np.float64)).reshape(3, 1))[0]
    T = np.array([-baseline, 0.002, 0.001])
    R1, R2, P1, P2, *_ = cv2.stereoRectify(
        K1, D1, K2, D2, size, R, T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY, alpha=0
    )
    return SyntheticRig(size, K1, D1, K2, D2, R, T, R1, R2, P1, P2)


# --------------------------------------------------------------------------- formats


def write_opencv_rig(path, rig: SyntheticRig, *, image_size=True) -> Path:
    """One FileStorage YAML with M1, D1, M2, D2, R, T (and imageSize)."""
    entries = {"M1": rig.K1, "D1": rig.D1[None], "M2": rig.K2, "D2": rig.D2[None]}
    entries.update({"R": rig.R, "T": rig.T[:, None]})
    if image_size:
        entries["imageSize"] = rig.size
    return write_opencv_yaml(path, entries)


def write_opencv_folder(folder, rig: SyntheticRig) -> Path:
    """OpenCV's stereo sample's ``intrinsics.yml`` and ``extrinsics.yml`` (with the rectified
    R1, R2, P1, P2 that the sample writes too)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    intrinsics = {"M1": rig.K1, "D1": rig.D1[None], "M2": rig.K2, "D2": rig.D2[None]}
    write_opencv_yaml(folder / "intrinsics.yml", intrinsics)
    extrinsics = {"R": rig.R, "T": rig.T[:, None], "R1": rig.R1, "R2": rig.R2}
    extrinsics.update({"P1": rig.P1, "P2": rig.P2})
    write_opencv_yaml(folder / "extrinsics.yml", extrinsics)
    return folder


def _ros_matrix(name: str, matrix: np.ndarray) -> str:
    matrix = np.atleast_2d(matrix)
    data = ", ".join(f"{v:.17g}" for v in matrix.ravel())
    rows, cols = matrix.shape
    return f"{name}:\n  rows: {rows}\n  cols: {cols}\n  data: [{data}]\n"


def ros_camera_info(rig: SyntheticRig, view: str) -> str:
    """A ROS ``camera_info`` YAML as ``camera_calibration`` writes it."""
    K, D, R, P = (
        (rig.K1, rig.D1, rig.R1, rig.P1) if view == "left" else (rig.K2, rig.D2, rig.R2, rig.P2)
    )
    width, height = rig.size
    return (
        f"image_width: {width}\nimage_height: {height}\ncamera_name: narrow_stereo/{view}\n"
        + _ros_matrix("camera_matrix", K)
        + "distortion_model: plumb_bob\n"
        + _ros_matrix("distortion_coefficients", D)
        + _ros_matrix("rectification_matrix", R)
        + _ros_matrix("projection_matrix", P)
    )


def write_ros_folder(folder, rig: SyntheticRig) -> Path:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for view in ("left", "right"):
        (folder / f"{view}.yaml").write_text(ros_camera_info(rig, view))
    return folder


def kalibr_text(rig: SyntheticRig) -> str:
    """A Kalibr ``camchain.yaml`` (radtan: the first four coefficients)."""
    transform = np.eye(4)
    transform[:3, :3], transform[:3, 3] = rig.R, rig.T

    def numbers(values):
        return "[" + ", ".join(f"{v:.17g}" for v in values) + "]"

    lines = []
    for name, K, D in (("cam0", rig.K1, rig.D1), ("cam1", rig.K2, rig.D2)):
        lines += [f"{name}:"]
        if name == "cam1":
            lines += ["  T_cn_cnm1:"] + [f"  - {numbers(row)}" for row in transform]
        lines += [
            "  cam_overlaps: [1]" if name == "cam0" else "  cam_overlaps: [0]",
            "  camera_model: pinhole",
            f"  distortion_coeffs: {numbers(D[:4])}",
            "  distortion_model: radtan",
            f"  intrinsics: {numbers([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])}",
            f"  resolution: [{rig.size[0]}, {rig.size[1]}]",
            f"  rostopic: /{name}/image_raw",
        ]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- rendering


def _shifted(K: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``K`` of the same camera with pixel ``(u, v)`` renamed ``(u - dx, v - dy)``."""
    shifted = K.copy()
    shifted[0, 2] -= dx
    shifted[1, 2] -= dy
    return shifted


def raw_from_fine(rig: SyntheticRig, view: str, fine: np.ndarray, scale: int) -> np.ndarray:
    """The raw camera's frame, each pixel the mean over its area of a rectified render
    ``fine`` made at ``scale`` times the resolution (pixel centres at integers)."""
    K, D, R, P = (
        (rig.K1, rig.D1, rig.R1, rig.P1) if view == "left" else (rig.K2, rig.D2, rig.R2, rig.P2)
    )
    offsets = (np.arange(scale) + 0.5) / scale - 0.5
    total = 0.0
    for dy in offsets:
        for dx in offsets:
            map_x, map_y = cv2.initInverseRectificationMap(
                _shifted(K, dx, dy), D, R, P, rig.size, cv2.CV_32FC1
            )
            fine_x = scale * map_x + (scale - 1) / 2  # rectified pixel -> fine pixel
            fine_y = scale * map_y + (scale - 1) / 2
            total = total + cv2.remap(
                np.ascontiguousarray(fine, dtype=np.float32),
                fine_x.astype(np.float32),
                fine_y.astype(np.float32),
                interpolation=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            )
    return (total / scale**2).astype(np.float32)


def fine_camera(K: np.ndarray, scale: int) -> np.ndarray:
    """``K`` for images ``scale`` times larger, pixel centres staying at integers."""
    fine = K * np.array([[scale], [scale], [1.0]])
    fine[:2, 2] += (scale - 1) / 2
    return fine


def area_mean(image: np.ndarray, scale: int) -> np.ndarray:
    """Means over ``scale x scale`` blocks."""
    height, width = image.shape[0] // scale, image.shape[1] // scale
    blocks = image[: height * scale, : width * scale].reshape(
        height, scale, width, scale, *image.shape[2:]
    )
    return blocks.mean(axis=(1, 3)).astype(np.float32)
