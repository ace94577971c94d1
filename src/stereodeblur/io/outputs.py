"""Output safety: the rules every command that writes follows, with symlinks resolved.

An output (a folder, or a single file such as a rendered PNG) is checked by
:func:`check_output` before anything is written:

- it is never equal to or inside an input (file or folder), and no input lies inside it;
  the output, each of its existing parents and each subfolder that will be written
  (e.g. ``OUT/left`` being a symlink into the input) are compared after ``Path.resolve``;
- it never goes through a dangling symlink (a clear error instead of ``FileExistsError``);
- it is never a folder holding another scene (``camera.json`` and frames), nor inside one
  (``OTHER_SCENE/gt``), unless that scene is this command's own earlier output, recognised by
  the marker file :data:`MARKER` (written by :func:`mark_output`) or, for ``deblur``, by its
  run log :data:`RUN_LOG`;
- a file the command opens in place (appends to or locks, such as the run log and
  :data:`LOCK_NAME`) is never a symlink: opening it would follow the link, maybe into an
  input. Every other file is written to a temporary name and renamed over its target, which
  replaces a symlink there instead of following it;
- a folder that cannot be written is an :class:`~stereodeblur.errors.InputError` naming it,
  not a ``PermissionError``.

Files are written atomically (a temporary name in the target folder, then a rename) by
:func:`atomic_write` (the writer of :mod:`stereodeblur.io.formats`) and
:func:`atomic_write_text`. :class:`OutputLock` holds ``OUT/.lock`` (``fcntl.flock``) for a
whole run, so a second run into the same folder is refused instead of mixing with the first.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import InputError
from .formats import _atomic_write as atomic_write

__all__ = [
    "LOCK_NAME",
    "MARKER",
    "RUN_LOG",
    "OutputLock",
    "atomic_write",
    "atomic_write_text",
    "check_output",
    "is_own_output",
    "is_scene_folder",
    "make_folder",
    "mark_output",
    "open_in_place",
    "resolve_output",
    "writing_errors",
]

MARKER = ".stereodeblur-output.json"
RUN_LOG = "run-log.jsonl"
LOCK_NAME = ".lock"
_FRAME_FOLDERS = ("left", "right")
# Errors of the file system that mean "this place cannot be written" rather than a bug.
_UNWRITABLE = (errno.EACCES, errno.EPERM, errno.EROFS)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and a rename."""
    return atomic_write(path, text.encode("utf-8"))


def _dangling(path: Path) -> Path | None:
    """The first of ``path`` and its parents that is a symlink to nothing, if any."""
    for item in [path, *path.parents]:
        if item.is_symlink() and not item.exists():
            return item
    return None


def resolve_output(path: str | os.PathLike) -> Path:
    """``path`` with every symlink resolved; an InputError for a dangling or looping link."""
    path = Path(os.path.abspath(os.fspath(path)))
    broken = _dangling(path)
    if broken is not None:
        raise InputError(
            f"output {path} goes through {broken}, a symlink to {os.readlink(broken)}, "
            "which does not exist"
        )
    try:
        return path.resolve(strict=False)
    except (OSError, RuntimeError) as exc:  # a symlink loop
        raise InputError(f"output {path} cannot be resolved: {exc}") from None


def _foreign_scene(folder: Path, command: str | None) -> Path | None:
    """The first of ``folder`` and its parents that holds a scene not written by ``command``."""
    for item in [folder, *folder.parents]:
        if item.is_dir() and is_scene_folder(item) and not is_own_output(item, command):
            return item
    return None


def _check_in_place(folder: Path, shown: Path, names: Iterable[str]) -> None:
    """Files of ``folder`` opened in place may not be symlinks (dangling or not)."""
    for name in names:
        path = folder / name
        if path.is_symlink():
            raise InputError(
                f"refusing to write output {shown}: {path} is a symlink (to "
                f"{os.readlink(path)}) and is written in place; remove the link"
            )


def is_scene_folder(folder: Path) -> bool:
    """Whether ``folder`` holds a scene: ``camera.json`` and at least one frame PNG."""
    if not (folder / "camera.json").exists():
        return False
    for view in _FRAME_FOLDERS:
        with contextlib.suppress(OSError):
            if any(p.suffix == ".png" for p in (folder / view).iterdir()):
                return True
    return False


def is_own_output(folder: Path, command: str | None) -> bool:
    """Whether ``folder`` was written by ``command`` of this tool (its marker or run log)."""
    try:
        marker = json.loads((folder / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        marker = None
    if isinstance(marker, dict) and marker.get("command") == command:
        return True
    return command == "deblur" and (folder / RUN_LOG).is_file()


def mark_output(folder: str | os.PathLike, command: str) -> Path:
    """Mark ``folder`` as the output of ``command`` (see :func:`is_own_output`)."""
    path = Path(folder) / MARKER
    if is_own_output(Path(folder), command) and path.is_file():
        return path
    return atomic_write_text(path, json.dumps({"command": command}) + "\n")


def _nearest_existing(path: Path) -> Path:
    for item in [path, *path.parents]:
        if item.exists():
            return item
    return Path(path.anchor)


def _check_writable(target: Path, shown: Path) -> None:
    folder = _nearest_existing(target)
    if not folder.is_dir():
        raise InputError(f"output {shown}: {folder} exists and is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"output {shown}: cannot write to {folder} (permission denied)")
    probe = folder / f".stereodeblur-probe-{os.getpid()}-{secrets.token_hex(4)}"
    try:  # catches what access() does not: read-only mounts, immutable folders, root
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    except OSError as exc:
        raise InputError(
            f"output {shown}: cannot write to {folder} ({exc.strerror or exc})"
        ) from None
    probe.unlink(missing_ok=True)


def _overlap(target: Path, source: Path) -> bool:
    return target == source or source in target.parents or target in source.parents


def check_output(
    output: str | os.PathLike,
    inputs: Iterable[str | os.PathLike] = (),
    *,
    subfolders: Iterable[str] = (),
    command: str | None = None,
    kind: str = "folder",
    in_place: Iterable[str] = (),
) -> Path:
    """Check that ``output`` may be written; return it with its symlinks resolved.

    Parameters
    ----------
    output : path
        The output folder (``kind='folder'``) or file (``kind='file'``).
    inputs : iterable of path
        Files and folders the command reads; none may overlap the output.
    subfolders : iterable of str
        Subfolders of a folder output that will be written (``'left'``, ``'gt/flow'``); each
        is resolved too, so one that is a symlink into an input is caught.
    command : str, optional
        The command writing; a folder holding another scene, or inside one, is accepted only
        when that scene is this command's own earlier output.
    kind : {'folder', 'file'}
    in_place : iterable of str
        Files of a folder output that are opened in place rather than replaced (the run log,
        the lock); none may be a symlink.

    Raises
    ------
    InputError
        Naming the output and the rule it breaks.
    """
    if kind not in ("folder", "file"):
        raise InputError(f"kind must be 'folder' or 'file', got {kind!r}")
    shown = Path(output)
    resolved = resolve_output(output)
    if kind == "folder" and resolved.exists() and not resolved.is_dir():
        raise InputError(f"output folder {shown} exists and is not a folder")
    if kind == "file" and resolved.is_dir():
        raise InputError(f"output file {shown} is a folder")
    targets = [resolved]
    if kind == "folder":
        targets += [resolve_output(Path(os.path.abspath(shown)) / name) for name in subfolders]
    sources = [(item, Path(os.path.abspath(os.fspath(item))).resolve()) for item in inputs]
    for target in targets:
        for item, source in sources:
            if _overlap(target, source):
                where = "" if target == resolved else f" (through {target})"
                raise InputError(
                    f"refusing to write output {shown}{where}: it overlaps input {item}; "
                    "choose a separate output"
                )
    if kind == "folder":
        for target in targets:
            folder = _foreign_scene(target, command)
            if folder is not None:
                raise InputError(
                    f"refusing to write output {shown} into {folder}: it holds another scene "
                    "(camera.json and frames); choose another folder"
                )
        _check_in_place(resolved, shown, in_place)
    for target in targets:
        _check_writable(target, shown)
    return resolved


def open_in_place(path: str | os.PathLike, flags: int) -> int:
    """``os.open(path, flags | O_CREAT)`` that refuses a symlink at ``path`` (dangling or not)
    with an InputError instead of following it."""
    nofollow = getattr(os, "O_NOFOLLOW", 0)
    try:
        return os.open(path, flags | os.O_CREAT | nofollow, 0o666)
    except OSError:
        if not Path(path).is_symlink():
            raise
    raise InputError(f"{path} is a symlink (to {os.readlink(path)}); remove the link")


def make_folder(folder: str | os.PathLike) -> Path:
    """Create ``folder`` (and its parents); an InputError naming it when that is refused."""
    folder = Path(folder)
    with writing_errors(folder):
        folder.mkdir(parents=True, exist_ok=True)
    return folder


@contextlib.contextmanager
def writing_errors(where: str | os.PathLike) -> Iterator[None]:
    """Turn "cannot write here" errors (permission, read-only, dangling link) into InputError."""
    try:
        yield
    except FileExistsError as exc:
        name = exc.filename or where
        raise InputError(f"cannot write {name}: it exists and is not a folder") from None
    except OSError as exc:
        if exc.errno not in _UNWRITABLE:
            raise
        name = exc.filename or where
        raise InputError(f"cannot write {name}: {exc.strerror or exc}") from None


class OutputLock:
    """``fcntl.flock`` on ``FOLDER/.lock`` (or ``FOLDER/name``) held while the ``with``
    block runs.

    A second holder (another process) is refused with an InputError at once instead of
    waiting, or with ``wait`` waits for the first to release it (a shared cache whose entries
    each process makes if missing). The lock file stays (removing it would race with a
    waiting locker); it is empty.
    """

    def __init__(self, folder: str | os.PathLike, *, name: str = LOCK_NAME, wait: bool = False):
        self.folder = Path(folder)
        self.path = self.folder / name
        self.wait = wait
        self._fd: int | None = None

    def __enter__(self) -> OutputLock:
        import fcntl

        with writing_errors(self.path):
            fd = open_in_place(self.path, os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX if self.wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise InputError(
                    f"output {self.folder} is in use by another run (locked: {self.path}); "
                    "wait for it to finish or choose another folder"
                ) from None
            raise
        self._fd = fd
        return self

    def release(self) -> None:
        """Release the lock (idempotent)."""
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor releases the flock
            self._fd = None

    def __exit__(self, *exc) -> None:
        self.release()
