"""The command line's one progress printer and its warning lines, both on stderr.

Every long-running library function reports :class:`stereodeblur.progress.Progress`; the
commands pass :func:`progress_printer` as its ``progress`` (None with ``-q``). Warnings of an
input (e.g. two videos of different lengths) are printed with :func:`print_warnings`, also
with ``-q``: they say something about the result.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterable

from ..progress import Progress, ProgressCallback

# Counted stages (e.g. "IRLS 3/10") print at most one line per interval, plus their last.
MIN_INTERVAL = 1.0


class ProgressPrinter:
    """Prints each report as ``[elapsed s] stage done/total`` on stderr.

    A counted stage prints when it starts, when it ends and at most once per
    :data:`MIN_INTERVAL` seconds in between.
    """

    def __init__(self, stream=None, *, min_interval: float = MIN_INTERVAL):
        self.stream = stream
        self.min_interval = min_interval
        self.start = time.perf_counter()
        self._last_stage: str | None = None
        self._last_time = -float("inf")
        self._lock = threading.Lock()  # reports of worker processes arrive on a thread

    def __call__(self, progress: Progress) -> None:
        with self._lock:
            self._print(progress)

    def _print(self, progress: Progress) -> None:
        now = time.perf_counter()
        counted = isinstance(progress, Progress) and progress.total > 0
        if counted and progress.stage == self._last_stage and progress.done < progress.total:
            if now - self._last_time < self.min_interval:
                return
        self._last_stage = progress.stage if counted else None
        self._last_time = now
        stream = self.stream or sys.stderr
        print(f"[{now - self.start:7.1f} s] {progress}", file=stream, flush=True)


def progress_printer(quiet: bool) -> ProgressCallback | None:
    """A :class:`ProgressPrinter`, or None when ``quiet``."""
    return None if quiet else ProgressPrinter()


COMPILE_NOTICE = "compiling the numba kernels once (about a minute); later runs reuse them"


def print_compile_notice(quiet: bool, modules) -> None:
    """Say on stderr, before the first frame, that this run compiles the kernels of
    ``modules`` (numba's cache holds none of them yet); nothing with ``quiet``."""
    from .._kernel_cache import kernels_cached

    if not quiet and not kernels_cached(modules):
        print(f"stereodeblur: {COMPILE_NOTICE}", file=sys.stderr, flush=True)


def with_compile_notice(progress, quiet: bool, modules):
    """``progress`` that first prints the compile notice (:func:`print_compile_notice`) at
    its first report, that is once the run has checked its inputs and starts computing;
    None stays None (nothing is reported, nothing is computed first)."""
    if progress is None:
        return None
    pending = [True]

    def report(*args, **kwargs):
        if pending:
            pending.clear()
            print_compile_notice(quiet, modules)
        return progress(*args, **kwargs)

    return report


def print_warnings(messages: Iterable[str]) -> None:
    """Each message once as ``stereodeblur: warning: ...`` on stderr."""
    for message in dict.fromkeys(messages):
        print(f"stereodeblur: warning: {message}", file=sys.stderr, flush=True)
