"""The run log ``OUT/run-log.jsonl``: one JSON object per line, appended by every run.

Events: ``{"event": "start", ...}`` (source, settings, frames, workers, warnings), one
``{"event": "frame", ...}`` per deblurred view (see :class:`~stereodeblur.clip.job.FrameRecord`),
and ``{"event": "end", ...}`` or ``{"event": "interrupted", ...}``. A line cut by a kill or
damaged from outside (not UTF-8, not JSON, not an object) is skipped by the reader, which
says so in :attr:`RunLogContents.problems`; the next run records them in its start event.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from ..errors import InputError, StorageError

# A run log line longer than this is damage, not a record (the longest start line of a
# long clip is a few hundred kilobytes).
MAX_LINE = 64 * 1024 * 1024


@dataclass(frozen=True)
class RunLogContents:
    """The readable events of a run log and a note per line that was skipped."""

    events: tuple[dict, ...]
    problems: tuple[str, ...]

    def last_start(self) -> dict | None:
        """The latest ``start`` event, if any."""
        starts = [e for e in self.events if e.get("event") == "start"]
        return starts[-1] if starts else None


def parse_run_log(data: bytes, name: str = "run log") -> RunLogContents:
    """Events of a run log's bytes; damaged lines are skipped and noted."""
    if not isinstance(data, bytes | bytearray):
        raise InputError(f"{name}: expected bytes, got {type(data).__name__}")
    events, problems = [], []
    for number, line in enumerate(bytes(data).split(b"\n"), start=1):
        if not line.strip():
            continue
        try:
            if len(line) > MAX_LINE:
                raise ValueError("line too long")
            event = json.loads(line.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            problems.append(f"{name} line {number}: not a JSON record, skipped")
            continue
        if not isinstance(event, dict) or not isinstance(event.get("event"), str):
            problems.append(f"{name} line {number}: not an event, skipped")
            continue
        events.append(event)
    return RunLogContents(tuple(events), tuple(problems))


def read_run_log(path: str | os.PathLike) -> RunLogContents:
    """Read the run log at ``path`` (an empty log when there is none).

    Raises
    ------
    InputError
        When ``path`` exists but cannot be read as a file.
    """
    path = Path(path)
    if not path.exists() and not path.is_symlink():
        return RunLogContents((), ())
    if not path.is_file():
        raise InputError(f"run log {path} is not a file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read run log {path}: {exc.strerror or exc}") from None
    return parse_run_log(data, str(path))


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


class RunLogWriter:
    """Appends events to a run log, one flushed line each; a symlink at ``path`` is refused
    (an InputError), never followed.

    A log whose last line was cut by a kill gets a newline first, so the new events start on
    lines of their own.
    """

    def __init__(self, path: str | os.PathLike):
        from ..io.outputs import open_in_place

        self.path = Path(path)
        fd = open_in_place(self.path, os.O_WRONLY | os.O_APPEND)  # never through a symlink
        # Unbuffered: a line is written whole or fails, and nothing waits for close().
        self._handle = os.fdopen(fd, "ab", buffering=0)
        size = os.fstat(fd).st_size
        if size:
            with open(self.path, "rb") as reader:
                reader.seek(size - 1)
                if reader.read(1) != b"\n":
                    self._append(b"\n")

    def _append(self, data: bytes) -> None:
        try:
            view = memoryview(data)
            while view:
                view = view[self._handle.write(view) :]
        except OSError as exc:
            if StorageError.matches(exc):
                raise StorageError.of(exc, self.path) from None
            raise

    def write(self, event: dict) -> None:
        """Append ``event`` with the time; a StorageError when the disk is full."""
        line = json.dumps({"time": _now(), **event}, default=str)
        self._append(line.encode("utf-8") + b"\n")

    def close(self) -> None:
        if not self._handle.closed:
            self._handle.close()

    def __enter__(self) -> RunLogWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
