"""A pair of video files (left, right) as a stereo clip, read frame by frame.

Frames are decoded on demand with :class:`cv2.VideoCapture` (FFmpeg): reading the
next frame is sequential decoding; any other frame is a seek. At most a few
recent frames per view stay in memory. Frame ``i`` of both videos is taken to be
exposed at the same instant. The frame rate comes from the container (or
``frame_rate``); the camera from a calibration file
(:mod:`stereodeblur.io.calibration`), or, for the videos of an unrectified rig, from the
rectification of its calibration (:mod:`stereodeblur.io.rig`, :mod:`stereodeblur.io.rectify`):
frames are then rectified on reading. The values are camera output, sRGB-encoded
(:data:`~stereodeblur.io.frame_source.CAMERA_OUTPUT_COLOR`) unless the calibration (a
``camera.json`` with ``"color"``) or ``color`` says otherwise: frames are linearised on reading.

Lossless encodings that OpenCV writes and reads back bit-exactly (8-bit RGB):
FFV1 (``.mkv``, ``.avi``), PNG (fourcc ``'png '``) and HuffYUV (``'HFYU'``).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from .calibration import check_image_size
from .files import quiet_stderr
from .frame_source import CAMERA_OUTPUT_COLOR, FrameSource, camera_info
from .rectify import rectify_rig
from .rig import StereoRig, read_calibration
from .scene import check_frame_size

CACHE_FRAMES = 4  # decoded frames kept per view


# File signatures of still-image formats FFmpeg would open as a one-frame "video".
_IMAGE_SIGNATURES = {
    b"\x89PNG\r\n\x1a\n": "PNG",
    b"\xff\xd8\xff": "JPEG",
    b"BM": "BMP",
    b"II*\x00": "TIFF",
    b"MM\x00*": "TIFF",
    b"GIF87a": "GIF",
    b"GIF89a": "GIF",
    b"P5": "PGM",
    b"P6": "PPM",
    b"PF": "PFM",
    b"Pf": "PFM",
}


def _check_not_image(path: Path) -> None:
    try:
        with open(path, "rb") as handle:
            head = handle.read(16)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        kind = "WebP"
    else:
        kind = next((k for sig, k in _IMAGE_SIGNATURES.items() if head.startswith(sig)), None)
    if kind is not None:
        raise InputError(f"{path} is a still image ({kind}), not a video: expected a video file")


def _capture(path: Path) -> cv2.VideoCapture:
    _check_not_image(path)
    with quiet_stderr():
        capture = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    if not capture.isOpened():
        raise InputError(
            f"{path} is not a readable video (unknown container or codec, or not a video)"
        )
    return capture


def _count_frames(capture: cv2.VideoCapture, first_read: bool) -> int:
    """Frames in the container's index, else counted by decoding to the end."""
    count = capture.get(cv2.CAP_PROP_FRAME_COUNT)
    if math.isfinite(count) and count > 0:
        return int(count)
    count = int(first_read)
    with quiet_stderr():
        while capture.grab():
            count += 1
    return count


def video_frame_count(path) -> int:
    """Number of frames of the video at ``path`` (opening it, decoding only if needed)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"video file not found: {path}")
    capture = _capture(path)
    try:
        return _count_frames(capture, False)
    finally:
        capture.release()


def _to_float(frame: np.ndarray, path: Path) -> np.ndarray:
    if frame.dtype == np.uint8:
        scale = 255.0
    elif frame.dtype == np.uint16:
        scale = 65535.0
    else:
        raise InputError(f"{path}: unsupported pixel type {frame.dtype}")
    if frame.ndim == 3:
        frame = frame[..., 2::-1]  # BGR(A) -> RGB
    return (frame.astype(np.float32) / np.float32(scale)).copy()


class VideoSource(FrameSource):
    """Two video files opened lazily (per process) and decoded frame by frame."""

    kind = "video"

    def __init__(
        self,
        left,
        right,
        *,
        info,
        num_frames,
        shape,
        calibration,
        warnings=(),
        rectification=None,
    ):
        self.files = {"left": Path(left), "right": Path(right)}
        self.calibration = calibration
        self._captures: dict[str, cv2.VideoCapture] = {}
        self._next: dict[str, int] = {}
        self._cache: dict[str, OrderedDict] = {"left": OrderedDict(), "right": OrderedDict()}
        paths = [self.files["left"], self.files["right"]]
        if calibration.path is not None:
            paths.append(calibration.path)
        super().__init__(
            root=self.files["left"],
            name=f"{self.files['left'].name} + {self.files['right'].name}",
            paths=paths,
            info=info,
            num_frames=num_frames,
            shape=shape,
            channels=3,
            warnings=warnings,
            rectification=rectification,
        )

    def frame_label(self, view: str, index: int) -> str:
        return f"{self.files[view]} frame {index}"

    def close(self) -> None:
        """Release the decoders (they reopen on the next read)."""
        for capture in self._captures.values():
            capture.release()
        self._captures.clear()
        self._next.clear()

    def __del__(self):
        self.close()

    def _decode(self, view: str, index: int) -> np.ndarray:
        path = self.files[view]
        capture = self._captures.get(view)
        if capture is None:
            capture = self._captures[view] = _capture(path)
            self._next[view] = 0
        with quiet_stderr():
            if self._next[view] != index:
                capture.set(cv2.CAP_PROP_POS_FRAMES, index)
                if int(round(capture.get(cv2.CAP_PROP_POS_FRAMES))) != index:
                    # Inexact seek: decode from the start instead.
                    capture.release()
                    capture = self._captures[view] = _capture(path)
                    for _ in range(index):
                        if not capture.grab():
                            break
            ok, frame = capture.read()
        if not ok or frame is None:
            self._next[view] = -1
            raise InputError(
                f"cannot read frame {index} of {path} (the file says it has "
                f"{self.num_frames} frames; truncated or corrupt?)"
            )
        self._next[view] = index + 1
        return _to_float(frame, path)

    def _read_stored(self, view: str, index: int) -> np.ndarray:
        cache = self._cache[view]
        if index in cache:
            cache.move_to_end(index)
            return cache[index].copy()
        frame = self._decode(view, index)
        cache[index] = frame
        while len(cache) > CACHE_FRAMES:
            cache.popitem(last=False)
        return frame.copy()


def _probe(path: Path) -> dict:
    """Size, frame count and frame rate of a video; reads its first frame to check it."""
    if not path.is_file():
        raise FileNotFoundError(f"video file not found: {path}")
    capture = _capture(path)
    try:
        with quiet_stderr():
            ok, frame = capture.read()
        if not ok or frame is None:
            raise InputError(f"{path} is not a readable video: cannot decode its first frame")
        count = _count_frames(capture, True)
        fps = capture.get(cv2.CAP_PROP_FPS)
    finally:
        capture.release()
    if count < 2:
        raise InputError(f"{path} has {count} frame: a video needs at least 2 frames")
    return {
        "size": (frame.shape[1], frame.shape[0]),
        "count": count,
        "fps": fps if fps and math.isfinite(fps) and fps > 0 else None,
    }


def open_video_pair(
    left,
    right,
    calib,
    *,
    exposure=None,
    frame_rate=None,
    color=None,
    require_exposure: bool = True,
) -> VideoSource:
    """Open two videos as a stereo clip, with the stereo calibration ``calib``.

    ``calib`` is a rectified pair's calibration, or an unrectified rig's (see
    :func:`~stereodeblur.io.rig.read_calibration`): its frames are then rectified on
    reading and the source's camera is the rectified one.

    The videos must have the same size and frame rate and at least two frames each.
    When their frame counts differ the extra frames of the longer one are ignored and
    the source's ``warnings`` says so (front ends print it: the user must see that
    frames were dropped). A still image (PNG, JPEG, ...) or a file FFmpeg cannot open
    is refused in one line, with FFmpeg's own log kept off the terminal.
    """
    left, right = Path(left), Path(right)
    if calib is None:
        raise InputError(
            "a video pair needs calib: an OpenCV stereo calibration file (YAML with P1, P2 "
            "or Q, or M1, D1, M2, D2, R, T), a camera.json, a Kalibr camchain.yaml or a "
            "folder with ROS left.yaml and right.yaml",
            parameter="calib",
        )
    if left.resolve() == right.resolve():
        raise InputError(f"the left and right videos are the same file: {left}")
    calibration = read_calibration(calib)
    probes = {"left": _probe(left), "right": _probe(right)}
    if probes["left"]["size"] != probes["right"]["size"]:
        (lw, lh), (rw, rh) = probes["left"]["size"], probes["right"]["size"]
        raise InputError(f"{right} is {rw}x{rh} but {left} is {lw}x{lh}: both views need one size")
    rates = [probes[v]["fps"] for v in ("left", "right")]
    if None not in rates and abs(rates[0] - rates[1]) > 1e-3 * rates[0]:
        raise InputError(
            f"{left} has {rates[0]:.6g} frames per second but {right} has {rates[1]:.6g}"
        )
    check_frame_size(*probes["left"]["size"], left)
    rectification = None
    if isinstance(calibration, StereoRig):
        rectification = rectify_rig(calibration, probes["left"]["size"], f"video {left}")
        calibration = rectification.calibration
    check_image_size(calibration, probes["left"]["size"], f"video {left}")
    warnings = []
    counts = probes["left"]["count"], probes["right"]["count"]
    if counts[0] != counts[1]:
        warnings.append(
            f"{left} has {counts[0]} frames and {right} {counts[1]}: using the first "
            f"{min(counts)} of both"
        )
    info = camera_info(
        calibration.camera,
        f"video {left}",
        frame_rate=frame_rate,
        exposure=exposure,
        color=color,
        source_frame_rate=rates[0] if rates[0] is not None else calibration.frame_rate,
        source_exposure=calibration.exposure,
        source_color=calibration.color or CAMERA_OUTPUT_COLOR,
        require_exposure=require_exposure,
    )
    width, height = probes["left"]["size"]
    return VideoSource(
        left,
        right,
        info=info,
        num_frames=min(counts),
        shape=(height, width),
        calibration=calibration,
        warnings=warnings,
        rectification=rectification,
    )


def write_video(path, frames, *, frame_rate: float, codec: str = "FFV1") -> Path:
    """Write 8-bit RGB frames (float in [0, 1] or uint8, (H, W, 3)) to a video file.

    ``codec`` is a fourcc; FFV1 in ``.mkv`` is lossless. Used to make test clips.
    """
    path = Path(path)
    writer = None
    try:
        for frame in frames:
            frame = np.asarray(frame)
            if frame.dtype != np.uint8:
                frame = np.rint(np.clip(frame, 0, 1) * 255).astype(np.uint8)
            if frame.ndim == 2:
                frame = np.repeat(frame[..., None], 3, axis=2)
            if writer is None:
                height, width = frame.shape[:2]
                writer = cv2.VideoWriter(
                    str(path), cv2.VideoWriter_fourcc(*codec), float(frame_rate), (width, height)
                )
                if not writer.isOpened():
                    raise InputError(f"cannot write {path} with codec {codec!r}")
            writer.write(np.ascontiguousarray(frame[..., ::-1]))
    finally:
        if writer is not None:
            writer.release()
    return path
