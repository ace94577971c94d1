"""Reading and writing stereo video scenes (``stereo-video/1``, see SCENE_FORMAT.md).

Layout
------
::

    SCENE/camera.json
    SCENE/left/000000.png, SCENE/right/000000.png, ...   frames, numbered from 000000
    SCENE/gt/sharp/VIEW/NNNNNN.png                        optional ground truth
    SCENE/gt/disparity/VIEW/NNNNNN.pfm
    SCENE/gt/flow/VIEW/NNNNNN.flo
    SCENE/gt/mixed/VIEW/NNNNNN.png

Views are ``'left'`` and ``'right'``. Images are float32 in [0, 1]; with
``color == 'srgb'`` the files hold sRGB-encoded values and frames are decoded to
linear on read (``linear=True``) and encoded on write. Disparities are (H, W) float32
in pixels with NaN where unknown; flows are (H, W, 2) float32 (u, v) with NaN where
unknown (stored as the Middlebury value 1e10). Bad input raises
:class:`~stereodeblur.errors.InputError` or ``FileNotFoundError`` with a one-line
message naming the file and what was expected.
"""

from __future__ import annotations

import operator
import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS
from .camera_json import (
    CameraInfo,
    _camera_json,
    read_camera,
    write_camera,
)
from .formats import read_flo, read_pfm, write_flo, write_pfm
from .intrinsics import check_intrinsics
from .numbering import SCENE_NUMBERING, FrameNumbering
from .png import (
    PngInfo,
    _check_image,
    read_mask,
    read_png,
    read_png_header,
    write_mask,
    write_png,
)
from .srgb import linear_to_srgb, srgb_to_linear

GT_KINDS = ("sharp", "disparity", "flow", "mixed")
_EXTENSIONS = {"frame": "png", "sharp": "png", "disparity": "pfm", "flow": "flo", "mixed": "png"}
_FRAME_NAME = re.compile(r"^(\d{6})\.png$")
# Frame files a writer may have written: a scene's, or another source's kept names
# (:mod:`.numbering`, e.g. KITTI's 000005_10.png, 0000000042.png).
_WRITTEN_NAME = re.compile(r"^\d[\d_]*\.png$")
# Middlebury marks unknown flow with values above 1e9.
FLOW_UNKNOWN = 1e10
# Smallest frame side of a clip: the dense optical flow (OpenCV DIS) needs 12 pixels,
# the census transform a 7x7 window; 16 leaves a margin for the image pyramid.
MIN_FRAME_SIZE = 16


# --------------------------------------------------------------------------- paths


def _check_view(view) -> str:
    if view not in VIEWS:
        raise InputError(f"view must be 'left' or 'right', got {view!r}")
    return view


def _check_index(index, num_frames: int | None = None) -> int:
    try:
        if isinstance(index, bool):
            raise TypeError
        index = operator.index(index)
    except TypeError:
        raise InputError(f"frame index must be an integer, got {index!r}") from None
    if index < 0 or index > 999999 or (num_frames is not None and index >= num_frames):
        top = 999999 if num_frames is None else num_frames - 1
        raise InputError(f"frame index {index} is out of range 0..{top}")
    return index


def scene_path(
    root: str | os.PathLike,
    kind: str,
    view: str,
    index: int,
    *,
    numbering: FrameNumbering = SCENE_NUMBERING,
) -> Path:
    """Path of a frame (``kind='frame'``) or ground-truth file in the scene at ``root``;
    named as ``numbering`` names frame ``index`` (a scene's ``NNNNNN`` by default)."""
    if kind not in _EXTENSIONS:
        raise InputError(f"kind must be one of {', '.join(_EXTENSIONS)}, got {kind!r}")
    name = f"{numbering.name(_check_index(index))}.{_EXTENSIONS[kind]}"
    folder = Path(root) / _check_view(view) if kind == "frame" else Path(root) / "gt" / kind / view
    return folder / name


# --------------------------------------------------------------------------- reading


def _list_frames(folder: Path) -> list[int]:
    """Frame numbers of ``folder``, sorted; hidden and non-PNG files are ignored."""
    with os.scandir(folder) as scan:
        entries = [(entry.name, entry.is_file()) for entry in scan]
    numbers = []
    for name, is_file in entries:
        if name.startswith(".") or not name.lower().endswith(".png"):
            continue
        match = _FRAME_NAME.match(name)
        if match is None:
            raise InputError(
                f"unexpected frame file name {folder / name}: expected six digits like 000000.png"
            )
        if is_file:
            numbers.append(int(match.group(1)))
    return sorted(numbers)


class Scene:
    """A stereo video scene on disk (see :func:`open_scene`).

    Satisfies :class:`~stereodeblur.io.protocol.StereoScene`. Opening checks the
    layout: ``camera.json``, both frame folders numbered alike, and the first frame
    of each view (size, type, at least ``MIN_FRAME_SIZE``). Every other frame file
    is checked when a run starts (:func:`~stereodeblur.io.readable.check_readable`,
    for the frames and views it reads) or when it is read, with an
    :class:`~stereodeblur.errors.InputError` naming it.

    Attributes
    ----------
    root : Path
        Scene folder.
    name : str
        The folder's name.
    kind : str
        ``'scene'``.
    paths : tuple of Path
        ``(root,)``: the whole folder is input.
    warnings : tuple of str
        Always empty (a scene folder is either valid or refused).
    info : CameraInfo
        Contents of ``camera.json``.
    num_frames : int
        Number of frames per view.
    shape : tuple of int
        Frame size ``(H, W)``.
    channels : int
        1 (grey) or 3 (RGB).
    bit_depth : int
        Bit depth of the frame PNGs.
    numbering : FrameNumbering
        ``000000``, ``000001``, ...
    """

    def __init__(self, root: str | os.PathLike):
        root = Path(root)
        if not root.is_dir():
            raise FileNotFoundError(f"scene folder not found: {root}")
        self.root = root
        self.name = root.name
        self.paths = (root,)
        self.warnings: tuple[str, ...] = ()
        self.numbering = SCENE_NUMBERING
        self.info = read_camera(root / "camera.json")
        numbers = {}
        for view in VIEWS:
            folder = root / view
            if not folder.is_dir():
                raise FileNotFoundError(f"missing frame folder {folder}")
            numbers[view] = _list_frames(folder)
            if not numbers[view]:
                raise InputError(f"no frames in {folder}: expected 000000.png, 000001.png, ...")
            for expected, found in enumerate(numbers[view]):
                if found != expected:
                    raise InputError(
                        f"missing frame {scene_path(root, 'frame', view, expected)}: frames must "
                        f"be numbered contiguously from 000000 (next found is {found:06d}.png)"
                    )
        left, right = len(numbers["left"]), len(numbers["right"])
        if left != right:
            short, other = ("right", "left") if right < left else ("left", "right")
            count = min(left, right)
            raise InputError(
                f"missing frame {scene_path(root, 'frame', short, count)}: {other}/ has "
                f"{max(left, right)} frames, {short}/ has {count}; both views need the same numbers"
            )
        if left < 2:
            raise InputError(f"a scene needs at least two frames, found {left} in {root}")
        self.num_frames = left
        first = read_png_header(self.frame_path("left", 0))
        check_frame_size(first.width, first.height, self.frame_path("left", 0))
        path = self.frame_path("right", 0)
        header = read_png_header(path)
        if header != first:
            raise InputError(
                f"{path} is {_describe(header)}, expected {_describe(first)} "
                f"like {self.frame_path('left', 0)}"
            )
        check_intrinsics(self.info.camera.K, (first.width, first.height), root / "camera.json")
        self._format = first
        self.shape = (first.height, first.width)
        self.channels = first.channels
        self.bit_depth = first.bit_depth

    kind = "scene"

    def __repr__(self) -> str:
        return (
            f"Scene({str(self.root)!r}, num_frames={self.num_frames}, shape={self.shape}, "
            f"channels={self.channels}, bit_depth={self.bit_depth}, color={self.info.color!r})"
        )

    def describe(self) -> str:
        """One line: kind, name, frames and size."""
        h, w = self.shape
        return f"{self.kind} {self.name}: {self.num_frames} frames of {w}x{h}"

    # paths
    def frame_path(self, view: str, index: int) -> Path:
        """Path of frame ``index`` of ``view``."""
        return scene_path(self.root, "frame", view, index)

    def frame_label(self, view: str, index: int) -> str:
        """The file of frame ``index`` of ``view``, for messages."""
        return str(self.frame_path(view, index))

    def gt_path(self, kind: str, view: str, index: int) -> Path:
        """Path of the ground truth ``kind`` ('sharp', 'disparity', 'flow', 'mixed')."""
        if kind not in GT_KINDS:
            raise InputError(
                f"ground-truth kind must be one of {', '.join(GT_KINDS)}, got {kind!r}"
            )
        return scene_path(self.root, kind, view, _check_index(index, self.num_frames))

    def has_gt(self, kind: str, view: str, index: int) -> bool:
        """Whether the scene holds ground truth ``kind`` for frame ``index`` of ``view``."""
        return self.gt_path(kind, view, index).is_file()

    # frames
    def read_frame(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Frame ``index`` of ``view`` as float32, linear when ``linear`` (else as stored)."""
        path = self.frame_path(_check_view(view), _check_index(index, self.num_frames))
        return self._read_image(path, linear=linear)

    def read_gt_sharp(self, view: str, index: int, *, linear: bool = True) -> np.ndarray:
        """Sharp image at the centre of frame ``index``'s exposure, like :meth:`read_frame`."""
        return self._read_image(self.gt_path("sharp", view, index), linear=linear)

    def read_gt_disparity(self, view: str, index: int) -> np.ndarray:
        """Disparity (H, W) float32 in pixels, NaN where unknown (non-finite or <= 0)."""
        path = self.gt_path("disparity", view, index)
        disparity = read_pfm(path)
        self._check_size(path, disparity, (*self.shape,), "an (H, W) disparity")
        with np.errstate(invalid="ignore"):
            disparity[~(np.isfinite(disparity) & (disparity > 0))] = np.nan
        return disparity

    def read_gt_flow(self, view: str, index: int) -> np.ndarray:
        """Flow (H, W, 2) float32 (u, v) to the next frame, NaN where unknown."""
        path = self.gt_path("flow", view, index)
        flow = read_flo(path)
        self._check_size(path, flow, (*self.shape, 2), "an (H, W, 2) flow")
        with np.errstate(invalid="ignore"):
            unknown = ~np.all(np.isfinite(flow) & (np.abs(flow) < 1e9), axis=2)
        flow[unknown] = np.nan
        return flow

    def read_gt_mixed(self, view: str, index: int) -> np.ndarray:
        """Mask (H, W) bool of pixels whose blur mixes differently moving surfaces."""
        path = self.gt_path("mixed", view, index)
        mask = read_mask(path)
        self._check_size(path, mask, (*self.shape,), "an (H, W) mask")
        return mask

    def _read_image(self, path: Path, *, linear: bool) -> np.ndarray:
        image = read_png(path)
        expected = (*self.shape, 3) if self.channels == 3 else self.shape
        self._check_size(path, image, expected, "an image")
        if linear and self.info.color == "srgb":
            image = srgb_to_linear(image)
        return image

    def _check_size(self, path: Path, array: np.ndarray, expected: tuple, what: str) -> None:
        if array.shape != tuple(expected):
            raise InputError(
                f"{path} has shape {array.shape}, expected {what} of shape {tuple(expected)} "
                f"like the scene's frames"
            )


def check_frame_size(width: int, height: int, where) -> None:
    """Fail unless frames of ``width x height`` are large enough to deblur (``MIN_FRAME_SIZE``)."""
    if min(width, height) < MIN_FRAME_SIZE:
        raise InputError(
            f"{where} is {width}x{height}: frames must be at least "
            f"{MIN_FRAME_SIZE}x{MIN_FRAME_SIZE} pixels"
        )


def _describe(info: PngInfo) -> str:
    kind = "grey" if info.channels == 1 else "RGB"
    return f"{info.width}x{info.height} {info.bit_depth}-bit {kind}"


def open_scene(path: str | os.PathLike) -> Scene:
    """Open and validate the scene folder at ``path``."""
    return Scene(path)


# --------------------------------------------------------------------------- writing


def _existing_frame_shape(root: Path) -> tuple[int, int, int] | None:
    """(H, W, channels) of a frame already in the scene at ``root``, if any."""
    for view in VIEWS:
        folder = root / view
        if not folder.is_dir():
            continue
        with os.scandir(folder) as scan:
            names = sorted(entry.name for entry in scan if entry.is_file())
        for name in names:
            if _WRITTEN_NAME.match(name):
                header = read_png_header(folder / name)
                return header.height, header.width, header.channels
    return None


class SceneWriter:
    """Writes a scene folder, one file at a time and each atomically.

    ``root`` may not exist yet, be empty, or already be a scene (hold
    ``camera.json``), so an interrupted run can resume; a folder holding anything
    else, or a scene with a different ``camera.json``, needs ``overwrite=True``.
    ``protect`` lists input scene folders that must never be written into.
    Existing files are never deleted. Frames and ground truth are named as ``numbering``
    names them (a scene's ``NNNNNN`` by default; a source's own names keep them in results).
    """

    def __init__(
        self,
        root: str | os.PathLike,
        info: CameraInfo,
        *,
        overwrite: bool = False,
        protect=(),
        numbering: FrameNumbering = SCENE_NUMBERING,
    ):
        if not isinstance(info, CameraInfo):
            raise InputError(f"info must be a CameraInfo, got {type(info).__name__}")
        root = Path(root)
        resolved = root.resolve()
        for item in [protect] if isinstance(protect, str | os.PathLike) else protect:
            guarded = Path(item).resolve()
            if resolved == guarded or guarded in resolved.parents or resolved in guarded.parents:
                raise InputError(
                    f"refusing to write output scene {root} into or around input {item}: "
                    "choose a separate output folder"
                )
        if root.exists() and not root.is_dir():
            raise InputError(f"output scene {root} exists and is not a folder")
        camera_file = root / "camera.json"
        text = _camera_json(info)
        if root.is_dir() and not overwrite:
            if camera_file.is_file():
                try:
                    same = _camera_json(read_camera(camera_file)) == text
                except InputError:
                    same = False
                if not same:
                    raise InputError(
                        f"{camera_file} holds a different camera than this output; "
                        "choose another folder or pass overwrite=True"
                    )
            elif any(not name.startswith(".") for name in os.listdir(root)):
                raise InputError(
                    f"output folder {root} is not empty and not a scene (no camera.json); "
                    "choose another folder or pass overwrite=True"
                )
        self.root = root
        self.info = info
        self.numbering = numbering
        self._shape = None if overwrite else _existing_frame_shape(root)
        for view in VIEWS:
            (root / view).mkdir(parents=True, exist_ok=True)
        if not camera_file.is_file() or camera_file.read_bytes() != text.encode("utf-8"):
            write_camera(camera_file, info)

    def __repr__(self) -> str:
        return f"SceneWriter({str(self.root)!r}, color={self.info.color!r})"

    def path_for(self, kind: str, view: str, index: int) -> Path:
        """Path of ``kind`` ('frame', 'sharp', 'disparity', 'flow', 'mixed') for a frame."""
        return scene_path(self.root, kind, view, index, numbering=self.numbering)

    def write_frame(
        self, view: str, index: int, image: np.ndarray, *, bit_depth: int = 16, linear: bool = True
    ) -> Path:
        """Write frame ``index`` of ``view``; a linear image is sRGB-encoded if the scene is."""
        return self._write_image("frame", view, index, image, bit_depth=bit_depth, linear=linear)

    def write_gt_sharp(
        self, view: str, index: int, image: np.ndarray, *, bit_depth: int = 16, linear: bool = True
    ) -> Path:
        """Write the sharp ground-truth image, encoded like :meth:`write_frame`."""
        return self._write_image("sharp", view, index, image, bit_depth=bit_depth, linear=linear)

    def write_gt_disparity(self, view: str, index: int, disparity: np.ndarray) -> Path:
        """Write an (H, W) disparity in pixels; NaN (unknown) is stored as inf."""
        disparity = np.asarray(disparity, dtype=np.float32)
        if disparity.ndim != 2:
            raise InputError(f"disparity must have shape (H, W), got {disparity.shape}")
        path = self.path_for("disparity", view, index)
        self._check_shape(path, disparity.shape)
        return write_pfm(
            path,
            np.where(np.isnan(disparity), np.float32(np.inf), disparity),
        )

    def write_gt_flow(self, view: str, index: int, flow: np.ndarray) -> Path:
        """Write an (H, W, 2) flow; pixels with a NaN component are stored as unknown (1e10)."""
        flow = np.array(flow, dtype=np.float32)
        if flow.ndim != 3 or flow.shape[2] != 2:
            raise InputError(f"flow must have shape (H, W, 2), got {flow.shape}")
        path = self.path_for("flow", view, index)
        self._check_shape(path, flow.shape)
        flow[np.any(np.isnan(flow), axis=2)] = FLOW_UNKNOWN
        return write_flo(path, flow)

    def write_gt_mixed(self, view: str, index: int, mask: np.ndarray) -> Path:
        """Write the (H, W) mask of pixels mixing differently moving surfaces."""
        path = self.path_for("mixed", view, index)
        self._check_shape(path, np.shape(mask))
        return write_mask(path, mask)

    def _check_shape(self, path: Path, shape: tuple, *, channels: bool = False) -> None:
        """Keep every written file the size (and frames and sharp images the channels)
        of the first frame written or already on disk."""
        if self._shape is None:
            if not channels:
                return
            self._shape = tuple(shape)
        expected = self._shape if channels else self._shape[:2]
        if tuple(shape[: len(expected)]) != expected:
            raise InputError(
                f"cannot write {path} with shape {tuple(shape)}: the scene's frames have "
                f"shape {expected}"
            )

    def _write_image(self, kind, view, index, image, *, bit_depth, linear) -> Path:
        path = self.path_for(kind, view, index)
        image = _check_image(image)
        shape = image.shape if image.ndim == 3 else (*image.shape, 1)
        self._check_shape(path, shape, channels=True)
        if linear and self.info.color == "srgb":
            image = linear_to_srgb(np.clip(image, 0.0, 1.0))
        return write_png(path, image, bit_depth=bit_depth)
