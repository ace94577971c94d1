"""A clip run: check everything, lock the output, run the tasks, log them, clean up.

Order of a run: the arguments, the frames, every input file and (with ground-truth motion)
every ground-truth file are checked, then the output (:func:`stereodeblur.io.outputs.
check_output`), all before anything is written. The output folder is then locked for the
whole run (``OUT/.lock``): a second run into it is refused. Finished frames are skipped,
temporaries a killed run left are removed, the remaining tasks run on an executor and every
view's record goes to the run log as it arrives.

An interrupted run (Ctrl-C, SIGTERM) logs the interruption and keeps every finished frame;
it removes only what it created itself: its temporaries, and the output folder when it
created that folder and nothing else is in it. A write the storage refuses (no space left,
quota, read-only: :class:`~stereodeblur.errors.StorageError`) stops the run the same way, at
once: no further frame is computed, the half-written temporaries are removed, and the
StorageError is raised; the same run resumes once there is room.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import socket
import threading
import time
import uuid
import warnings
from collections.abc import Iterator
from pathlib import Path

from ..errors import InputError, StorageError
from ..geometry.camera import VIEWS
from ..io.outputs import (
    LOCK_NAME,
    MARKER,
    RUN_LOG,
    OutputLock,
    check_output,
    mark_output,
    writing_errors,
)
from ..io.protocol import StereoScene
from ..io.sources import SourceSpec
from ..pipeline.window import views_read
from .checks import check_arguments, check_gt_files, check_inputs, select_gt_frames
from .executors import DaskExecutor, default_workers, make_executor
from .job import ClipJob, ClipReport, FrameRecord, is_finished, make_tasks, remove_temporaries
from .progress import make_progress
from .runlog import RunLogWriter, read_run_log
from .worker import captured_stderr

# What a run puts into a folder it created, besides frames: removed again when no frame was kept.
_OWN_FILES = ("camera.json", RUN_LOG, LOCK_NAME, MARKER)
_OWN_FOLDERS = ("pointcloud/left", "pointcloud/right", "pointcloud", *VIEWS)


class Terminated(KeyboardInterrupt):
    """The run was asked to stop by SIGTERM; handled like Ctrl-C."""


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` in the main thread while the run lasts."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated("SIGTERM")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@dataclasses.dataclass(frozen=True)
class _Plan:
    """What the checks found: the open scene, the frames to run and the notes for the log."""

    scene: StereoScene
    frames: tuple[int, ...]
    warnings: tuple[str, ...]  # for the user: the source's warnings, frames left out
    notes: tuple[str, ...]  # for the log: the warnings and the libraries' messages


def _select_frames(scene, frames, settings, views) -> tuple[list[int], list[int]]:
    """The frames to run and (with ground-truth motion) those left out for lack of it."""
    explicit = frames is not None
    last = scene.num_frames - 1
    if frames is None:
        frames = range(scene.num_frames)
    if isinstance(frames, range) and frames:  # checked before it is expanded
        low, high = sorted((frames[0], frames[-1]))
        if low < 0 or high > last:
            raise InputError(f"frames must lie in 0..{last}, got {low}..{high}")
    frames = sorted(set(frames))
    bad = [f for f in frames if isinstance(f, bool) or not isinstance(f, int) or not 0 <= f <= last]
    if bad or not frames:
        raise InputError(f"frames must lie in 0..{last}, got {bad[:5] or 'none'}")
    without_gt = []
    if settings.motion_source == "gt":
        frames, without_gt = select_gt_frames(scene, frames, explicit, settings, views)
    else:
        check_gt_files(scene, frames, settings, views)
    return frames, without_gt


def _prepare(spec: SourceSpec, frames, views, settings) -> _Plan:
    """Open the source and check every file the run reads; library noise goes to the notes."""
    messages: list[str] = []
    with captured_stderr(messages), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = spec.open()
        read = views_read(settings, views)
        frames, without_gt = _select_frames(scene, frames, settings, read)
        check_inputs(scene, read, frames, settings)
    warned = [*scene.warnings]
    warned += [f"frame {i}: no ground-truth motion, not deblurred" for i in without_gt]
    notes = [*warned, *(str(w.message) for w in caught), *messages]
    return _Plan(scene, tuple(frames), tuple(warned), tuple(dict.fromkeys(notes)))


def _inputs(spec: SourceSpec, scene) -> list[str]:
    paths = [*spec.paths, *(str(p) for p in scene.paths)]
    return paths + ([spec.calib] if spec.calib else [])


def _make_output(output: Path) -> bool:
    """Create ``output`` (and its parents) if needed; whether this run created ``output``."""
    with writing_errors(output):
        output.parent.mkdir(parents=True, exist_ok=True)
        try:
            output.mkdir()
        except FileExistsError:
            if not output.is_dir():
                raise
            return False
    return True


def _only_ours(output: Path) -> bool:
    """Whether ``output`` holds nothing but what a run puts there besides frames."""
    for folder in [output, *(output / name for name in _OWN_FOLDERS)]:
        if not folder.exists() and not folder.is_symlink():
            continue
        if folder.is_symlink() or not folder.is_dir():
            return False
        for entry in folder.iterdir():
            relative = entry.relative_to(output).as_posix()
            if relative not in _OWN_FILES + _OWN_FOLDERS:
                return False
    return True


def _remove_if_only_ours(output: Path) -> bool:
    """Remove ``output`` when it holds only what a run puts there besides frames."""
    if not _only_ours(output):
        return False
    for name in _OWN_FILES:
        with contextlib.suppress(FileNotFoundError, IsADirectoryError):
            (output / name).unlink()
    for name in _OWN_FOLDERS:
        with contextlib.suppress(OSError):  # a folder that is not empty stays
            (output / name).rmdir()
    try:
        output.rmdir()
    except OSError:
        return False
    return True


def _check_identity(output: Path, identity: dict, overwrite: bool) -> list[str]:
    """Problems of the existing run log; an InputError when it belongs to other input or
    settings (unless ``overwrite``)."""
    contents = read_run_log(output / RUN_LOG)
    previous = contents.last_start()
    if previous is not None and not overwrite:
        before = {k: previous.get(k) for k in identity}
        if before != identity:
            changed = [k for k in identity if before[k] != identity[k]]
            raise InputError(
                f"{output} holds frames deblurred from another {' and '.join(changed)} "
                f"(see {output / RUN_LOG}): overwrite them or choose another folder"
            )
    return list(contents.problems)


def _start_event(plan, job, identity, tasks, skipped, workers, scheduler, command, notes):
    return {
        "event": "start",
        **identity,
        "source_kind": plan.scene.kind,
        "output": job.output,
        "frames": list(plan.frames),
        "views": sorted({v for _, views in tasks for v in views} | {v for _, v in skipped}),
        "tasks": len(tasks),
        "skipped": len(skipped),
        "workers": workers,
        "scheduler": scheduler,
        "point_cloud": job.point_cloud,
        "command": command,
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "warnings": notes,
    }


def _run_tasks(log, executor, job, tasks, bar, on_frame, stages) -> list[FrameRecord]:
    records: list[FrameRecord] = []
    runner = executor.run(job, tasks, stages) if tasks else iter(())
    try:
        for record in runner:
            records.append(record)
            log.write(record.to_json())
            if bar is not None:
                bar.update(record)
            if on_frame is not None:
                on_frame(record)
            if record.storage_errno is not None:  # the disk is full: no further frame
                number = record.storage_errno
                raise StorageError(number, os.strerror(number), record.storage_path)
    except BaseException as exc:
        reason = "SIGTERM" if isinstance(exc, Terminated) else type(exc).__name__
        if isinstance(exc, StorageError):
            reason = str(exc)
        with contextlib.suppress(StorageError):  # the log may be on the disk that is full
            log.write({"event": "interrupted", "reason": reason, "done": len(records)})
        raise
    finally:
        close = getattr(runner, "close", None)
        if close is not None:
            close()
        if bar is not None:
            bar.close()
    return records


def _stage_progress(progress):
    """Where the stages' progress of each frame goes: a callable ``progress`` gets it; a bar
    (True, a stream) shows frames only."""
    if progress is True or not progress or hasattr(progress, "write"):
        return None
    return progress if callable(progress) else None


def _run_locked(spec, plan, output: Path, options: dict) -> ClipReport:
    """The run proper, with the output locked."""
    from ..io.scene import SceneWriter

    settings, views = options["settings"], options["views"]
    identity = {"source": list(spec.paths), "settings": dataclasses.asdict(settings)}
    identity = json.loads(json.dumps(identity, default=str))  # as the log stores it
    notes = list(plan.notes) + _check_identity(output, identity, options["overwrite"])
    SceneWriter(
        output,
        plan.scene.info,
        overwrite=options["overwrite"],
        protect=_inputs(spec, plan.scene),
        numbering=plan.scene.numbering,
    )
    mark_output(output, "deblur")
    notes += [f"removed the half-written {p}" for p in remove_temporaries(output)]
    job = ClipJob(
        spec,
        str(output),
        settings,
        options["point_cloud"],
        run_id=uuid.uuid4().hex,
        shape=tuple(plan.scene.shape),
        numbering=plan.scene.numbering,
    )
    pairs = [(i, v) for i in plan.frames for v in views]
    skipped = [] if options["overwrite"] else [p for p in pairs if is_finished(job, *p)]
    tasks = make_tasks(plan.frames, views, set(skipped))
    workers, scheduler = options["workers"], options["scheduler"]
    if scheduler is None and workers is None:
        workers = default_workers(
            plan.scene.shape, num_samples=settings.num_samples, num_tasks=max(1, len(tasks))
        )
    executor = options.get("executor") or make_executor(workers, scheduler)
    todo = sum(len(v) for _, v in tasks)
    bar = make_progress(options["progress"], todo, len(skipped), plan.scene.numbering)
    start = time.perf_counter()
    with RunLogWriter(output / RUN_LOG) as log:
        log.write(
            _start_event(
                plan, job, identity, tasks, skipped, workers, scheduler, options["command"], notes
            )
        )
        try:
            stages = _stage_progress(options["progress"])
            records = _run_tasks(log, executor, job, tasks, bar, options["on_frame"], stages)
        except StorageError:  # the executor has stopped: remove what its frames left
            remove_temporaries(output)
            raise
        seconds = time.perf_counter() - start
        done = sum(r.status == "done" for r in records)
        log.write(
            {
                "event": "end",
                "done": done,
                "failed": len(records) - done,
                "skipped": len(skipped),
                "seconds": round(seconds, 3),
                "frames_per_minute": round(done / seconds * 60, 3) if seconds > 0 else None,
            }
        )
    return ClipReport(
        output, output / RUN_LOG, tuple(records), tuple(skipped), seconds, plan.warnings
    )


def deblur_clip(
    source: SourceSpec,
    output,
    *,
    frames=None,
    views=VIEWS,
    settings=None,
    overwrite: bool = False,
    point_cloud: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress=True,
    on_frame=None,
    command: list[str] | None = None,
) -> ClipReport:
    """Deblur frames of both views of a clip and write them as a scene at ``output``.

    Parameters
    ----------
    source : SourceSpec
        The input (see :func:`stereodeblur.io.sources.open_source`).
    output : path
        Output scene folder (see :mod:`stereodeblur.io.outputs` for what is refused).
    frames : iterable of int, optional
        Frames to deblur; default all (with ground-truth motion: all that have it).
    views : iterable of {'left', 'right'}
    settings : DeblurSettings, optional
    overwrite : bool
        Deblur finished frames again (and write into a non-empty folder that is no scene).
    point_cloud : bool
        Also write ``pointcloud/VIEW/NNNNNN.ply`` per frame.
    workers : int, optional
        Local worker processes (default :func:`default_workers`); 1 runs in this process.
    scheduler : str, optional
        Address of a Dask scheduler, ``tcp://HOST:PORT``; excludes ``workers``.
    progress : bool, file or callable
        Progress bar on stderr (True), on a given stream, ``Progress`` reports to a callable
        (the frames finished, and the stages of each frame, also from worker processes), or
        none (False).
    on_frame : callable, optional
        Called with every :class:`FrameRecord` as it arrives.
    command : list of str, optional
        The command line, for the log.

    Returns
    -------
    ClipReport
        Its ``log`` is None when the run removed the output folder it had created (no frame
        was written).

    Raises
    ------
    InputError
        For bad arguments, inputs or outputs, before anything is written; also when another
        run holds the output.
    KeyboardInterrupt
        On Ctrl-C or SIGTERM (:class:`Terminated`), after logging the interruption.
    """
    from ..pipeline import DeblurSettings

    settings = settings or DeblurSettings()
    spec = source if isinstance(source, SourceSpec) else SourceSpec.from_arguments(source)
    views = check_arguments(views, workers, scheduler, settings, point_cloud)
    plan = _prepare(spec, frames, views, settings)
    subfolders = [*VIEWS, *(["pointcloud/left", "pointcloud/right"] if point_cloud else [])]
    check_output(
        output,
        _inputs(spec, plan.scene),
        subfolders=subfolders,
        command="deblur",
        in_place=(RUN_LOG, LOCK_NAME),
    )
    executor = DaskExecutor(scheduler) if scheduler is not None else None
    options = {
        "settings": settings,
        "views": views,
        "overwrite": overwrite,
        "point_cloud": point_cloud,
        "workers": workers,
        "scheduler": scheduler,
        "executor": executor,
        "progress": progress,
        "on_frame": on_frame,
        "command": command,
    }
    try:
        if executor is not None:
            executor.connect()  # an unreachable scheduler is refused before anything is written
        return _run_in(spec, plan, Path(os.path.abspath(output)), options)
    finally:
        if executor is not None:
            executor.close()


def _run_in(spec: SourceSpec, plan: _Plan, output: Path, options: dict) -> ClipReport:
    """Create and lock ``output``, run, and clean up what this run created and did not use."""
    created = _make_output(output)
    lock = OutputLock(output)
    lock.__enter__()  # refused: the folder (even one this run just created) is another run's
    report = None
    try:
        with _sigterm_as_interrupt():
            report = _run_locked(spec, plan, output, options)
    finally:
        # A run that created the folder and recorded no frame leaves nothing behind; with
        # failed frames the log stays, to say why.
        if created and (report is None or not report.records):
            if _remove_if_only_ours(output) and report is not None:
                report = dataclasses.replace(report, log=None)
        lock.release()
    return report
