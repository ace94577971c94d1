"""Open any stereo input as a scene: scene folders, KITTI folders and video pairs.

:func:`open_source` detects the kind of input from the paths given and returns an
object with the interface of :class:`~stereodeblur.io.scene.Scene`: ``info``
(:class:`~stereodeblur.io.scene.CameraInfo`), ``num_frames``, ``shape`` (H, W),
``channels``, ``root``, ``name``, ``read_frame(view, index, linear=True)`` and
``has_gt(kind, view, index)`` (False for everything but scene folders). Frames are
read lazily, one at a time, never the whole clip.

Kinds of input
--------------
- a scene folder (``camera.json``, ``left/``, ``right/``; SCENE_FORMAT.md);
- KITTI scene flow 2015 (``image_2/ image_3/ calib_cam_to_cam/``), stereo/flow 2012
  (``image_0/ image_1/ calib/``, or ``colored_0/ colored_1/``) and raw recordings
  (``image_02/data image_03/data``, ``calib_cam_to_cam.txt``): see :mod:`.kitti`;
- two video files, left then right, with a calibration file: see :mod:`.video`.

Frame rate, exposure and colour come from the source when it has them;
``frame_rate``, ``exposure`` and ``color`` given here override them. A source
without an exposure time needs ``exposure`` (unless ``require_exposure=False``,
then frames count as instantaneous, exposure 0).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS, Exposure, StereoCamera
from .formats import srgb_to_linear
from .scene import COLORS, CameraInfo


@dataclass(frozen=True)
class SourceSpec:
    """How to open a source: enough to open it again in another process.

    Paths are made absolute, so a worker on another machine that shares the same
    paths opens the same input.
    """

    paths: tuple[str, ...]
    calib: str | None = None
    exposure: float | None = None
    frame_rate: float | None = None
    color: str | None = None
    sequence: str | None = None
    require_exposure: bool = True

    @classmethod
    def from_arguments(
        cls,
        paths,
        *,
        calib=None,
        exposure=None,
        frame_rate=None,
        color=None,
        sequence=None,
        require_exposure=True,
    ) -> SourceSpec:
        """A spec with absolute paths (a single path may be given as a string)."""
        if isinstance(paths, str | os.PathLike):
            paths = [paths]
        absolute = tuple(os.path.abspath(os.fspath(p)) for p in paths)
        return cls(
            absolute,
            calib=None if calib is None else os.path.abspath(os.fspath(calib)),
            exposure=None if exposure is None else float(exposure),
            frame_rate=None if frame_rate is None else float(frame_rate),
            color=color,
            sequence=None if sequence is None else str(sequence),
            require_exposure=require_exposure,
        )

    def open(self):
        """Open the source (see :func:`open_source`)."""
        return open_source(
            self.paths,
            calib=self.calib,
            exposure=self.exposure,
            frame_rate=self.frame_rate,
            color=self.color,
            sequence=self.sequence,
            require_exposure=self.require_exposure,
        )


class FrameSource:
    """Base of the non-scene sources: the read-only interface of a :class:`Scene`.

    Subclasses set the attributes in ``__init__`` and implement :meth:`_read_stored`.

    Attributes
    ----------
    kind : str
        Short name of the input kind, e.g. ``'kitti-2015'``, ``'video'``.
    root : Path
        The folder (or the left video) the source was opened from.
    name : str
    paths : tuple of Path
        Every input file or folder (an output must not go into them).
    info : CameraInfo
    num_frames : int
    shape : tuple of int
        ``(H, W)``.
    channels : int
        1 (grey) or 3 (RGB).
    warnings : tuple of str
        Problems found that do not stop reading (e.g. dropped frames).
    """

    kind = "source"

    def __init__(self, *, root, name, paths, info, num_frames, shape, channels, warnings=()):
        self.root = Path(root)
        self.name = name
        self.paths = tuple(Path(p) for p in paths)
        self.info = info
        self.num_frames = int(num_frames)
        self.shape = tuple(shape)
        self.channels = int(channels)
        self.warnings = tuple(warnings)
        if self.num_frames < 2:
            raise InputError(f"a clip needs at least two frames, found {self.num_frames} in {root}")

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}({str(self.root)!r}, num_frames={self.num_frames}, "
            f"shape={self.shape}, channels={self.channels}, color={self.info.color!r})"
        )

    def describe(self) -> str:
        """One line: kind, name, frames and size."""
        h, w = self.shape
        return f"{self.kind} {self.name}: {self.num_frames} frames of {w}x{h}"

    def _check(self, view: str, index) -> int:
        if view not in VIEWS:
            raise InputError(f"view must be 'left' or 'right', got {view!r}")
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise InputError(f"frame index must be an integer, got {index!r}")
        if not 0 <= index < self.num_frames:
            raise InputError(f"frame index {index} is out of range 0..{self.num_frames - 1}")
        return int(index)

    def read_frame(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Frame ``index`` of ``view`` as float32 in [0, 1], linear when ``linear``."""
        image = self._read_stored(view, self._check(view, index))
        expected = (*self.shape, 3) if self.channels == 3 else self.shape
        if image.shape != expected:
            raise InputError(
                f"frame {index} of the {view} view of {self.name} has shape {image.shape}, "
                f"expected {expected}"
            )
        if linear and self.info.color == "srgb":
            image = srgb_to_linear(image)
        return image

    def _read_stored(self, view: str, index: int) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def frame_label(self, view: str, index: int) -> str:
        """Where frame ``index`` of ``view`` comes from, for messages."""
        return f"{self.name} {view} frame {index}"

    def has_gt(self, kind: str, view: str, index: int) -> bool:
        """Ground truth is only in scene folders: always False."""
        return False

    def gt_path(self, kind: str, view: str, index: int):
        raise InputError(
            f"{self.root} ({self.kind}) has no ground truth ({kind}): only scene folders have gt/"
        )


# --------------------------------------------------------------------------- timing


def _positive(value, name: str) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive number, got {value}")
    return value


def camera_info(
    camera: StereoCamera,
    what: str,
    *,
    frame_rate=None,
    exposure=None,
    color=None,
    source_frame_rate=None,
    source_exposure=None,
    source_color=None,
    require_exposure: bool = True,
) -> CameraInfo:
    """Camera info from the given values, else the source's, else a one-line error.

    ``what`` names the source in messages, e.g. ``'KITTI folder data/training'``.
    """
    if frame_rate is not None:
        frame_rate = _positive(frame_rate, "--frame-rate")
    elif source_frame_rate is not None:
        frame_rate = float(source_frame_rate)
    else:
        raise InputError(f"{what} has no frame rate: pass --frame-rate FPS")
    if exposure is not None:
        try:
            exposure = float(exposure)
        except (TypeError, ValueError):
            raise InputError(f"--exposure must be a number of seconds, got {exposure!r}") from None
        if not np.isfinite(exposure) or exposure < 0:
            raise InputError(f"--exposure must be a non-negative number of seconds, got {exposure}")
    elif source_exposure is not None:
        exposure = float(source_exposure)
    elif require_exposure:
        raise InputError(
            f"{what} has no exposure time: pass --exposure SECONDS (at most 1/frame rate = "
            f"{1 / frame_rate:.4g} s)"
        )
    else:
        exposure = 0.0
    color = color if color is not None else (source_color or "linear")
    if color not in COLORS:
        raise InputError(f"--color must be 'linear' or 'srgb', got {color!r}")
    try:
        timing = Exposure(frame_rate, exposure)
    except ValueError as exc:
        raise InputError(f"{what}: {exc}") from None
    return CameraInfo(camera, timing, color)


# --------------------------------------------------------------------------- detection


def detect_source(paths: Sequence) -> str:
    """Kind of input: 'scene', 'kitti-2015', 'kitti-2012', 'kitti-raw' or 'video'."""
    from .kitti import detect_kitti

    paths = [Path(p) for p in paths]
    if len(paths) == 2:
        for path in paths:
            if not path.exists():
                raise FileNotFoundError(f"video file not found: {path}")
            if not path.is_file():
                raise InputError(
                    f"{path} is not a file: two inputs must be a LEFT and a RIGHT video"
                )
        return "video"
    if len(paths) != 1:
        raise InputError(
            f"expected one input folder or two video files (left, right), got {len(paths)} paths"
        )
    path = paths[0]
    if not path.exists():
        raise FileNotFoundError(f"input not found: {path}")
    if path.is_file():
        raise InputError(
            f"{path} is a single file: give a scene or KITTI folder, or two videos LEFT RIGHT"
        )
    if (path / "camera.json").exists():
        return "scene"
    kind = detect_kitti(path)
    if kind is not None:
        return kind
    raise InputError(
        f"{path} is not a scene folder (no camera.json) nor a KITTI folder (image_2/ image_3/, "
        "image_0/ image_1/, or image_02/data image_03/data)"
    )


def open_source(
    paths,
    *,
    calib=None,
    exposure=None,
    frame_rate=None,
    color=None,
    sequence=None,
    require_exposure: bool = True,
):
    """Open a scene folder, a KITTI folder or a pair of videos as a scene.

    Parameters
    ----------
    paths : path or sequence of paths
        One folder, or two video files (left, right).
    calib : path, optional
        Stereo calibration for videos: OpenCV YAML (``P1``/``P2``/``Q``) or ``camera.json``.
    exposure, frame_rate : float, optional
        Seconds and frames per second; override the source's.
    color : {'linear', 'srgb'}, optional
        How the stored values encode irradiance; overrides the source's.
    sequence : str or int, optional
        KITTI 2012/2015 sequence number, when the folder holds several.
    require_exposure : bool
        Fail when no exposure time is known (else frames count as instantaneous).

    Returns
    -------
    Scene or FrameSource
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    paths = [Path(p) for p in paths]
    kind = detect_source(paths)
    if kind != "video" and calib is not None:
        raise InputError(f"--calib is only for video pairs; {paths[0]} has its own calibration")
    if kind != "video" and kind not in ("kitti-2015", "kitti-2012") and sequence is not None:
        raise InputError(f"--sequence is only for KITTI 2012/2015 folders, not {paths[0]}")
    options = dict(exposure=exposure, frame_rate=frame_rate, color=color)
    if kind == "scene":
        from .scene import open_scene

        scene = open_scene(paths[0])
        if any(v is not None for v in options.values()):
            old = scene.info
            scene.info = camera_info(
                old.camera,
                f"scene {paths[0]}",
                **options,
                source_frame_rate=old.exposure.frame_rate,
                source_exposure=old.exposure.exposure,
                source_color=old.color,
            )
        if not hasattr(scene, "name"):
            scene.name = scene.root.name
        return scene
    if kind == "video":
        from .video import open_video_pair

        if sequence is not None:
            raise InputError("--sequence is only for KITTI 2012/2015 folders, not videos")
        return open_video_pair(
            paths[0], paths[1], calib, **options, require_exposure=require_exposure
        )
    from .kitti import open_kitti

    return open_kitti(
        paths[0], kind=kind, sequence=sequence, **options, require_exposure=require_exposure
    )
