"""The shared worker threads under callers with different numba thread counts."""

from __future__ import annotations

import threading

import numba
import numpy as np

from stereodeblur._threads import balanced_ranges, executor, run_ranges


def _square(first, last, out):
    out[first:last] = np.arange(first, last) ** 2


def test_callers_with_other_thread_counts_do_not_stop_each_others_pools():
    """numba's thread count is per thread (a Dask worker, a background thread, ``threads_for``
    on small images): a caller must never shut down a pool another thread is submitting to."""
    errors = []

    def work(threads: int) -> None:
        numba.set_num_threads(threads)
        out = np.zeros(64, np.int64)
        try:
            for _ in range(300):
                run_ranges(_square, [(0, 20), (20, 40), (40, 64)], out)
                assert executor()._max_workers == threads
        except Exception as error:  # noqa: BLE001 - reported below
            errors.append(error)
        np.testing.assert_array_equal(out, np.arange(64) ** 2)

    callers = [
        threading.Thread(target=work, args=(n,)) for n in (1, numba.config.NUMBA_NUM_THREADS)
    ]
    for caller in callers:
        caller.start()
    for caller in callers:
        caller.join()
    assert not errors, errors


def test_balanced_ranges_split_the_work_evenly():
    bounds = np.array([0, 10, 10, 20, 30, 100])
    ranges = balanced_ranges(bounds, 2)
    assert ranges[0][0] == 0 and ranges[-1][1] == 5
    assert all(b > a for a, b in ranges)
    assert balanced_ranges(np.array([0]), 3) == [(0, 0)]
