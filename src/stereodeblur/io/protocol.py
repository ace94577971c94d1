"""What every stereo input offers: the :class:`StereoScene` protocol.

A scene folder (:class:`~stereodeblur.io.scene.Scene`), a KITTI folder
(:class:`~stereodeblur.io.kitti.KittiSource`) and a video pair
(:class:`~stereodeblur.io.video.VideoSource`) all satisfy it, so code that reads
frames or ground truth takes a ``StereoScene`` and never probes for attributes.

Conventions
-----------
- Views are ``'left'`` and ``'right'``; frames are indexed ``0 .. num_frames - 1``; the
  source's own numbers and file names are ``numbering``'s (:mod:`.numbering`).
- Frames are float32 in [0, 1], ``(H, W)`` grey or ``(H, W, 3)`` RGB, linear in
  irradiance when read with ``linear=True`` (sRGB decoded when ``info.color == 'srgb'``).
- Ground truth kinds are ``'sharp'``, ``'disparity'``, ``'flow'`` and ``'mixed'``
  (SCENE_FORMAT.md). Only scene folders hold any: other sources answer
  ``has_gt(...) -> False`` and their ``gt_path`` / ``read_gt_*`` raise
  :class:`~stereodeblur.errors.InputError` naming the source and what is missing.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    import numpy as np

    from .camera_json import CameraInfo
    from .numbering import FrameNumbering


@runtime_checkable
class StereoScene(Protocol):
    """A rectified stereo clip read frame by frame, with optional ground truth.

    Attributes
    ----------
    root : Path
        The folder (or the left video) the input was opened from.
    name : str
        Short name for messages and logs.
    kind : str
        ``'scene'``, ``'kitti-2015'``, ``'kitti-2012'``, ``'kitti-raw'`` or ``'video'``.
    paths : tuple of Path
        Every input file or folder; outputs must never go into them.
    warnings : tuple of str
        Problems found on opening that do not stop reading (e.g. dropped frames).
    info : CameraInfo
        Stereo camera, frame timing and colour encoding.
    num_frames : int
        Frames per view (at least 2).
    shape : tuple of int
        Frame size ``(H, W)``.
    channels : int
        1 (grey) or 3 (RGB).
    numbering : FrameNumbering
        The source's numbers and names of its frames (results keep them).
    """

    root: Path
    name: str
    kind: str
    paths: tuple[Path, ...]
    warnings: tuple[str, ...]
    info: CameraInfo
    num_frames: int
    shape: tuple[int, int]
    channels: int
    numbering: FrameNumbering

    def read_frame(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Frame ``index`` of ``view`` as float32 in [0, 1], linear when ``linear``."""
        ...

    def frame_label(self, view: str, index: int) -> str:
        """Where frame ``index`` of ``view`` comes from (a file, or a video and frame)."""
        ...

    def has_gt(self, kind: str, view: str, index: int) -> bool:
        """Whether ground truth ``kind`` exists for frame ``index`` of ``view``."""
        ...

    def gt_path(self, kind: str, view: str, index: int) -> Path:
        """The file that holds (or would hold) ground truth ``kind`` of a frame."""
        ...

    def read_gt_disparity(self, view: str, index: int) -> np.ndarray:
        """Disparity (H, W) float32 in pixels, NaN where unknown."""
        ...

    def read_gt_flow(self, view: str, index: int) -> np.ndarray:
        """Flow (H, W, 2) float32 (u, v) to the next frame, NaN where unknown."""
        ...

    def read_gt_mixed(self, view: str, index: int) -> np.ndarray:
        """Mask (H, W) bool of pixels whose blur mixes differently moving surfaces."""
        ...

    def read_gt_sharp(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Sharp image at the centre of frame ``index``'s exposure, like ``read_frame``."""
        ...

    def describe(self) -> str:
        """One line: kind, name, frames and size."""
        ...
