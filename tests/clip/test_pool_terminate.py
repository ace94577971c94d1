"""Stopping a worker pool at once leaves none of its threads or pipes behind."""

from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

from stereodeblur.clip.executors import _terminate


def test_terminate_ends_the_workers_and_the_pools_manager_thread():
    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
    future = pool.submit(time.sleep, 60)
    deadline = time.monotonic() + 60
    while not future.running() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert future.running()
    manager, wakeup = pool._executor_manager_thread, pool._executor_manager_thread_wakeup
    workers = list(pool._processes.values())

    _terminate(pool)

    assert not any(worker.is_alive() for worker in workers)
    # concurrent.futures' exit hook writes to the wake-up pipe of a manager thread it still
    # knows; a manager closing that pipe at the same time gave "Bad file descriptor".
    assert not manager.is_alive()
    assert wakeup._closed
