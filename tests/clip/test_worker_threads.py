"""A pool worker compiles numba code that is in no cache, as on a fresh install's first run."""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

from stereodeblur.clip.worker import init_worker


def _compile_fresh(threads: int) -> tuple[int, int]:
    import numba

    from stereodeblur.clip.worker import set_threads

    set_threads(threads)

    @numba.njit  # defined in the call: numba has no cache of it and compiles it here
    def add_one(x):
        return x + 1

    return add_one(1), numba.get_num_threads()


def test_a_pool_worker_compiles_numba_code_it_has_no_cache_for():
    """numba is loaded before the worker's initializer runs; setting NUMBA_NUM_THREADS there
    made every later compilation fail ("Cannot set NUMBA_NUM_THREADS to a different value
    once the threads have been launched"): every frame of a first run on a fresh install."""
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        1, mp_context=context, initializer=init_worker, initargs=(1, os.getpid())
    ) as pool:
        assert pool.submit(_compile_fresh, 1).result(timeout=120) == (2, 1)
