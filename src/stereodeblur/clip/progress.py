"""Progress of a clip run: frames done, rate and ETA as a bar, or as reports to a callback."""

from __future__ import annotations

import sys
import time

from ..io.numbering import SCENE_NUMBERING, FrameNumbering
from ..progress import ProgressCallback, report
from .job import FrameRecord


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class ProgressBar:
    """Frames done, rate and ETA on ``stream``: one redrawn line on a terminal, else a
    line per frame (named by the source's numbers, ``numbering``)."""

    def __init__(
        self,
        total: int,
        *,
        skipped: int = 0,
        stream=None,
        width: int = 24,
        numbering: FrameNumbering = SCENE_NUMBERING,
    ):
        self.total = total
        self.skipped = skipped
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.numbering = numbering
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
            number = self.numbering.number(record.index)
            print(
                f"frame {number} {record.view} {what} in {record.seconds:.1f} s | " + self.line(),
                file=self.stream,
                flush=True,
            )

    def close(self) -> None:
        if self.tty:
            print(file=self.stream, flush=True)


class ReportProgress:
    """The clip's progress as :class:`~stereodeblur.progress.Progress` reports to a callback:
    stage ``"frame N VIEW done"`` (or ``failed``; ``N`` the source's number), views finished
    of ``total``."""

    def __init__(
        self, progress: ProgressCallback, total: int, numbering: FrameNumbering = SCENE_NUMBERING
    ):
        self.progress = progress
        self.numbering = numbering
        self.total = total
        self.finished = 0

    def update(self, record: FrameRecord) -> None:
        self.finished += 1
        stage = f"frame {self.numbering.number(record.index)} {record.view} {record.status}"
        report(self.progress, stage, self.finished, self.total)

    def close(self) -> None:
        pass


def make_progress(progress, total: int, skipped: int, numbering: FrameNumbering = SCENE_NUMBERING):
    """A bar on stderr (``True``), on a stream, reports to a callable, or None (``False``);
    frames named by ``numbering``."""
    if not progress or total == 0:
        return None
    if progress is True:
        return ProgressBar(total, skipped=skipped, numbering=numbering)
    if hasattr(progress, "write"):
        return ProgressBar(total, skipped=skipped, stream=progress, numbering=numbering)
    if callable(progress):
        return ReportProgress(progress, total, numbering)
    raise TypeError(f"progress must be a bool, a stream or a callable, got {progress!r}")
