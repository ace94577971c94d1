"""Progress reports: the one convention every long-running function uses.

A long-running function takes ``progress: ProgressCallback | None = None`` and calls
:func:`report` with what it is doing and, where it can count, how far it is. The CLI turns
the reports into lines on stderr; library users pass any callable or nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Progress:
    """One report: ``stage`` (e.g. ``"frame 3 left: IRLS"``), ``done`` of ``total`` steps.

    ``total`` is 0 where the stage is not counted.
    """

    stage: str
    done: int = 0
    total: int = 0

    @property
    def fraction(self) -> float | None:
        """``done / total``, or None for an uncounted stage."""
        return self.done / self.total if self.total > 0 else None

    def __str__(self) -> str:
        return f"{self.stage} {self.done}/{self.total}" if self.total > 0 else self.stage


ProgressCallback = Callable[[Progress], None]


def report(progress: ProgressCallback | None, stage: str, done: int = 0, total: int = 0) -> None:
    """Send ``Progress(stage, done, total)`` to ``progress`` if there is one."""
    if progress is not None:
        progress(Progress(stage, done, total))


def prefixed(progress: ProgressCallback | None, prefix: str) -> ProgressCallback | None:
    """``progress`` with ``prefix`` put before every stage (e.g. ``"frame 3 left: "``)."""
    if progress is None:
        return None
    return lambda p: progress(Progress(prefix + p.stage, p.done, p.total))
