"""The base of frame sources that are not scene folders (KITTI folders, video pairs).

:class:`FrameSource` holds what every source knows after opening (camera, size,
frame count, input paths) and implements the read-only part of the
:class:`~stereodeblur.io.protocol.StereoScene` protocol; subclasses implement
:meth:`FrameSource._read_stored`. A source of an unrectified rig carries a
:class:`~stereodeblur.io.rectify.Rectification`: its frames are rectified on reading, in
linear light, and everything after sees the rectified pair. :func:`camera_info` merges
the timing and colour given by the caller with the source's own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS, Exposure, StereoCamera
from .camera_json import COLORS, CameraInfo
from .numbering import SCENE_NUMBERING
from .srgb import linear_to_srgb, srgb_to_linear

# The encoding of camera output (video files, KITTI's PNGs) when its calibration states none.
CAMERA_OUTPUT_COLOR = "srgb"


class FrameSource:
    """Base of the non-scene sources; satisfies :class:`~stereodeblur.io.protocol.StereoScene`.

    Subclasses set ``kind``, call ``__init__`` and implement :meth:`_read_stored`.
    There is no ground truth: :meth:`has_gt` is False and :meth:`gt_path` and the
    ``read_gt_*`` methods raise :class:`~stereodeblur.errors.InputError`.

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
    numbering : FrameNumbering
        The source's frame numbers and names (default: ``000000``, ``000001``, ...).
    rectification : Rectification or None
        For an unrectified rig: how its stored frames are rectified on reading; ``info``
        then holds the rectified camera.
    """

    kind = "source"

    def __init__(
        self,
        *,
        root,
        name,
        paths,
        info,
        num_frames,
        shape,
        channels,
        warnings=(),
        numbering=SCENE_NUMBERING,
        rectification=None,
    ):
        self.root = Path(root)
        self.name = name
        self.paths = tuple(Path(p) for p in paths)
        self.info = info
        self.num_frames = int(num_frames)
        self.shape = tuple(shape)
        self.channels = int(channels)
        self.warnings = tuple(warnings)
        self.numbering = numbering
        self.rectification = rectification
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
        text = f"{self.kind} {self.name}: {self.num_frames} frames of {w}x{h}"
        if self.rectification is not None:
            text += f", rectified on reading ({self.rectification.kind} calibration)"
        return text

    def _check(self, view: str, index) -> int:
        if view not in VIEWS:
            raise InputError(f"view must be 'left' or 'right', got {view!r}")
        if isinstance(index, bool) or not isinstance(index, int | np.integer):
            raise InputError(f"frame index must be an integer, got {index!r}")
        if not 0 <= index < self.num_frames:
            raise InputError(f"frame index {index} is out of range 0..{self.num_frames - 1}")
        return int(index)

    def read_frame(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Frame ``index`` of ``view`` as float32 in [0, 1], linear when ``linear``.

        A raw rig's frame is rectified in linear light, then encoded again when the
        stored encoding is asked for (``linear=False``).
        """
        image = self._read_stored(view, self._check(view, index))
        expected = (*self.shape, 3) if self.channels == 3 else self.shape
        if image.shape != expected:
            raise InputError(
                f"frame {index} of the {view} view of {self.name} has shape {image.shape}, "
                f"expected {expected}"
            )
        encoded = self.info.color == "srgb"
        if self.rectification is None:
            return srgb_to_linear(image) if linear and encoded else image
        from .rectify import rectify_view

        image = rectify_view(self.rectification, view, srgb_to_linear(image) if encoded else image)
        return linear_to_srgb(image) if encoded and not linear else image

    def _read_stored(self, view: str, index: int) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def frame_label(self, view: str, index: int) -> str:
        """Where frame ``index`` of ``view`` comes from, for messages."""
        return f"{self.name} {view} frame {index}"

    def has_gt(self, kind: str, view: str, index: int) -> bool:
        """Ground truth is only in scene folders: always False."""
        return False

    def _no_gt(self, kind: str, view: str, index: int) -> InputError:
        return InputError(
            f"{self.name} ({self.kind}) has no ground-truth {kind} for the {view} view of "
            f"frame {index}: only scene folders have gt/"
        )

    def gt_path(self, kind: str, view: str, index: int) -> Path:
        """No ground truth here: raises :class:`InputError` naming what is missing."""
        raise self._no_gt(kind, view, index)

    def read_gt_disparity(self, view: str, index: int) -> np.ndarray:
        """No ground truth here: raises :class:`InputError` naming what is missing."""
        raise self._no_gt("disparity", view, index)

    def read_gt_flow(self, view: str, index: int) -> np.ndarray:
        """No ground truth here: raises :class:`InputError` naming what is missing."""
        raise self._no_gt("flow", view, index)

    def read_gt_mixed(self, view: str, index: int) -> np.ndarray:
        """No ground truth here: raises :class:`InputError` naming what is missing."""
        raise self._no_gt("mixed", view, index)

    def read_gt_sharp(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """No ground truth here: raises :class:`InputError` naming what is missing."""
        raise self._no_gt("sharp", view, index)


# --------------------------------------------------------------------------- timing


def _number(value, name: str, *, allow_zero: bool) -> float:
    """``value`` as a finite float > 0 (>= 0 with ``allow_zero``); InputError naming ``name``."""
    what = "a non-negative" if allow_zero else "a positive"
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be {what} number, got {value!r}", parameter=name) from None
    if not np.isfinite(number) or number < 0 or (number == 0 and not allow_zero):
        raise InputError(f"{name} must be {what} number, got {number}", parameter=name)
    return number


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

    ``what`` names the source in messages, e.g. ``'KITTI folder data/training'``. ``color``
    given wins over ``source_color``; with neither the values count as linear (camera output
    passes ``source_color=CAMERA_OUTPUT_COLOR`` when its calibration states no encoding).
    Errors about a value the caller gives or must give carry its name as
    :attr:`InputError.parameter` (``'frame_rate'``, ``'exposure'``, ``'color'``).
    """
    if frame_rate is not None:
        frame_rate = _number(frame_rate, "frame_rate", allow_zero=False)
    elif source_frame_rate is not None:
        frame_rate = float(source_frame_rate)
    else:
        raise InputError(
            f"{what} has no frame rate: give frame_rate (frames per second)",
            parameter="frame_rate",
        )
    if exposure is not None:
        exposure = _number(exposure, "exposure", allow_zero=True)
    elif source_exposure is not None:
        exposure = float(source_exposure)
    elif require_exposure:
        raise InputError(
            f"{what} has no exposure time: give exposure in seconds (at most 1/frame rate = "
            f"{1 / frame_rate:.4g} s)",
            parameter="exposure",
        )
    else:
        exposure = 0.0
    color = color if color is not None else (source_color or "linear")
    if color not in COLORS:
        raise InputError(f"color must be 'linear' or 'srgb', got {color!r}", parameter="color")
    try:
        timing = Exposure(frame_rate, exposure)
    except ValueError as exc:
        raise InputError(f"{what}: {exc}", parameter="exposure") from None
    return CameraInfo(camera, timing, color)
