"""Helpers of the fault-injection tests: runs as subprocesses tagged in their environment,
finding a run's processes through /proc, checksums of folders."""

import hashlib
import io
import os
import subprocess
import sys
import time
import uuid
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
from types import SimpleNamespace

NUM_FRAMES = 6
SIZE = (48, 32)
# Ground-truth motion, one IRLS round of two CG steps: the tests are about the plumbing.
FAST = ["--motion-source", "gt", "--irls", "1", "--cg", "2", "--samples", "8"]
# Seconds per frame on the 200x150 ``slow_scene``: a signal lands before the first frame.
SLOW = ["--motion-source", "gt", "--alpha", "0.001", "--irls", "8", "--cg", "100"]
MARK = "STEREODEBLUR_FAULT_TEST"


def run_cli(*argv) -> SimpleNamespace:
    """``stereodeblur ARGV`` in this process: exit code, stdout and stderr."""
    from stereodeblur.cli import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return SimpleNamespace(code=code, stdout=out.getvalue(), stderr=err.getvalue())


def start_run(*argv, stderr=subprocess.PIPE) -> SimpleNamespace:
    """``stereodeblur ARGV`` as a subprocess in its own session, tagged by a unique marker
    in its environment (inherited by every process it starts)."""
    mark = uuid.uuid4().hex
    env = {**os.environ, MARK: mark}
    process = subprocess.Popen(
        [sys.executable, "-m", "stereodeblur.cli", *map(str, argv)],
        stdout=subprocess.DEVNULL,
        stderr=stderr,
        env=env,
        start_new_session=True,
    )
    return SimpleNamespace(process=process, mark=mark)


def tagged_processes(mark: str) -> list[int]:
    """Live processes whose environment holds ``MARK=mark`` (zombies do not count)."""
    needle = f"{MARK}={mark}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if needle not in (entry / "environ").read_bytes().split(b"\0"):
                continue
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z":
            found.append(int(entry.name))
    return found


def wait_until(condition, timeout: float, what: str, process=None) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if process is not None and process.poll() is not None:
            err = process.stderr.read() if process.stderr else ""
            raise AssertionError(f"the run ended before {what}: {err}")
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def frame_files(root: Path, views=("left", "right")) -> list[str]:
    """Relative paths of the frame PNGs under ``root``."""
    if not root.exists():
        return []
    return sorted(f"{v}/{p.name}" for v in views for p in (root / v).glob("[0-9]*.png"))


def tree_checksums(root: Path) -> dict[str, str]:
    """SHA-256 of every file under ``root`` (symlinks by target), by relative path."""
    sums = {}
    for path in sorted(Path(root).rglob("*")):
        relative = path.relative_to(root).as_posix()
        if path.is_symlink():
            sums[relative] = "link:" + os.readlink(path)
        elif path.is_file():
            sums[relative] = hashlib.sha256(path.read_bytes()).hexdigest()
        else:
            sums[relative] = "dir"
    return sums


def refused(argv, watched, *needles) -> str:
    """Run ``stereodeblur ARGV``; check it is refused (exit 2, one line holding every needle)
    and no watched tree changed; return the line."""
    before = {path: tree_checksums(path) if path.exists() else None for path in watched}
    result = run_cli(*argv)
    lines = result.stderr.strip().splitlines()
    assert result.code == 2, result.stderr
    assert len(lines) == 1 and "Traceback" not in result.stderr, lines
    for needle in needles:
        assert str(needle) in lines[0], (needle, lines[0])
    after = {path: tree_checksums(path) if path.exists() else None for path in watched}
    assert after == before
    return lines[0]


def same_frames(out: Path, reference: Path) -> None:
    assert frame_files(out) == frame_files(reference)
    for name in frame_files(reference):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
