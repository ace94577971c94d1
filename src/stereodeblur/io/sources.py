"""Open any stereo input as a scene: detect its kind and dispatch to its reader.

:func:`open_source` detects the kind of input from the paths given and returns a
:class:`~stereodeblur.io.protocol.StereoScene`: a :class:`~stereodeblur.io.scene.Scene`
for scene folders, a :class:`~stereodeblur.io.frame_source.FrameSource` otherwise.
Frames are read lazily, one at a time, never the whole clip.

Kinds of input
--------------
- a scene folder (``camera.json``, ``left/``, ``right/``; SCENE_FORMAT.md);
- KITTI scene flow 2015 (``image_2/ image_3/ calib_cam_to_cam/``), stereo/flow 2012
  (``image_0/ image_1/ calib/``, or ``colored_0/ colored_1/``) and raw recordings
  (``image_02/data image_03/data``, ``calib_cam_to_cam.txt``): see :mod:`.kitti`;
- two video files, left then right, with a calibration file: see :mod:`.video`; the
  videos of an unrectified rig are rectified on reading (:mod:`.rig`, :mod:`.rectify`).

Frame rate, exposure and colour come from the source when it has them;
``frame_rate``, ``exposure`` and ``color`` given here override them. Video files and
KITTI's PNGs are camera output: sRGB unless their calibration says otherwise; a scene
folder's ``camera.json`` states its encoding (linear when it has no ``"color"``). Frames are
read linear; results are written back in the input's encoding. A source
without an exposure time needs ``exposure`` (unless ``require_exposure=False``,
then frames count as instantaneous, exposure 0).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .frame_source import camera_info
from .kitti import detect_kitti, open_kitti
from .protocol import StereoScene
from .scene import open_scene
from .video import open_video_pair

__all__ = ["SourceSpec", "detect_source", "open_source"]


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

    def open(self) -> StereoScene:
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


# --------------------------------------------------------------------------- detection


def detect_source(paths: Sequence) -> str:
    """Kind of input: 'scene', 'kitti-2015', 'kitti-2012', 'kitti-raw' or 'video'."""
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
) -> StereoScene:
    """Open a scene folder, a KITTI folder or a pair of videos as a scene.

    Parameters
    ----------
    paths : path or sequence of paths
        One folder, or two video files (left, right).
    calib : path, optional
        Stereo calibration for videos: OpenCV YAML (``P1``/``P2``/``Q``) or ``camera.json``,
        or an unrectified rig's (:func:`~stereodeblur.io.rig.read_calibration`).
    exposure, frame_rate : float, optional
        Seconds and frames per second; override the source's.
    color : {'linear', 'srgb'}, optional
        How the stored values encode irradiance; overrides the source's (video and KITTI:
        'srgb' unless a ``camera.json`` calibration says; scene folders: their ``camera.json``).
    sequence : str or int, optional
        KITTI 2012/2015 sequence number, when the folder holds several.
    require_exposure : bool
        Fail when no exposure time is known (else frames count as instantaneous).

    Returns
    -------
    StereoScene
        A :class:`~stereodeblur.io.scene.Scene` or a
        :class:`~stereodeblur.io.frame_source.FrameSource`.
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    paths = [Path(p) for p in paths]
    kind = detect_source(paths)
    if kind != "video" and calib is not None:
        raise InputError(
            f"calib is only for video pairs; {paths[0]} has its own calibration",
            parameter="calib",
        )
    if kind != "video" and kind not in ("kitti-2015", "kitti-2012") and sequence is not None:
        raise InputError(
            f"sequence is only for KITTI 2012/2015 folders, not {paths[0]}", parameter="sequence"
        )
    options = dict(exposure=exposure, frame_rate=frame_rate, color=color)
    if kind == "scene":
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
        return scene
    if kind == "video":
        if sequence is not None:
            raise InputError(
                "sequence is only for KITTI 2012/2015 folders, not videos", parameter="sequence"
            )
        return open_video_pair(
            paths[0], paths[1], calib, **options, require_exposure=require_exposure
        )
    return open_kitti(
        paths[0], kind=kind, sequence=sequence, **options, require_exposure=require_exposure
    )
