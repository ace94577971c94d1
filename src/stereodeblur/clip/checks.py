"""Checks of a clip run before its first frame starts: arguments, frames, input files, ground truth.

Everything a run will read is checked up front, so a bad file stops the run before any work
is done and before anything is written, with a one-line
:class:`~stereodeblur.errors.InputError` naming the file and what was expected.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from ..errors import InputError
from ..geometry.camera import VIEWS
from ..io.gt_checks import check_gt_file


def check_arguments(views, workers, scheduler, settings, point_cloud: bool) -> tuple[str, ...]:
    """The views as a tuple; an InputError for a bad view, worker count or combination."""
    views = tuple(dict.fromkeys(views))
    if not views or any(v not in VIEWS for v in views):
        raise InputError(f"views must be 'left' and/or 'right', got {views}")
    if workers is not None and scheduler is not None:
        raise InputError("give either workers or a scheduler, not both")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise InputError(f"workers must be an integer of at least 1, got {workers!r}")
    if point_cloud and settings.motion_source == "initial-flow":
        raise InputError(
            "point clouds need scene-flow geometry: use motion_source 'sceneflow' or 'gt'"
        )
    return views


def neighbours(index: int, num_frames: int) -> list[int]:
    """Frames read to deblur frame ``index``: itself and its neighbour."""
    from ..pipeline import neighbour_of

    return sorted({index, neighbour_of(index, num_frames)})


def check_inputs(scene, views: Iterable[str], frames: Iterable[int], settings) -> None:
    """Check that every frame file the run will read is there and readable.

    The scene-flow motion reads both views of a frame and of its neighbour; the other
    motion sources read the deblurred views only.
    """
    from ..io.readable import check_readable

    read_views = VIEWS if settings.motion_source == "sceneflow" else tuple(views)
    indices = sorted({i for index in frames for i in neighbours(index, scene.num_frames)})
    check_readable(scene, read_views, indices)


# --------------------------------------------------------------------------- ground truth


def gt_files(scene, index: int, settings, views=VIEWS) -> list[Path]:
    """The ground-truth files deblurring ``views`` of frame ``index`` reads."""
    from ..pipeline import gt_needs

    return [Path(p) for p in gt_needs(scene, index, settings, views=views)]


def check_gt_files(scene, frames: list[int], settings, views) -> None:
    """An InputError naming the first ground-truth file (e.g. a gt/mixed mask) that
    ``frames`` need and that is missing."""
    for index in frames:
        for path in gt_files(scene, index, settings, views):
            if not path.is_file():
                raise InputError(f"frame {index} needs {path}, which is missing")


def select_gt_frames(scene, frames: list[int], explicit: bool, settings, views=VIEWS):
    """Frames whose ground-truth motion is there, and those without it.

    A one-line InputError when no frame has it, or (when the frames were asked for) any
    lacks it, or a file it needs is unknown everywhere.
    """
    if not any(scene.has_gt("disparity", "left", i) for i in frames):
        raise InputError(
            f"ground-truth motion needs ground truth, which {scene.root} does not have for frames "
            f"{frames[0]}..{frames[-1]}: use the estimated scene flow"
        )
    ok, missing, first_missing = [], [], None
    for index in frames:
        lacking = [p for p in gt_files(scene, index, settings, views) if not p.is_file()]
        (missing if lacking else ok).append(index)
        if lacking and first_missing is None:
            first_missing = (index, lacking[0])
    if missing and (explicit or not ok):
        index, path = first_missing
        raise InputError(f"ground-truth motion: frame {index} needs {path}, which is missing")
    for path in sorted({p for index in ok for p in gt_files(scene, index, settings, views)}):
        check_gt_file(path)
    return ok, missing
