"""Deblur a whole clip: every frame of both views, resumable, in parallel or on a Dask cluster.

Each (frame, view) pair is one task. Frame i uses frames i and i + 1; the last
frame uses i - 1 with the motion reversed (with ``motion_source='gt'`` its ground
truth is read backwards in time, the flow to i - 1 inverted). The right view is
deblurred as its own reference with the same model (:mod:`stereodeblur.pipeline`).

Output
------
``OUT`` is a scene (SCENE_FORMAT.md) with the source's ``camera.json``; a task
writes ``OUT/VIEW/NNNNNN.png`` (16 bit) through a temporary file and a rename,
after ``OUT/pointcloud/VIEW/NNNNNN.ply`` when point clouds are asked for, so a
frame whose PNG exists is finished. Re-running skips finished frames unless
``overwrite``; a killed run loses at most the frames in flight.
``OUT/run-log.jsonl`` gets one JSON object per line, appended by every run:
``{"event": "start", ...}`` (source, settings, frames, workers), one
``{"event": "frame", "index", "view", "status": "done" | "failed", "seconds",
"timings", "warnings", "worker", "error"}`` per task, and ``{"event": "end", ...}``
(or ``"interrupted"``).

Parallelism
-----------
``workers=1`` runs the tasks in this process. ``workers=N`` runs them in N
spawned worker processes, each with ``cores // N`` numba and OpenCV threads; a
worker that dies (killed, out of memory) has its tasks run again in a new pool.
``scheduler='tcp://HOST:PORT'`` sends them to an existing Dask distributed
cluster; workers open the input and write the output themselves, so both paths
must be the same on every worker (a shared file system). Dask runs a task
again on another worker when its worker dies.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import re
import shutil
import socket
import sys
import time
import traceback
import uuid
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..geometry.camera import VIEWS
from ..io.sources import SourceSpec

LOG_NAME = "run-log.jsonl"
MAX_POOL_RESTARTS = 2
DASK_CONNECT_TIMEOUT = 30.0
DASK_RETRIES = 2
# Peak memory of a worker deblurring one 640x480 RGB frame with the paper's 70 samples (about
# 0.6 GB measured, with margin); scaled with pixels and samples for other sizes.
FRAME_MEMORY_640x480 = 0.8e9


@dataclass(frozen=True)
class ClipJob:
    """What every task needs: where to read, where to write, how to deblur."""

    source: SourceSpec
    output: str
    settings: object  # DeblurSettings (imported lazily: workers import on demand)
    point_cloud: bool = False
    run_id: str = ""  # sources and writers are cached per process and run


@dataclass(frozen=True)
class FrameRecord:
    """Outcome of one task."""

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

    def to_json(self) -> dict:
        data = {"event": "frame", **dataclasses.asdict(self)}
        data["warnings"] = list(self.warnings)
        data["seconds"] = round(self.seconds, 3)
        data["timings"] = {k: round(v, 3) for k, v in self.timings.items()}
        return {k: v for k, v in data.items() if v is not None}


@dataclass(frozen=True)
class ClipReport:
    """What a run did: one record per task it ran, and the tasks it skipped."""

    output: Path
    log: Path
    records: tuple[FrameRecord, ...]
    skipped: tuple[tuple[int, str], ...]
    seconds: float

    @property
    def done(self) -> int:
        return sum(r.status == "done" for r in self.records)

    @property
    def failed(self) -> tuple[FrameRecord, ...]:
        return tuple(r for r in self.records if r.status != "done")


# --------------------------------------------------------------------------- one frame


class TimeReversed:
    """A scene read backwards in time: frame j is frame ``n - 1 - j``, flows inverted.

    Lets the last frame be deblurred from ground truth towards the previous frame.
    """

    def __init__(self, scene):
        self.scene = scene
        self.info = scene.info
        self.num_frames = scene.num_frames
        self.shape = scene.shape
        self.root = getattr(scene, "root", None)

    def _j(self, index: int) -> int:
        return self.num_frames - 1 - index

    def read_frame(self, view, index, *, linear=True):
        return self.scene.read_frame(view, self._j(index), linear=linear)

    def has_gt(self, kind, view, index):
        j = self._j(index) - (kind == "flow")
        return j >= 0 and self.scene.has_gt(kind, view, j)

    def gt_path(self, kind, view, index):
        return self.scene.gt_path(kind, view, max(self._j(index) - (kind == "flow"), 0))

    def read_gt_disparity(self, view, index):
        return self.scene.read_gt_disparity(view, self._j(index))

    def read_gt_mixed(self, view, index):
        return self.scene.read_gt_mixed(view, self._j(index))

    def read_gt_sharp(self, view, index, *, linear=True):
        return self.scene.read_gt_sharp(view, self._j(index), linear=linear)

    def read_gt_flow(self, view, index):
        from ..pipeline import invert_flow

        flow = self.scene.read_gt_flow(view, self._j(index) - 1)
        unknown = ~np.all(np.isfinite(flow), axis=2)
        inverse = invert_flow(np.where(unknown[..., None], 0.0, flow).astype(np.float32))
        if unknown.any():  # unknown where the inverse lands on an unknown pixel
            H, W = unknown.shape
            y, x = np.mgrid[0:H, 0:W]
            ys = np.clip(np.rint(y + inverse[..., 1]), 0, H - 1).astype(int)
            xs = np.clip(np.rint(x + inverse[..., 0]), 0, W - 1).astype(int)
            inverse[unknown[ys, xs]] = np.nan
        return inverse


def gt_needs(num_frames: int, index: int) -> list[tuple[str, int]]:
    """Ground-truth files (kind, frame) of the left view that frame ``index`` needs."""
    from ..pipeline import neighbour_of

    neighbour = neighbour_of(index, num_frames)
    return [("disparity", index), ("disparity", neighbour), ("flow", min(index, neighbour))]


def deblur_clip_frame(source, index: int, view: str, settings):
    """Deblur frame ``index`` of ``view`` (the last frame too, with ground-truth motion)."""
    from ..pipeline import deblur_frame

    last = index == source.num_frames - 1
    if settings.motion_source == "gt" and last:
        result = deblur_frame(TimeReversed(source), 0, view=view, settings=settings)
        motion = dataclasses.replace(result.motion, index=index, neighbour=index - 1)
        return dataclasses.replace(result, index=index, motion=motion)
    return deblur_frame(source, index, view=view, settings=settings)


def frame_outputs(job: ClipJob, index: int, view: str) -> list[Path]:
    """The files a finished task has written; the frame PNG comes last."""
    from ..io.scene import scene_path
    from ..pointcloud import point_cloud_path

    paths = [scene_path(job.output, "frame", view, index)]
    if job.point_cloud:
        paths.insert(0, point_cloud_path(job.output, view, index))
    return paths


def is_finished(job: ClipJob, index: int, view: str) -> bool:
    return all(p.is_file() for p in frame_outputs(job, index, view))


_OPEN: dict = {}


def _open(job: ClipJob):
    """Source and writer of ``job``, opened once per process."""
    key = (job.source, job.output, job.run_id)
    if key not in _OPEN:
        from ..io.scene import SceneWriter

        source = job.source.open()
        writer = SceneWriter(job.output, source.info, overwrite=True)
        _OPEN.clear()
        _OPEN[key] = (source, writer)
    return _OPEN[key]


def _set_threads(threads: int | None) -> None:
    if not threads:
        return
    import cv2
    import numba

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    cv2.setNumThreads(max(1, int(threads)))


def _dask_threads(host_threads: dict | None) -> int | None:
    """Threads per task on a Dask worker: the host's cores shared by its worker threads."""
    if host_threads is None:
        return None
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    host = worker.address.rsplit(":", 1)[0]
    total = host_threads.get(host) or worker.state.nthreads
    return max(1, _cores() // max(1, total))


def process_frame(
    job: ClipJob, index: int, view: str, *, threads: int | None = None, host_threads=None
) -> FrameRecord:
    """Deblur and write one frame of one view; runs in a worker. Never raises for a frame."""
    start = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    caught = []
    try:
        _set_threads(threads or _dask_threads(host_threads))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            source, writer = _open(job)
            result = deblur_clip_frame(source, index, view, job.settings)
            t0 = time.perf_counter()
            if job.point_cloud:
                from ..pointcloud import frame_point_cloud, point_cloud_path, write_ply

                cloud = frame_point_cloud(
                    result.motion.sceneflow,
                    result.image,
                    blurred=result.blurred,
                    color=source.info.color,
                )
                write_ply(
                    point_cloud_path(job.output, view, index),
                    cloud,
                    comments=[f"frame {index} view {view}"],
                )
            writer.write_frame(view, index, result.image)
            timings = {**result.timings, "write": time.perf_counter() - t0}
            alpha = getattr(result, "alpha", None)
    except Exception as exc:  # reported in the log and the summary, not raised
        is_input = isinstance(exc, InputError | FileNotFoundError)
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return FrameRecord(
            index,
            view,
            "failed",
            seconds=time.perf_counter() - start,
            warnings=tuple(str(w.message) for w in caught),
            worker=worker,
            error=message if is_input else f"{type(exc).__name__}: {message}",
            input_error=is_input,
            details=None if is_input else traceback.format_exc(),
        )
    return FrameRecord(
        index,
        view,
        "done",
        seconds=time.perf_counter() - start,
        timings=timings,
        warnings=tuple(dict.fromkeys(str(w.message) for w in caught)),
        worker=worker,
        alpha=None if alpha is None else float(alpha),
    )


# --------------------------------------------------------------------------- executors


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _available_memory() -> float | None:
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return None


def default_workers(shape, *, num_samples: int = 70, num_tasks: int | None = None) -> int:
    """Worker processes for a local run: one per core, as many as memory allows.

    Each worker gets ``cores // workers`` numba threads, so the cores are busy
    either way; separate processes also overlap the serial parts of a frame.
    """
    height, width = shape
    per_frame = FRAME_MEMORY_640x480 * (height * width / (640 * 480)) * (num_samples / 70)
    per_frame = max(per_frame, 2e8)
    workers = _cores()
    memory = _available_memory()
    if memory is not None:
        workers = min(workers, int(0.8 * memory // per_frame))
    if num_tasks is not None:
        workers = min(workers, num_tasks)
    return max(1, workers)


def _init_worker(threads: int) -> None:
    """Pool worker start: threads before numba loads; interrupts are the parent's job."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ["NUMBA_NUM_THREADS"] = str(threads)
    os.environ["OMP_NUM_THREADS"] = str(threads)


def _run_serial(job, tasks) -> Iterator[FrameRecord]:
    for index, view in tasks:
        yield process_frame(job, index, view)


def _terminate(pool) -> None:
    """Stop a process pool now: cancel what waits, end the workers (frames in flight are lost)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=10)


def _run_pool(job, tasks, workers: int) -> Iterator[FrameRecord]:
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    threads = max(1, _cores() // workers)
    context = multiprocessing.get_context("spawn")
    remaining = list(tasks)
    for attempt in range(MAX_POOL_RESTARTS + 1):
        pool = ProcessPoolExecutor(
            max_workers=min(workers, len(remaining)),
            mp_context=context,
            initializer=_init_worker,
            initargs=(threads,),
        )
        futures = {
            pool.submit(process_frame, job, index, view, threads=threads): (index, view)
            for index, view in remaining
        }
        broken = []
        try:
            for future in as_completed(futures):
                try:
                    record = future.result()
                except BrokenProcessPool:
                    broken.append(futures[future])
                    continue
                yield record
        except BaseException:
            _terminate(pool)
            raise
        pool.shutdown(wait=True)
        if not broken:
            return
        remaining = sorted(broken)
        if attempt == MAX_POOL_RESTARTS:
            for index, view in remaining:
                yield FrameRecord(
                    index, view, "failed", error="a worker process died (killed or out of memory)"
                )


def _run_dask(job, tasks, address: str) -> Iterator[FrameRecord]:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError(
            "--scheduler needs dask.distributed: pip install 'stereodeblur[dask]'"
        ) from None
    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot connect to the Dask scheduler at {address}: {message}") from None
    futures = []
    try:
        host_threads: dict[str, int] = {}
        try:
            workers = client.scheduler_info(n_workers=-1)["workers"]
        except TypeError:  # distributed before n_workers (it listed all workers then)
            workers = client.scheduler_info()["workers"]
        for address_, info in workers.items():
            host = address_.rsplit(":", 1)[0]
            host_threads[host] = host_threads.get(host, 0) + int(info.get("nthreads", 1))
        token = uuid.uuid4().hex[:8]
        futures = [
            client.submit(
                process_frame,
                job,
                index,
                view,
                host_threads=host_threads,
                key=f"stereodeblur-{token}-{index:06d}-{view}",
                pure=False,
                retries=DASK_RETRIES,
            )
            for index, view in tasks
        ]
        keys = {future.key: task for future, task in zip(futures, tasks, strict=True)}
        for future in as_completed(futures, loop=client.loop):
            try:
                record = future.result()
            except Exception as exc:  # e.g. KilledWorker: the task killed workers repeatedly
                index, view = keys[future.key]
                record = FrameRecord(
                    index, view, "failed", error=f"{type(exc).__name__}: {str(exc)[:200]}"
                )
            yield record
    finally:
        for future in futures:
            if not future.done():
                future.cancel()
        client.close()


# --------------------------------------------------------------------------- progress


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class ProgressBar:
    """Frames done, rate and ETA on ``stream``: one redrawn line on a terminal, else a
    line per frame."""

    def __init__(self, total: int, *, skipped: int = 0, stream=None, width: int = 24):
        self.total = total
        self.skipped = skipped
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.done = 0
        self.failed = 0
        self.start = time.perf_counter()
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def line(self) -> str:
        finished = self.done + self.failed
        elapsed = time.perf_counter() - self.start
        rate = self.done / elapsed * 60 if elapsed > 0 and self.done else 0.0
        left = self.total - finished
        eta = _clock(left / rate * 60) if rate > 0 else "?"
        filled = int(self.width * finished / self.total) if self.total else self.width
        bar = "#" * filled + "." * (self.width - filled)
        text = f"[{bar}] {finished}/{self.total} frames, {rate:.2f} frames/min, ETA {eta}"
        if self.failed:
            text += f", {self.failed} failed"
        return text

    def update(self, record: FrameRecord) -> None:
        if record.status == "done":
            self.done += 1
        else:
            self.failed += 1
        if self.tty:
            print("\r" + self.line(), end="", file=self.stream, flush=True)
        else:
            what = "done" if record.status == "done" else f"FAILED ({record.error})"
            print(
                f"frame {record.index} {record.view} {what} in {record.seconds:.1f} s | "
                + self.line(),
                file=self.stream,
                flush=True,
            )

    def close(self) -> None:
        if self.tty:
            print(file=self.stream, flush=True)


# --------------------------------------------------------------------------- the run


_TEMPORARY = re.compile(r"^\.\d{6}\.(png|ply)\.[0-9a-f]+\.tmp$")


def _remove_temporaries(output: Path) -> None:
    """Delete temporary files that a killed run left half-written."""
    folders = [output / view for view in VIEWS] + [output / "pointcloud" / v for v in VIEWS]
    for folder in folders:
        if folder.is_dir():
            for path in folder.iterdir():
                if _TEMPORARY.match(path.name):
                    path.unlink(missing_ok=True)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _settings_json(settings) -> dict:
    return dataclasses.asdict(settings)


def _last_start(log: Path) -> dict | None:
    if not log.is_file():
        return None
    last = None
    with open(log, encoding="utf-8") as handle:
        for line in handle:
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a kill
            if isinstance(record, dict) and record.get("event") == "start":
                last = record
    return last


def _check_frames_for_gt(source, frames, explicit: bool):
    """Frames whose ground-truth motion is there; a one-line error when none (or, when
    the frames were asked for, any) lacks it."""
    if not all(hasattr(source, a) for a in ("read_gt_flow", "read_gt_disparity")):
        raise InputError(
            f"--motion-source gt needs ground truth, which {source.root} does not have: "
            "use --motion-source sceneflow"
        )
    ok, missing = [], []
    for index in frames:
        lacking = [
            (kind, i)
            for kind, i in gt_needs(source.num_frames, index)
            if not source.has_gt(kind, "left", i)
        ]
        (missing if lacking else ok).append((index, lacking[:1]))
    if missing and (explicit or not ok):
        index, [(kind, i)] = missing[0]
        raise InputError(
            f"--motion-source gt: frame {index} needs {source.gt_path(kind, 'left', i)}, "
            "which is missing"
        )
    return [index for index, _ in ok], [index for index, _ in missing]


def deblur_clip(
    source: SourceSpec,
    output,
    *,
    frames: Iterable[int] | None = None,
    views: Iterable[str] = VIEWS,
    settings=None,
    overwrite: bool = False,
    point_cloud: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool | object = True,
    on_frame: Callable[[FrameRecord], None] | None = None,
    command: list[str] | None = None,
) -> ClipReport:
    """Deblur frames of both views of a clip and write them as a scene at ``output``.

    Parameters
    ----------
    source : SourceSpec
        The input (see :func:`stereodeblur.io.sources.open_source`).
    output : path
        Output scene folder.
    frames : iterable of int, optional
        Frames to deblur; default all (with ground-truth motion: all that have it).
    views : iterable of {'left', 'right'}
    settings : DeblurSettings, optional
    overwrite : bool
        Deblur finished frames again (and write into a folder of another scene).
    point_cloud : bool
        Also write ``pointcloud/VIEW/NNNNNN.ply`` per frame.
    workers : int, optional
        Local worker processes (default :func:`default_workers`); 1 runs in this process.
    scheduler : str, optional
        Address of a Dask scheduler, ``tcp://HOST:PORT``; excludes ``workers``.
    progress : bool or file
        Progress bar on stderr (True), on a given stream, or none (False).
    on_frame : callable, optional
        Called with every :class:`FrameRecord` as it arrives.
    command : list of str, optional
        The command line, for the log.
    """
    from ..io.scene import SceneWriter
    from ..pipeline import DeblurSettings

    settings = settings or DeblurSettings()
    if not isinstance(source, SourceSpec):
        source = SourceSpec.from_arguments(source)
    views = tuple(dict.fromkeys(views))
    if not views or any(v not in VIEWS for v in views):
        raise InputError(f"views must be 'left' and/or 'right', got {views}")
    if workers is not None and scheduler is not None:
        raise InputError("give either --workers or --scheduler, not both")
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise InputError(f"--workers must be at least 1, got {workers}")
    if point_cloud and settings.motion_source == "initial-flow":
        raise InputError(
            "--point-cloud needs scene-flow geometry: use --motion-source sceneflow or gt"
        )
    scene = source.open()
    explicit = frames is not None
    frames = list(range(scene.num_frames)) if frames is None else sorted(set(frames))
    bad = [f for f in frames if not 0 <= f < scene.num_frames]
    if bad or not frames:
        raise InputError(f"frames must lie in 0..{scene.num_frames - 1}, got {bad or 'none'}")
    if getattr(settings, "boundary_mask", None) == "gt" and not hasattr(scene, "read_gt_mixed"):
        raise InputError(
            f"--boundary-mask gt needs gt/mixed masks, which {scene.root} does not have"
        )
    without_gt = []
    if settings.motion_source == "gt":
        frames, without_gt = _check_frames_for_gt(scene, frames, explicit)
    output = Path(os.path.abspath(output))
    log_path = output / LOG_NAME
    identity = {"source": list(source.paths), "settings": _settings_json(settings)}
    previous = _last_start(log_path)
    if previous is not None and not overwrite:
        before = {k: previous.get(k) for k in identity}
        if before != identity:
            changed = [k for k in identity if before[k] != identity[k]]
            raise InputError(
                f"{output} holds frames deblurred from another {' and '.join(changed)} "
                f"(see {log_path}): pass --overwrite or choose another folder"
            )
    created = not output.exists()
    protect = list(getattr(scene, "paths", [])) or [scene.root]
    SceneWriter(output, scene.info, overwrite=overwrite, protect=protect)
    job = ClipJob(source, str(output), settings, point_cloud, run_id=uuid.uuid4().hex)
    _remove_temporaries(output)
    tasks = [(i, v) for i in frames for v in views]
    skipped = [] if overwrite else [t for t in tasks if is_finished(job, *t)]
    todo = [t for t in tasks if t not in set(skipped)]
    if scheduler is None and workers is None:
        workers = default_workers(
            scene.shape, num_samples=settings.num_samples, num_tasks=max(1, len(todo))
        )
    start = time.perf_counter()
    records: list[FrameRecord] = []
    bar = None
    if progress and todo:
        bar = ProgressBar(
            len(todo), skipped=len(skipped), stream=None if progress is True else progress
        )
    with open(log_path, "a", encoding="utf-8") as log:

        def write(entry: dict) -> None:
            log.write(json.dumps({"time": _now(), **entry}) + "\n")
            log.flush()

        write(
            {
                "event": "start",
                **identity,
                "source_kind": getattr(scene, "kind", "scene"),
                "output": str(output),
                "frames": frames,
                "views": list(views),
                "tasks": len(tasks),
                "skipped": len(skipped),
                "workers": workers,
                "scheduler": scheduler,
                "point_cloud": point_cloud,
                "command": command,
                "host": socket.gethostname(),
                "warnings": list(getattr(scene, "warnings", ()))
                + [f"frame {i}: no ground-truth motion, not deblurred" for i in without_gt],
            }
        )
        if scheduler is not None:
            runner = _run_dask(job, todo, scheduler)
        elif workers == 1:
            runner = _run_serial(job, todo)
        else:
            runner = _run_pool(job, todo, workers)
        try:
            for record in runner:
                records.append(record)
                write(record.to_json())
                if bar is not None:
                    bar.update(record)
                if on_frame is not None:
                    on_frame(record)
        except BaseException as exc:
            write({"event": "interrupted", "reason": type(exc).__name__, "done": len(records)})
            if bar is not None:
                bar.close()
            if created and not any(r.status == "done" for r in records):
                log.close()
                shutil.rmtree(output, ignore_errors=True)
            raise
        finally:
            close = getattr(runner, "close", None)
            if close is not None:
                close()
        seconds = time.perf_counter() - start
        done = sum(r.status == "done" for r in records)
        write(
            {
                "event": "end",
                "done": done,
                "failed": len(records) - done,
                "skipped": len(skipped),
                "seconds": round(seconds, 3),
                "frames_per_minute": round(done / seconds * 60, 3) if seconds > 0 else None,
            }
        )
    if bar is not None:
        bar.close()
    if created and records and done == 0:  # nothing worth keeping: leave no folder behind
        shutil.rmtree(output, ignore_errors=True)
    return ClipReport(output, log_path, tuple(records), tuple(skipped), seconds)
