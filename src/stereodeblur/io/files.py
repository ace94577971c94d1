"""Files written atomically, read whole, and C libraries kept quiet while reading them.

Every writer in :mod:`stereodeblur.io` goes through :func:`atomic_write`: a hidden
temporary file in the target folder (created if needed), then a rename over the
target, so a reader never sees a half-written file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import sys
import threading
from pathlib import Path

import cv2

from ..errors import InputError, StorageError


def atomic_write(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and ``os.replace``.

    Raises
    ------
    StorageError
        When the storage refuses the write (no space left, quota, read-only), naming ``path``;
        the temporary file is removed first, as on every failure.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
        fd = os.open(tmp, flags, 0o666)
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
                handle.flush()
                os.fsync(handle.fileno())
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    except OSError as exc:
        if StorageError.matches(exc):
            raise StorageError.of(exc, path) from None
        raise
    return path


def _read_bytes(path: str | os.PathLike) -> bytes:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from exc


_QUIET_LOCK = threading.Lock()
_quiet_state = {"depth": 0, "saved": None, "level": None}


@contextlib.contextmanager
def quiet_stderr():
    """Keep C libraries' messages (OpenCV, libpng, FFmpeg) off the terminal (fd 2).

    For calls whose failure the caller reports itself, in one line. Nested and
    concurrent uses (threads) share one redirection: the first to enter redirects,
    the last to leave restores.
    """
    with _QUIET_LOCK:
        if _quiet_state["depth"] == 0:
            _quiet_state["level"] = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
            if sys.stderr is not None:
                sys.stderr.flush()  # what Python already wrote still reaches the terminal
            try:
                saved = os.dup(2)
            except OSError:  # no fd 2 (detached process): nothing to silence
                saved = None
            if saved is not None:
                try:
                    with open(os.devnull, "wb") as null:
                        os.dup2(null.fileno(), 2)
                except OSError:
                    os.close(saved)
                    saved = None
            _quiet_state["saved"] = saved
        _quiet_state["depth"] += 1
    try:
        yield
    finally:
        with _QUIET_LOCK:
            _quiet_state["depth"] -= 1
            if _quiet_state["depth"] == 0:
                saved = _quiet_state["saved"]
                if saved is not None:
                    os.dup2(saved, 2)
                    os.close(saved)
                cv2.utils.logging.setLogLevel(_quiet_state["level"])


_atomic_write = atomic_write  # the name other modules import
