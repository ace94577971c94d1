"""The job of a clip run: what every task needs, its outcome, and which results are finished.

A task is one stereo frame: its index and the views to deblur there, deblurred together
(:func:`stereodeblur.pipeline.deblur_stereo_frame`: the motion is computed once). A view's
result is finished when every file it writes exists and is complete: the frame PNG (written
last, through a temporary name and a rename) must start with a valid header of the scene's
size and end with the IEND chunk, so a 0-byte or truncated PNG (damaged from outside) is
deblurred again.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..geometry.camera import VIEWS
from ..io.formats import read_png_header
from ..io.numbering import SCENE_NUMBERING, FrameNumbering
from ..io.sources import SourceSpec

# The last 12 bytes of every complete PNG: the empty IEND chunk with its CRC.
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"
# Temporary names of io.formats' atomic writer: ".NAME.HEX.tmp" (NAME: a frame's, e.g.
# 000005, KITTI's 000005_10 or 0000000042).
_TEMPORARY = re.compile(r"^\.\d[\d_]*\.(png|ply)\.[0-9a-f]+\.tmp$")

Task = tuple[int, tuple[str, ...]]


@dataclass(frozen=True)
class ClipJob:
    """What every task needs: where to read, where to write, how to deblur."""

    source: SourceSpec
    output: str
    settings: object  # DeblurSettings (imported lazily: workers import on demand)
    point_cloud: bool = False
    run_id: str = ""  # sources and writers are cached per process and run
    shape: tuple[int, int] | None = None  # (height, width) of a finished frame
    numbering: FrameNumbering = SCENE_NUMBERING  # the source's frame names, kept by results


@dataclass(frozen=True)
class FrameRecord:
    """Outcome of one view of one task; ``seconds`` is the whole task's wall time."""

    index: int
    view: str
    status: str  # 'done' or 'failed'
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    worker: str = ""
    error: str | None = None
    input_error: bool = False
    details: str | None = None
    alpha: float | None = None  # the prior weight used (chosen per frame with 'auto')
    exposure: float | None = None  # seconds the frame was deblurred for (estimated with 'auto')
    alerts: tuple[str, ...] = ()  # the warnings among them for the user (FrameWarning)
    # Set when the output's storage refused a write (StorageError): the run stops at once.
    storage_errno: int | None = None
    storage_path: str | None = None

    def to_json(self) -> dict:
        data = {"event": "frame", **dataclasses.asdict(self)}
        data["warnings"] = list(self.warnings)
        del data["alerts"]  # among the warnings
        data["seconds"] = round(self.seconds, 3)
        data["timings"] = {k: round(v, 3) for k, v in self.timings.items()}
        return {k: v for k, v in data.items() if v is not None}


@dataclass(frozen=True)
class ClipReport:
    """What a run did: one record per view it ran, and the (frame, view) pairs it skipped.

    ``log`` is the run log, or None when the run left no output folder behind. ``warnings``
    are for the user (e.g. a video pair of unequal length, frames without ground truth); the
    libraries' messages go to the log only.
    """

    output: Path
    log: Path | None
    records: tuple[FrameRecord, ...]
    skipped: tuple[tuple[int, str], ...]
    seconds: float
    warnings: tuple[str, ...] = ()

    @property
    def done(self) -> int:
        return sum(r.status == "done" for r in self.records)

    @property
    def failed(self) -> tuple[FrameRecord, ...]:
        return tuple(r for r in self.records if r.status != "done")


def make_tasks(frames, views: tuple[str, ...], finished: set[tuple[int, str]]) -> list[Task]:
    """One task per frame with the views of it that are not ``finished``."""
    tasks = []
    for index in frames:
        todo = tuple(v for v in views if (index, v) not in finished)
        if todo:
            tasks.append((index, todo))
    return tasks


def frame_outputs(job: ClipJob, index: int, view: str) -> list[Path]:
    """The files a finished view of a task has written; the frame PNG comes last."""
    from ..io.scene import scene_path
    from ..pointcloud import point_cloud_path

    paths = [scene_path(job.output, "frame", view, index, numbering=job.numbering)]
    if job.point_cloud:
        name = job.numbering.name(index)
        paths.insert(0, point_cloud_path(job.output, view, index, name=name))
    return paths


def is_complete_png(path: Path, shape: tuple[int, int] | None = None) -> bool:
    """Whether ``path`` is a whole PNG (valid header, IEND at the end) of ``shape`` (H, W)."""
    try:
        header = read_png_header(path)
        with open(path, "rb") as handle:
            handle.seek(-len(PNG_END), 2)
            tail = handle.read()
    except (InputError, OSError):
        return False
    if shape is not None and (header.height, header.width) != tuple(shape):
        return False
    return tail == PNG_END


def is_finished(job: ClipJob, index: int, view: str) -> bool:
    """Whether every file of (``index``, ``view``) exists and is complete. A symlink is not a
    result (a run writes none): the view is deblurred again and the link replaced."""
    *others, frame = frame_outputs(job, index, view)
    if any(p.is_symlink() for p in [*others, frame]):
        return False
    if not all(p.is_file() and p.stat().st_size > 0 for p in others):
        return False
    return is_complete_png(frame, job.shape)


def remove_temporaries(output: Path) -> list[Path]:
    """Delete the temporary files a killed run left half-written; return them."""
    removed = []
    folders = [output / view for view in VIEWS] + [output / "pointcloud" / v for v in VIEWS]
    for folder in folders:
        if folder.is_dir() and not folder.is_symlink():
            for path in folder.iterdir():
                if _TEMPORARY.match(path.name):
                    path.unlink(missing_ok=True)
                    removed.append(path)
    return removed
