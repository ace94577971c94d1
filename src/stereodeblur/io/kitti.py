"""KITTI folders as stereo clips: scene flow 2015, stereo/flow 2012 and raw recordings.

Layouts
-------
Scene flow 2015 (``kitti-2015``)::

    ROOT/image_2/NNNNNN_XX.png  ROOT/image_3/NNNNNN_XX.png   left / right (cameras 2, 3)
    ROOT/calib_cam_to_cam/NNNNNN.txt                           P_rect_02, P_rect_03, S_rect_02

Stereo/flow 2012 (``kitti-2012``)::

    ROOT/image_0/NNNNNN_XX.png  ROOT/image_1/NNNNNN_XX.png   grey cameras 0, 1 (P0, P1)
    ROOT/colored_0/...          ROOT/colored_1/...           colour cameras 2, 3 (P2, P3)
    ROOT/calib/NNNNNN.txt

``NNNNNN`` is the sequence and ``XX`` the frame (``10`` and ``11`` in the base
benchmarks, ``00`` to ``20`` in the multi-view extensions); a sequence's frames
must be numbered contiguously. Results keep these names and frames are selected by
their ``XX`` (:mod:`.numbering`). Raw recordings (``kitti-raw``)::

    DRIVE/image_02/data/NNNNNNNNNN.png  DRIVE/image_03/data/...   (or image_00 / image_01)
    DRIVE/image_02/timestamps.txt                                 one time per frame
    DRIVE/calib_cam_to_cam.txt  or  DRIVE/../calib_cam_to_cam.txt

Their frames are numbered by the file, from 0 (``0000000042`` is frame 42).

Calibration files hold lines ``key: numbers``. The stereo camera is that of
:func:`~stereodeblur.io.calibration.stereo_from_projections`: ``K`` from the left
projection matrix, the baseline from the difference of the two projection
matrices' translations (KITTI's ``P_rect_0i = K [I | t_i]``). The benchmarks
are recorded at 10 frames per second; raw recordings take the frame rate from
the median interval of their timestamps. KITTI states no exposure time. Its PNGs are camera
output, sRGB-encoded (:data:`~stereodeblur.io.frame_source.CAMERA_OUTPUT_COLOR`) unless
``color`` says otherwise: frames are linearised on reading.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from ..errors import InputError
from .calibration import stereo_from_projections
from .frame_source import CAMERA_OUTPUT_COLOR, FrameSource, camera_info
from .intrinsics import check_intrinsics
from .numbering import FrameNumbering
from .png import read_png, read_png_header
from .scene import check_frame_size

KITTI_FRAME_RATE = 10.0
_BENCHMARK_NAME = re.compile(r"^(\d{6})_(\d{2})\.png$")
_RAW_NAME = re.compile(r"^(\d{10})\.png$")
# A raw drive's frames, 0000000000.png, 0000000001.png, ...
RAW_NUMBERING = FrameNumbering(digits=10)
# kind -> list of (left folder, right folder, calibration folder, left key, right key, size key)
_BENCHMARK_LAYOUTS = {
    "kitti-2015": [
        ("image_2", "image_3", "calib_cam_to_cam", "P_rect_02", "P_rect_03", "S_rect_02")
    ],
    "kitti-2012": [
        ("image_0", "image_1", "calib", "P0", "P1", None),
        ("colored_0", "colored_1", "calib", "P2", "P3", None),
    ],
}
_RAW_LAYOUTS = [
    ("image_02", "image_03", "P_rect_02", "P_rect_03", "S_rect_02"),
    ("image_00", "image_01", "P_rect_00", "P_rect_01", "S_rect_00"),
]


def detect_kitti(root) -> str | None:
    """'kitti-2015', 'kitti-2012', 'kitti-raw' or None for a folder of another kind."""
    root = Path(root)
    if (root / "image_2").is_dir() and (root / "image_3").is_dir():
        return "kitti-2015"
    for left, right, *_ in _BENCHMARK_LAYOUTS["kitti-2012"]:
        if (root / left).is_dir() and (root / right).is_dir():
            return "kitti-2012"
    for left, right, *_ in _RAW_LAYOUTS:
        if (root / left / "data").is_dir() and (root / right / "data").is_dir():
            return "kitti-raw"
    return None


# --------------------------------------------------------------------------- calibration


def read_kitti_calibration(path) -> dict[str, tuple[str, int]]:
    """Entries of a KITTI calibration file: key -> (value text, line number)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"KITTI calibration file not found: {path}")
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path} as text: {exc}") from None
    entries: dict[str, tuple[str, int]] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        key, colon, value = line.partition(":")
        key = key.strip()
        if not colon or not key or " " in key:
            raise InputError(
                f"{path}, line {number}: expected 'key: numbers', got {line.strip()[:40]!r}"
            )
        if key in entries:
            raise InputError(
                f"{path}: key {key!r} appears twice (lines {entries[key][1]} and {number})"
            )
        entries[key] = (value.strip(), number)
    return entries


def kitti_numbers(entries, key: str, count: int, path) -> np.ndarray:
    """The ``count`` numbers of ``key`` in a KITTI calibration file."""
    if key not in entries:
        raise InputError(f"{path}: missing {key!r}")
    text, line = entries[key]
    try:
        values = np.array([float(v) for v in text.split()], dtype=np.float64)
    except ValueError:
        bad = next(v for v in text.split() if not _is_number(v))
        raise InputError(f"{path}, line {line}: {key!r} holds {bad[:20]!r}, not a number") from None
    if values.size != count:
        raise InputError(
            f"{path}, line {line}: {key!r} has {values.size} numbers, expected {count}"
        )
    if not np.all(np.isfinite(values)):
        raise InputError(f"{path}, line {line}: {key!r} has non-finite numbers")
    return values


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def kitti_camera(path, left_key: str, right_key: str):
    """Stereo camera from the rectified projection matrices ``left_key`` / ``right_key``."""
    entries = read_kitti_calibration(path)
    P_left = kitti_numbers(entries, left_key, 12, path).reshape(3, 4)
    P_right = kitti_numbers(entries, right_key, 12, path).reshape(3, 4)
    return stereo_from_projections(P_left, P_right, f"{path}: {left_key}/{right_key}"), entries


def _rectified_size(entries, key, path) -> tuple[int, int] | None:
    if key is None or key not in entries:
        return None
    values = kitti_numbers(entries, key, 2, path)
    return int(round(values[0])), int(round(values[1]))


# --------------------------------------------------------------------------- timestamps


def read_timestamps(path) -> np.ndarray:
    """Seconds since the first line of every line ``YYYY-MM-DD HH:MM:SS.fffffffff`` of a KITTI
    timestamps file (relative, to keep nanoseconds in float64)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"KITTI timestamps file not found: {path}")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path} as text: {exc}") from None
    whole_seconds, fractions = [], []
    for number, line in enumerate(lines, start=1):
        line = line.strip()
        if not line:
            continue
        match = re.fullmatch(r"(\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2})(\.\d+)?", line)
        try:
            if match is None:
                raise ValueError
            whole = datetime.strptime(match.group(1), "%Y-%m-%d %H:%M:%S").timestamp()
        except ValueError:
            raise InputError(
                f"{path}, line {number}: expected a time like 2011-09-26 13:02:25.964389445, "
                f"got {line[:40]!r}"
            ) from None
        whole_seconds.append(int(whole))
        fractions.append(float(match.group(2) or 0.0))
    if len(fractions) < 2:
        raise InputError(f"{path}: needs at least two timestamps, found {len(fractions)}")
    seconds = np.array(whole_seconds) - whole_seconds[0] + np.array(fractions)
    steps = np.diff(seconds)
    if np.any(steps <= 0):
        bad = int(np.argmax(steps <= 0)) + 2
        raise InputError(f"{path}, line {bad}: timestamps must increase")
    return seconds


# --------------------------------------------------------------------------- the source


class KittiSource(FrameSource):
    """A KITTI sequence or raw drive read frame by frame from its PNG files."""

    def __init__(
        self, *, kind, root, name, files, info, shape, channels, paths, warnings=(), numbering
    ):
        self.kind = kind
        self._files = files
        super().__init__(
            root=root,
            name=name,
            paths=paths,
            info=info,
            num_frames=len(files["left"]),
            shape=shape,
            channels=channels,
            warnings=warnings,
            numbering=numbering,
        )

    def frame_path(self, view: str, index: int) -> Path:
        """The PNG file of frame ``index`` of ``view``."""
        return self._files[view][self._check(view, index)]

    def frame_label(self, view: str, index: int) -> str:
        return str(self.frame_path(view, index))

    def _read_stored(self, view: str, index: int) -> np.ndarray:
        return read_png(self._files[view][index])


def _benchmark_frames(
    folder: Path, sequence: str | None, root: Path
) -> tuple[str, list[Path], FrameNumbering]:
    """The sequence to read, its frame files (sorted and checked to be contiguous) and their
    numbering (``NNNNNN_XX``: the frame number ``XX`` within the sequence)."""
    found: dict[str, dict[int, Path]] = {}
    for path in folder.iterdir():
        match = _BENCHMARK_NAME.match(path.name)
        if match and path.is_file():
            found.setdefault(match.group(1), {})[int(match.group(2))] = path
    if not found:
        raise InputError(f"no frames in {folder}: expected files like 000000_10.png")
    if sequence is None:
        if len(found) > 1:
            names = sorted(found)
            raise InputError(
                f"{root} holds {len(found)} sequences ({names[0]} .. {names[-1]}): "
                "choose one with sequence",
                parameter="sequence",
            )
        sequence = next(iter(found))
    else:
        try:
            sequence = f"{int(sequence):06d}"
        except ValueError:
            raise InputError(
                f"sequence must be a number like 5 or 000005, got {sequence!r}",
                parameter="sequence",
            ) from None
        if sequence not in found:
            raise FileNotFoundError(f"no sequence {sequence} in {folder} (no {sequence}_XX.png)")
    frames = found[sequence]
    numbers = sorted(frames)
    for expected in range(numbers[0], numbers[-1] + 1):
        if expected not in frames:
            raise InputError(
                f"missing frame {folder / f'{sequence}_{expected:02d}.png'}: the frames of "
                f"sequence {sequence} must be numbered contiguously"
            )
    numbering = FrameNumbering(first=numbers[0], digits=2, prefix=f"{sequence}_")
    return sequence, [frames[n] for n in numbers], numbering


def _raw_frames(folder: Path) -> list[Path]:
    numbers = {}
    for path in folder.iterdir():
        match = _RAW_NAME.match(path.name)
        if match and path.is_file():
            numbers[int(match.group(1))] = path
    if not numbers:
        raise InputError(f"no frames in {folder}: expected files like 0000000000.png")
    for expected in range(len(numbers)):
        if expected not in numbers:
            raise InputError(
                f"missing frame {folder / f'{expected:010d}.png'}: frames must be numbered "
                "contiguously from 0000000000"
            )
    return [numbers[n] for n in range(len(numbers))]


def _check_headers(files: dict[str, list[Path]]):
    """The first frames of both views have the same size and type; returns the header.

    Every other frame is checked by :func:`~stereodeblur.io.readable.check_readable`
    before a run, or when it is read.
    """
    first = read_png_header(files["left"][0])
    path = files["right"][0]
    header = read_png_header(path)
    if (header.width, header.height, header.channels) != (
        first.width,
        first.height,
        first.channels,
    ):
        raise InputError(
            f"{path} is {header.width}x{header.height} with {header.channels} channel(s), "
            f"expected {first.width}x{first.height} with {first.channels} like "
            f"{files['left'][0]}"
        )
    return first


@dataclass(frozen=True)
class _Layout:
    """Where one KITTI sequence or drive keeps its frames and calibration."""

    name: str
    files: dict[str, list[Path]]
    calib_path: Path
    keys: tuple[str, str, str | None]  # left and right projection, rectified size
    data_dirs: tuple[Path, Path]
    numbering: FrameNumbering
    frame_rate: float = KITTI_FRAME_RATE
    warnings: tuple[str, ...] = ()


def _right_files(left: list[Path], folder: Path) -> list[Path]:
    right = [folder / p.name for p in left]
    for path in right:
        if not path.is_file():
            raise FileNotFoundError(f"missing frame {path} (the left view has {left[0].name})")
    return right


def _benchmark_layout(root: Path, kind: str, sequence) -> _Layout:
    left_dir, right_dir, calib_dir, *keys = next(
        lay
        for lay in _BENCHMARK_LAYOUTS[kind]
        if (root / lay[0]).is_dir() and (root / lay[1]).is_dir()
    )
    sequence, left, numbering = _benchmark_frames(root / left_dir, sequence, root)
    return _Layout(
        name=f"{root.name}/{sequence}",
        files={"left": left, "right": _right_files(left, root / right_dir)},
        calib_path=root / calib_dir / f"{sequence}.txt",
        keys=tuple(keys),
        data_dirs=(root / left_dir, root / right_dir),
        numbering=numbering,
    )


def _raw_layout(root: Path, frame_rate) -> _Layout:
    left_dir, right_dir, *keys = next(
        lay for lay in _RAW_LAYOUTS if (root / lay[0] / "data").is_dir()
    )
    left = _raw_frames(root / left_dir / "data")
    candidates = [root / "calib_cam_to_cam.txt", root.parent / "calib_cam_to_cam.txt"]
    calib_path = next((p for p in candidates if p.is_file()), None)
    if calib_path is None:
        raise FileNotFoundError(f"KITTI calibration not found: {candidates[0]} or {candidates[1]}")
    source_frame_rate, warnings = KITTI_FRAME_RATE, []
    stamps_path = root / left_dir / "timestamps.txt"
    if stamps_path.is_file() or frame_rate is None:
        stamps = read_timestamps(stamps_path)
        if stamps.size < len(left):
            raise InputError(f"{stamps_path} has {stamps.size} timestamps for {len(left)} frames")
        steps = np.diff(stamps[: len(left)])
        median = float(np.median(steps))
        source_frame_rate = float(f"{1.0 / median:.9g}")  # timestamps: ns, jitter
        gaps = np.flatnonzero(steps > 1.5 * median)
        if gaps.size:
            warnings.append(
                f"{stamps_path}: {gaps.size} gap(s) longer than 1.5 frame intervals "
                f"(first after frame {gaps[0]}): frames were dropped there"
            )
    return _Layout(
        name=root.name,
        files={"left": left, "right": _right_files(left, root / right_dir / "data")},
        calib_path=calib_path,
        keys=tuple(keys),
        data_dirs=(root / left_dir / "data", root / right_dir / "data"),
        numbering=RAW_NUMBERING,
        frame_rate=source_frame_rate,
        warnings=tuple(warnings),
    )


def open_kitti(
    root,
    *,
    kind: str | None = None,
    sequence=None,
    exposure=None,
    frame_rate=None,
    color=None,
    require_exposure: bool = True,
) -> KittiSource:
    """Open a KITTI 2015, 2012 or raw folder (module docstring) as a stereo clip."""
    root = Path(root)
    kind = kind or detect_kitti(root)
    if kind is None:
        raise InputError(f"{root} is not a KITTI folder")
    if kind in _BENCHMARK_LAYOUTS:
        layout = _benchmark_layout(root, kind, sequence)
    else:
        layout = _raw_layout(root, frame_rate)
    first, calib_path = layout.files["left"][0], layout.calib_path
    left_key, right_key, size_key = layout.keys
    header = _check_headers(layout.files)
    check_frame_size(header.width, header.height, first)
    camera, entries = kitti_camera(calib_path, left_key, right_key)
    size = _rectified_size(entries, size_key, calib_path)
    if size is not None and size != (header.width, header.height):
        raise InputError(
            f"{first} is {header.width}x{header.height} but {calib_path} says rectified "
            f"images are {size[0]}x{size[1]} ({size_key}); are these unrectified images?"
        )
    check_intrinsics(camera.K, (header.width, header.height), f"{calib_path}: {left_key}")
    info = camera_info(
        camera,
        f"KITTI folder {root}",
        frame_rate=frame_rate,
        exposure=exposure,
        color=color,
        source_frame_rate=layout.frame_rate,
        source_color=CAMERA_OUTPUT_COLOR,
        require_exposure=require_exposure,
    )
    return KittiSource(
        kind=kind,
        root=root,
        name=layout.name,
        files=layout.files,
        info=info,
        shape=(header.height, header.width),
        channels=header.channels,
        paths=[*layout.data_dirs, calib_path],
        warnings=layout.warnings,
        numbering=layout.numbering,
    )
