"""Errors for bad input (the CLI prints them as one line and exits with code 2) and for an
output's storage that refuses writes (one line, exit code 1); warnings about a frame's result."""

from __future__ import annotations

import errno
import os


class InputError(ValueError):
    """Input data (a file, a value, an argument) is not what was expected.

    The message names the file or value and says what was expected. When a
    library parameter is at fault (or can supply what is missing), ``parameter``
    names it, e.g. ``'exposure'``, so a front end can point at its own option.

    Parameters
    ----------
    message : str
        One line.
    parameter : str, optional
        The library parameter concerned.
    """

    def __init__(self, message: str = "", *, parameter: str | None = None):
        super().__init__(message)
        self.parameter = parameter


class FrameWarning(UserWarning):
    """A frame's result may be poor and the user should know: part of it deblurred with no
    motion (range guard), or an exposure the frames contradict. The command line prints it."""


class StorageError(OSError):
    """The output's storage refuses a write: no space left (``ENOSPC``), the disk quota
    exceeded (``EDQUOT``) or the file system read-only (``EROFS``).

    Not the input's fault and not a frame's: a run stops at once on it (what is finished
    stays, and the same run resumes later). Built like ``OSError(errno, strerror, filename)``
    with ``filename`` the file that could not be written; its message is one line naming it.
    """

    ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)

    @classmethod
    def matches(cls, exc: BaseException) -> bool:
        """Whether ``exc`` is an OSError of the storage (see :attr:`ERRNOS`)."""
        return isinstance(exc, OSError) and exc.errno in cls.ERRNOS

    @classmethod
    def of(cls, exc: OSError, path=None) -> StorageError:
        """``exc`` (one that :meth:`matches`) as a StorageError naming ``path`` (default: the
        file ``exc`` names)."""
        if isinstance(exc, StorageError) and path is None:
            return exc
        return cls(exc.errno, os.strerror(exc.errno), str(path or exc.filename or "the output"))

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {(self.strerror or '').lower()}"
