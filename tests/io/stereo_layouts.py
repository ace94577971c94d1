"""Write one stereo clip in the layouts of other sources: KITTI 2015 / 2012 / raw, video pairs.

Every writer takes 8-bit frames, so each layout stores exactly the same values.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from stereodeblur.io.formats import write_png
from stereodeblur.io.video import write_video

# Where KITTI's rectified colour camera 2 sits relative to camera 0 (KITTI-like, nonzero y, z).
CAMERA_2_OFFSET = np.array([0.06, 0.001, 0.002])


def to_u8(frame: np.ndarray) -> np.ndarray:
    return np.rint(np.clip(frame, 0, 1) * 255).astype(np.uint8)


def _numbers(values) -> str:
    return " ".join(f"{v:.17g}" for v in np.ravel(values))


def projection(K: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``K [I | t]``, KITTI's rectified projection matrix of a camera at ``-t``."""
    return K @ np.hstack([np.eye(3), np.reshape(t, (3, 1))])


def kitti_projections(K, baseline):
    """Left and right projection matrices of a KITTI-like rig (left camera offset from 0)."""
    t_left = CAMERA_2_OFFSET
    t_right = t_left - np.array([baseline, 0.0, 0.0])
    return projection(K, t_left), projection(K, t_right)


def cam_to_cam_text(K, baseline, size) -> str:
    """A KITTI ``calib_cam_to_cam.txt`` with cameras 0-3 (rectified 2 and 3 form the pair)."""
    P2, P3 = kitti_projections(K, baseline)
    P0 = projection(K, np.zeros(3))
    P1 = projection(K, np.array([-0.54, 0.0, 0.0]))
    lines = ["calib_time: 09-Jan-2012 13:57:47", "corner_dist: 9.950000e-02"]
    for cam, P in zip(("00", "01", "02", "03"), (P0, P1, P2, P3), strict=True):
        lines += [
            f"S_{cam}: 1.392000e+03 5.120000e+02",
            f"K_{cam}: {_numbers(K)}",
            f"D_{cam}: 0 0 0 0 0",
            f"R_{cam}: {_numbers(np.eye(3))}",
            f"T_{cam}: 0 0 0",
            f"S_rect_{cam}: {size[0]:.6e} {size[1]:.6e}",
            f"R_rect_{cam}: {_numbers(np.eye(3))}",
            f"P_rect_{cam}: {_numbers(P)}",
        ]
    return "\n".join(lines) + "\n"


def write_kitti_2015(root, left, right, K, baseline, *, sequence=0, first=10) -> Path:
    """``image_2/``, ``image_3/`` as ``NNNNNN_XX.png`` from ``first``, ``calib_cam_to_cam/``."""
    root = Path(root)
    for k, (a, b) in enumerate(zip(left, right, strict=True)):
        write_png(
            root / "image_2" / f"{sequence:06d}_{first + k:02d}.png", to_u8(a) / 255, bit_depth=8
        )
        write_png(
            root / "image_3" / f"{sequence:06d}_{first + k:02d}.png", to_u8(b) / 255, bit_depth=8
        )
    size = (left[0].shape[1], left[0].shape[0])
    calib = root / "calib_cam_to_cam" / f"{sequence:06d}.txt"
    calib.parent.mkdir(parents=True, exist_ok=True)
    calib.write_text(cam_to_cam_text(K, baseline, size))
    return root


def write_kitti_2012(root, left, right, K, baseline, *, sequence=0, first=10) -> Path:
    """Grey ``image_0/``, ``image_1/`` (P0, P1) and ``calib/NNNNNN.txt`` with P0-P3 and Tr."""
    root = Path(root)
    for k, (a, b) in enumerate(zip(left, right, strict=True)):
        write_png(root / "image_0" / f"{sequence:06d}_{first + k:02d}.png", a, bit_depth=8)
        write_png(root / "image_1" / f"{sequence:06d}_{first + k:02d}.png", b, bit_depth=8)
    P0, P1 = projection(K, np.zeros(3)), projection(K, np.array([-baseline, 0.0, 0.0]))
    P2, P3 = kitti_projections(K, baseline)
    text = "".join(f"P{i}: {_numbers(P)}\n" for i, P in enumerate((P0, P1, P2, P3)))
    text += f"Tr: {_numbers(np.eye(3, 4))}\n"
    calib = root / "calib" / f"{sequence:06d}.txt"
    calib.parent.mkdir(parents=True, exist_ok=True)
    calib.write_text(text)
    return root


def write_kitti_raw(date_root, left, right, K, baseline, *, frame_rate=20.0) -> Path:
    """``DATE/DATE_drive_0001_sync/image_02|03/data/NNNNNNNNNN.png`` with timestamps and
    ``DATE/calib_cam_to_cam.txt``; returns the drive folder."""
    date_root = Path(date_root)
    drive = date_root / f"{date_root.name}_drive_0001_sync"
    for view, frames in (("image_02", left), ("image_03", right)):
        for k, frame in enumerate(frames):
            write_png(drive / view / "data" / f"{k:010d}.png", to_u8(frame) / 255, bit_depth=8)
        stamps = [f"2011-09-26 13:02:{25 + k / frame_rate:012.9f}" for k in range(len(frames))]
        (drive / view / "timestamps.txt").write_text("\n".join(stamps) + "\n")
    size = (left[0].shape[1], left[0].shape[0])
    (date_root / "calib_cam_to_cam.txt").write_text(cam_to_cam_text(K, baseline, size))
    return drive


def opencv_calibration(K, baseline, size) -> dict:
    """M1, D1, P1, P2, Q as cv2.stereoRectify returns them for an already rectified rig."""
    P1 = np.hstack([K, np.zeros((3, 1))])
    P2 = P1.copy()
    P2[0, 3] = -K[0, 0] * baseline
    Q = np.array(
        [
            [1, 0, 0, -K[0, 2]],
            [0, 1, 0, -K[1, 2]],
            [0, 0, 0, K[0, 0]],
            [0, 0, 1 / baseline, 0],
        ]
    )
    return {"M1": K, "D1": np.zeros((1, 5)), "P1": P1, "P2": P2, "Q": Q, "imageSize": size}


def write_opencv_yaml(path, entries: dict) -> Path:
    """Write ``entries`` with cv2.FileStorage (matrices, and size tuples)."""
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, value in entries.items():
        if isinstance(value, tuple):
            storage.write(key, np.array(value, dtype=np.float64).reshape(-1, 1))
        else:
            storage.write(key, np.asarray(value, dtype=np.float64))
    storage.release()
    return Path(path)


def write_video_pair(folder, left, right, K, baseline, *, frame_rate=20.0, codec="FFV1"):
    """``left.mkv``, ``right.mkv`` (lossless FFV1) and ``calib.yml``; returns the three paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = (
        write_video(
            folder / "left.mkv", [to_u8(f) for f in left], frame_rate=frame_rate, codec=codec
        ),
        write_video(
            folder / "right.mkv", [to_u8(f) for f in right], frame_rate=frame_rate, codec=codec
        ),
    )
    size = (left[0].shape[1], left[0].shape[0])
    calib = write_opencv_yaml(folder / "calib.yml", opencv_calibration(K, baseline, size))
    return (*paths, calib)
