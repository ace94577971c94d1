"""One task of a clip run, as a worker runs it: deblur a frame's views and write them.

A worker process watches its parent: on Linux the kernel kills it when the parent dies
(``PR_SET_PDEATHSIG``), and on every system a thread polls ``os.getppid()`` and ends the
worker when the parent has gone, so no worker outlives a run whose main process was killed.
Library messages that a task prints on the standard error (OpenCV, libpng, FFmpeg) and
Python warnings are kept off the terminal: they go into the task's records and the run log.
The stages' progress of a task (motion, operator, deconvolution) goes to the ``progress``
callback it is given or, in a pool worker, to the queue the pool gave the worker at its start
(:func:`init_worker`), which the parent drains onto its own callback.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
import warnings
from collections.abc import Iterator

from ..errors import FrameWarning, InputError, StorageError
from ..progress import Progress, ProgressCallback
from .job import ClipJob, FrameRecord

PARENT_POLL_SECONDS = 0.5
_PR_SET_PDEATHSIG = 1

_OPEN: dict = {}
# The queue this pool worker sends its tasks' progress reports to (None: not in a pool).
_PROGRESS_QUEUE = None


# --------------------------------------------------------------------------- worker start


def _kill_with_parent() -> None:
    """Ask Linux to SIGKILL this process when its parent dies (nothing elsewhere)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - no prctl: the thread still watches
        pass


def _poll_parent(parent: int) -> None:
    while True:
        time.sleep(PARENT_POLL_SECONDS)
        if os.getppid() != parent:
            os._exit(1)


def watch_parent(parent: int) -> None:
    """End this process as soon as process ``parent`` (its parent) is gone."""
    _kill_with_parent()
    if os.getppid() != parent:  # the parent died before the watch began
        os._exit(1)
    threading.Thread(target=_poll_parent, args=(parent,), daemon=True, name="watch-parent").start()


def init_worker(threads: int, parent: int, progress_queue=None) -> None:
    """Pool worker start: watch the parent and use ``threads`` threads; interrupts and
    terminations are the parent's job. The tasks' progress reports go to ``progress_queue``
    (a ``multiprocessing`` queue the parent drains), if given.

    numba, numpy and OpenCV are loaded before this runs (unpickling it imports the package),
    so the thread counts are set through their calls (:func:`set_threads`), not the
    environment: a ``NUMBA_NUM_THREADS`` that differs from numba's once its threads run makes
    every later compilation fail."""
    global _PROGRESS_QUEUE
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _PROGRESS_QUEUE = progress_queue
    watch_parent(parent)
    os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
    set_threads(threads)


def set_threads(threads: int | None) -> None:
    """Use ``threads`` threads in numba and OpenCV (none given: leave them)."""
    if not threads:
        return
    import cv2
    import numba

    numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    cv2.setNumThreads(max(1, int(threads)))


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


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
    return max(1, cores() // max(1, total))


# --------------------------------------------------------------------------- messages


@contextlib.contextmanager
def captured_stderr(lines: list[str]) -> Iterator[object]:
    """Send what this process writes on the standard error (file descriptor 2 and
    ``sys.stderr``) into ``lines``, one entry per line.

    Yields ``shown(callback)``: ``callback`` wrapped to write on the real standard error
    while it runs (a progress printer called from inside the block)."""
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    saved = os.dup(2)
    text = io.StringIO()
    original = sys.stderr
    with tempfile.TemporaryFile() as sink:

        def shown(callback):
            def call(*args):
                os.dup2(saved, 2)
                captured, sys.stderr = sys.stderr, original
                try:
                    callback(*args)
                finally:
                    with contextlib.suppress(Exception):
                        original.flush()
                    sys.stderr = captured
                    os.dup2(sink.fileno(), 2)

            return None if callback is None else call

        os.dup2(sink.fileno(), 2)
        try:
            with contextlib.redirect_stderr(text):
                yield shown
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            written = sink.read().decode("utf-8", "replace") + text.getvalue()
            lines.extend(line.strip() for line in written.splitlines() if line.strip())


# --------------------------------------------------------------------------- one task


def _open(job: ClipJob):
    """Source and writer of ``job``, opened once per process."""
    key = (job.source, job.output, job.run_id)
    if key not in _OPEN:
        from ..io.scene import SceneWriter

        source = job.source.open()
        writer = SceneWriter(job.output, source.info, overwrite=True, numbering=source.numbering)
        _OPEN.clear()
        _OPEN[key] = (source, writer)
    return _OPEN[key]


def _queued(progress: Progress) -> None:
    """Send a report to this pool worker's parent (a lost report is no failure)."""
    with contextlib.suppress(Exception):
        _PROGRESS_QUEUE.put(progress)


def _deblur_views(source, index: int, views: tuple[str, ...], job: ClipJob, progress) -> dict:
    """Results of ``views`` of frame ``index``, deblurred together (motion computed once)."""
    from ..pipeline import deblur_stereo_frame

    if progress is None and _PROGRESS_QUEUE is not None:
        progress = _queued
    stereo = deblur_stereo_frame(
        source, index, views=views, settings=job.settings, progress=progress
    )
    frames = stereo.frames
    return {view: frames[view] for view in views}


def _write_view(job: ClipJob, source, writer, result, view: str, index: int) -> None:
    if job.point_cloud:
        from ..pointcloud import frame_point_cloud, point_cloud_path, write_ply

        cloud = frame_point_cloud(
            result.motion.sceneflow, result.image, blurred=result.blurred, color=source.info.color
        )
        write_ply(
            point_cloud_path(job.output, view, index, name=source.numbering.name(index)),
            cloud,
            comments=[f"frame {index} view {view}"],
        )
    writer.write_frame(view, index, result.image)


def _failed(index, views, start, messages, worker, exc, output) -> tuple[FrameRecord, ...]:
    is_input = isinstance(exc, InputError | FileNotFoundError)
    storage = None
    if StorageError.matches(exc):  # named by the file it names, else by the output folder
        storage = StorageError.of(exc, None if exc.filename else output)
    message = str(storage or exc).splitlines()[0] if str(storage or exc) else type(exc).__name__
    plain = is_input or storage is not None
    return tuple(
        FrameRecord(
            index,
            view,
            "failed",
            seconds=time.perf_counter() - start,
            warnings=tuple(dict.fromkeys(messages)),
            worker=worker,
            error=message if plain else f"{type(exc).__name__}: {message}",
            input_error=is_input,
            details=None if plain else traceback.format_exc(),
            storage_errno=None if storage is None else storage.errno,
            storage_path=None if storage is None else storage.filename,
        )
        for view in views
    )


def process_task(
    job: ClipJob,
    index: int,
    views: tuple[str, ...],
    *,
    threads: int | None = None,
    host_threads=None,
    capture: bool = True,
    progress: ProgressCallback | None = None,
) -> tuple[FrameRecord, ...]:
    """Deblur and write ``views`` of frame ``index``; runs in a worker. Never raises for a
    frame: a failure is a record with ``status='failed'`` per view. The stages' progress goes
    to ``progress`` (in a pool worker without one: to the parent's queue)."""
    start = time.perf_counter()
    worker = f"{socket.gethostname()}:{os.getpid()}"
    messages: list[str] = []
    caught: list = []
    stderr = captured_stderr(messages) if capture else contextlib.nullcontext()
    try:
        with stderr as shown, warnings.catch_warnings(record=True) as caught:
            if shown is not None:  # the progress printer writes on the real standard error
                progress = shown(progress)
            warnings.simplefilter("always")
            set_threads(threads or _dask_threads(host_threads))
            source, writer = _open(job)
            results = _deblur_views(source, index, views, job, progress)
            t0 = time.perf_counter()
            for view, result in results.items():
                _write_view(job, source, writer, result, view, index)
            write_seconds = (time.perf_counter() - t0) / len(views)
    except Exception as exc:  # reported in the log and the summary, not raised
        messages += [str(w.message) for w in caught or ()]
        return _failed(index, views, start, messages, worker, exc, job.output)
    messages += [str(w.message) for w in caught]
    alerts = tuple(dict.fromkeys(str(w.message) for w in caught if w.category is FrameWarning))
    seconds = time.perf_counter() - start
    return tuple(
        FrameRecord(
            index,
            view,
            "done",
            seconds=seconds,
            timings={**result.timings, "write": write_seconds},
            warnings=tuple(dict.fromkeys(messages)),
            worker=worker,
            alpha=None if result.alpha is None else float(result.alpha),
            exposure=result.exposure,
            alerts=alerts,
        )
        for view, result in results.items()
    )
