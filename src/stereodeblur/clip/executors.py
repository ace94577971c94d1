"""Where the tasks of a clip run: this process, a local process pool, or a Dask cluster.

Every executor offers ``run(job, tasks)``, an iterator of
:class:`~stereodeblur.clip.job.FrameRecord` in the order the views finish. Closing the
iterator (or an exception in the consumer) stops the executor's work at once: frames in
flight are lost, finished frames stay.

``SerialExecutor`` runs the tasks here. ``PoolExecutor(workers)`` runs them in spawned worker
processes, each with ``cores // workers`` numba and OpenCV threads; the workers watch this
process and end with it (:func:`~stereodeblur.clip.worker.watch_parent`) and send the stages'
progress of their tasks back through a queue (shown as a serial run shows it); a worker that dies
(killed, out of memory) has its tasks run again in a new pool. ``DaskExecutor(address)``
sends them to an existing Dask distributed cluster, whose workers open the input and write
the output themselves (both paths must be the same on every worker: a shared file system);
Dask runs a task again on another worker when its worker dies. Before connecting, the address
must answer Dask's ``identity`` request as a scheduler within
:data:`~stereodeblur.settings.DASK_CONNECT_TIMEOUT` seconds (:func:`check_scheduler`); a peer
that answers something else or nothing is an InputError, not a hang.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import uuid
from collections.abc import Iterator, Sequence
from typing import Protocol

from ..errors import InputError
from ..progress import ProgressCallback
from ..settings import DASK_CONNECT_TIMEOUT, NUM_SAMPLES
from .job import ClipJob, FrameRecord, Task
from .worker import cores, init_worker, process_task

MAX_POOL_RESTARTS = 2
DASK_RETRIES = 2
# Peak memory of a worker deblurring one 640x480 RGB frame with the paper's 70 samples (about
# 0.6 GB measured, with margin); scaled with pixels and samples for other sizes.
FRAME_MEMORY_640x480 = 0.8e9


class Executor(Protocol):
    """Runs the tasks of a clip job and yields a record per view as it finishes."""

    def run(
        self, job: ClipJob, tasks: Sequence[Task], progress: ProgressCallback | None = None
    ) -> Iterator[FrameRecord]:
        """Records of ``tasks`` as they finish; the stages' progress to ``progress``."""
        ...


def _available_memory() -> float | None:
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:  # pragma: no cover - not Linux
        pass
    return None


def default_workers(shape, *, num_samples: int = NUM_SAMPLES, num_tasks: int | None = None) -> int:
    """Worker processes for a local run: one per core, as many as memory allows.

    Each worker gets ``cores // workers`` numba threads, so the cores are busy
    either way; separate processes also overlap the serial parts of a frame.
    """
    height, width = shape
    per_frame = FRAME_MEMORY_640x480 * (height * width / (640 * 480)) * (num_samples / 70)
    per_frame = max(per_frame, 2e8)
    workers = cores()
    memory = _available_memory()
    if memory is not None:
        workers = min(workers, int(0.8 * memory // per_frame))
    if num_tasks is not None:
        workers = min(workers, num_tasks)
    return max(1, workers)


class SerialExecutor:
    """Every task in this process, one after the other."""

    def run(
        self, job: ClipJob, tasks: Sequence[Task], progress: ProgressCallback | None = None
    ) -> Iterator[FrameRecord]:
        for index, views in tasks:
            yield from process_task(job, index, views, progress=progress)


def _terminate(pool) -> None:
    """Stop a process pool now: cancel what waits, end the workers (frames in flight are lost)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    # Taken before shutdown(), which drops the pool's reference to it.
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=10)
        if process.is_alive():  # pragma: no cover - a worker ignoring SIGTERM
            process.kill()
            process.join(timeout=5)
    # The pool's manager thread sees the workers gone, closes its wake-up pipe and ends. Left
    # running, it races concurrent.futures' exit hook, which writes to that pipe: "Bad file
    # descriptor" and a traceback at interpreter exit (seen under SIGTERM in
    # tests/faults/test_processes.py).
    if manager is not None:
        manager.join(timeout=5)


@contextlib.contextmanager
def _interrupts_deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block is done, then act as they would have.

    Spawning a worker writes its start-up data to a pipe; an interrupt in the middle of that
    write leaves the child with half of it and a traceback on the terminal.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {
        sig: signal.signal(sig, lambda signum, frame: arrived.append(signum)) for sig in signals
    }
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for sig in dict.fromkeys(arrived):
            handler = previous[sig]
            if callable(handler):
                handler(sig, None)
            elif handler != signal.SIG_IGN:
                signal.raise_signal(sig)


@contextlib.contextmanager
def _forwarded(progress: ProgressCallback | None) -> Iterator[object]:
    """A queue for the pool workers' progress reports, drained onto ``progress`` by a thread
    while the block runs (None and no thread without ``progress``)."""
    if progress is None:
        yield None
        return
    queue = multiprocessing.get_context("spawn").Queue()

    def drain() -> None:
        while True:
            try:
                report = queue.get()
            except (EOFError, OSError):  # the queue was closed
                return
            if report is None:
                return
            with contextlib.suppress(Exception):  # a failing printer stops no run
                progress(report)

    thread = threading.Thread(target=drain, daemon=True, name="worker-progress")
    thread.start()
    try:
        yield queue
    finally:
        queue.put(None)
        thread.join(timeout=5)
        queue.close()
        queue.cancel_join_thread()


class PoolExecutor:
    """Tasks in ``workers`` spawned local processes that end when this process ends."""

    def __init__(self, workers: int):
        if isinstance(workers, bool) or int(workers) < 1:
            raise InputError(f"workers must be at least 1, got {workers}")
        self.workers = int(workers)

    def run(
        self, job: ClipJob, tasks: Sequence[Task], progress: ProgressCallback | None = None
    ) -> Iterator[FrameRecord]:
        remaining = list(tasks)
        for attempt in range(MAX_POOL_RESTARTS + 1):
            if not remaining:
                return
            broken: list[Task] = []
            with _forwarded(progress) as queue:
                yield from self._one_pool(job, remaining, broken, queue)
            remaining = sorted(broken)
            if remaining and attempt == MAX_POOL_RESTARTS:
                for index, views in remaining:
                    for view in views:
                        yield FrameRecord(
                            index,
                            view,
                            "failed",
                            error="a worker process died (killed or out of memory)",
                        )

    def _one_pool(self, job, tasks, broken: list, queue) -> Iterator[FrameRecord]:
        from concurrent.futures import ProcessPoolExecutor, as_completed
        from concurrent.futures.process import BrokenProcessPool

        threads = max(1, cores() // self.workers)
        pool = ProcessPoolExecutor(
            max_workers=max(1, min(self.workers, len(tasks))),
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_worker,
            initargs=(threads, os.getpid(), queue),
        )
        try:
            with _interrupts_deferred():  # submitting spawns the workers
                futures = {
                    pool.submit(process_task, job, index, views, threads=threads): (index, views)
                    for index, views in tasks
                }
            for future in as_completed(futures):
                try:
                    records = future.result()
                except BrokenProcessPool:
                    broken.append(futures[future])
                    continue
                yield from records
        except BaseException:
            _terminate(pool)
            raise
        pool.shutdown(wait=True)


def _first_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _no_answer(timeout: float) -> InputError:
    return InputError(f"no answer within {timeout:g} s (is it a Dask scheduler?)")


def _not_a_scheduler(exc: Exception) -> InputError:
    # Garbage read as Dask messages fails in many ways (a 3 EiB allocation for an HTTP
    # answer): the kind of failure is enough.
    return InputError(f"it answers, but not as a Dask scheduler ({type(exc).__name__})")


async def _identity(address: str, timeout: float) -> dict:
    """The answer of ``address`` to Dask's ``identity`` request, all within ``timeout``."""
    import asyncio
    import time

    from distributed.comm import connect

    deadline = time.monotonic() + timeout
    try:  # distributed retries a refused connection until its own, shorter, timeout
        comm = await asyncio.wait_for(connect(address, timeout=round(0.8 * timeout, 1)), timeout)
    except TimeoutError:  # connected, but the handshake got no answer
        raise _no_answer(timeout) from None
    except OSError as exc:
        raise InputError(_first_line(exc)) from None
    except Exception as exc:  # the handshake got garbage
        raise _not_a_scheduler(exc) from None
    try:
        await comm.write({"op": "identity", "reply": True})
        remaining = max(0.1, deadline - time.monotonic())
        try:
            answer = await asyncio.wait_for(comm.read(), remaining)
        except TimeoutError:
            raise _no_answer(timeout) from None
    except InputError:
        raise
    except Exception as exc:  # garbage: unpickling or allocation errors of every kind
        raise _not_a_scheduler(exc) from None
    finally:
        comm.abort()
    return answer


def check_scheduler(address: str, timeout: float | None = None) -> None:
    """Check that ``address`` is a Dask scheduler that answers within ``timeout`` seconds
    (default :data:`DASK_CONNECT_TIMEOUT`); an InputError saying what answered otherwise.

    The exchange runs on its own event loop in a daemon thread, so it neither needs nor
    disturbs a loop of the caller, and a peer that never answers costs ``timeout`` at most.
    """
    import asyncio

    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)  # a port is needed
    except (ValueError, TypeError) as exc:
        raise InputError(
            f"scheduler address {address!r}: {_first_line(exc)}; expected tcp://HOST:PORT"
        ) from None
    timeout = DASK_CONNECT_TIMEOUT if timeout is None else float(timeout)
    outcome: dict = {}

    def ask() -> None:
        try:
            outcome["answer"] = asyncio.run(_identity(address, timeout))
        except BaseException as exc:  # handed to the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=ask, daemon=True, name="dask-identity")
    thread.start()
    thread.join(timeout + 2.0)
    error = outcome.get("error")
    if thread.is_alive():
        error = _no_answer(timeout)
    elif error is None:
        answer = outcome.get("answer")
        kind = answer.get("type") if isinstance(answer, dict) else type(answer).__name__
        if kind != "Scheduler":
            error = InputError(f"it answers, but as a {kind}, not as a Dask scheduler")
    if error is not None:
        message = _first_line(error)
        raise InputError(f"cannot connect to the Dask scheduler at {address}: {message}") from None


def _dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise InputError(
            "a Dask scheduler needs dask.distributed: pip install 'stereodeblur[dask]'"
        ) from None
    check_scheduler(address)
    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT, set_as_default=False)
    except Exception as exc:
        message = _first_line(exc)
        raise InputError(f"cannot connect to the Dask scheduler at {address}: {message}") from None


def _host_threads(client) -> dict[str, int]:
    try:
        workers = client.scheduler_info(n_workers=-1)["workers"]
    except TypeError:  # distributed before n_workers (it listed all workers then)
        workers = client.scheduler_info()["workers"]
    threads: dict[str, int] = {}
    for address, info in workers.items():
        host = address.rsplit(":", 1)[0]
        threads[host] = threads.get(host, 0) + int(info.get("nthreads", 1))
    return threads


class DaskExecutor:
    """Tasks on the Dask distributed cluster at ``address`` (``tcp://HOST:PORT``)."""

    def __init__(self, address: str):
        self.address = address
        self.client = None

    def connect(self) -> None:
        """Connect now (an InputError when the scheduler cannot be reached)."""
        if self.client is None:
            self.client = _dask_client(self.address)

    def run(
        self, job: ClipJob, tasks: Sequence[Task], progress: ProgressCallback | None = None
    ) -> Iterator[FrameRecord]:
        """Records of ``tasks``; the stages' progress stays on the cluster's workers."""
        from distributed import as_completed

        self.connect()
        client, futures = self.client, []
        try:
            host_threads = _host_threads(client)
            token = uuid.uuid4().hex[:8]
            for index, views in tasks:
                key = f"stereodeblur-{token}-{index:06d}-{'-'.join(views)}"
                futures.append(
                    client.submit(
                        process_task,
                        *(job, index, views),
                        host_threads=host_threads,
                        capture=False,  # worker threads share the standard error
                        key=key,
                        pure=False,
                        retries=DASK_RETRIES,
                    )
                )
            keys = {future.key: task for future, task in zip(futures, tasks, strict=True)}
            for future in as_completed(futures, loop=client.loop):
                try:
                    yield from future.result()
                except Exception as exc:  # e.g. KilledWorker: the task killed workers repeatedly
                    index, views = keys[future.key]
                    error = f"{type(exc).__name__}: {str(exc)[:200]}"
                    yield from (FrameRecord(index, v, "failed", error=error) for v in views)
        finally:
            for future in futures:
                if not future.done():
                    future.cancel()
            self.close()

    def close(self) -> None:
        """Disconnect from the scheduler (idempotent)."""
        if self.client is not None:
            self.client.close()
            self.client = None


def make_executor(workers: int | None, scheduler: str | None) -> Executor:
    """The executor for ``workers`` local processes (1: this process) or a Dask ``scheduler``."""
    if scheduler is not None:
        return DaskExecutor(scheduler)
    if workers is None or workers == 1:
        return SerialExecutor()
    return PoolExecutor(workers)
