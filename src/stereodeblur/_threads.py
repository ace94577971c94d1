"""The package's shared worker threads, for numba kernels that release the GIL.

A persistent pool of ``numba.get_num_threads()`` Python threads runs a kernel on several
contiguous ranges at once (:func:`run_ranges`); the results are joined in order. Its idle
threads block instead of spinning, so an oversubscribed machine does not make them
collapse (see :mod:`stereodeblur.blur._kernels`).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

_pools: dict[int, ThreadPoolExecutor] = {}
_pool_lock = threading.Lock()


def _forget_pools_after_fork() -> None:
    """A forked child has none of the parent's worker threads: start afresh."""
    global _pool_lock
    _pools.clear()
    _pool_lock = threading.Lock()


os.register_at_fork(after_in_child=_forget_pools_after_fork)


def executor() -> ThreadPoolExecutor:
    """The shared worker threads, as many as ``numba.get_num_threads()``.

    numba's thread count is per calling thread (``threads_for`` lowers it for small
    images; a Dask worker or a background thread may have another), so there is one pool
    per count, kept for the life of the process: a pool in use by one thread is never shut
    down by another.
    """
    threads = numba.get_num_threads()
    with _pool_lock:
        pool = _pools.get(threads)
        if pool is None:
            pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="stereodeblur")
            _pools[threads] = pool
        return pool


def run_ranges(function, ranges, *args) -> list:
    """``function(first, last, *args)`` for every range, in parallel; results in order."""
    if len(ranges) == 1:
        return [function(ranges[0][0], ranges[0][1], *args)]
    pool = executor()
    futures = [pool.submit(function, a, b, *args) for a, b in ranges]
    return [f.result() for f in futures]


def balanced_ranges(bounds, parts: int) -> list[tuple[int, int]]:
    """At most ``parts`` contiguous ranges of items ``0 .. len(bounds) - 2`` whose items hold
    about equal work, item ``i`` holding ``bounds[i + 1] - bounds[i]`` (``bounds``
    non-decreasing, from 0)."""
    bounds = np.asarray(bounds)
    num = bounds.size - 1
    edges = np.searchsorted(bounds, np.linspace(0, bounds[-1], parts + 1))
    edges[0], edges[-1] = 0, num
    ranges = [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]
    return ranges or [(0, num)]
