"""A full disk (``ENOSPC``; also ``EDQUOT``, ``EROFS``) met while writing a result: one line
naming the file, exit 1, the run stops at once, no temporary left, and the same command
resumes to the output of an uninterrupted run. The error is injected at ``os.fsync`` of the
files under the output, so the real writer meets it with its temporary half done."""

import errno
import os

import pytest

from stereodeblur.clip import read_run_log
from tests.faults.helpers import FAST, frame_files, run_cli, same_frames, tree_checksums

MESSAGES = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EROFS: "read-only file system",
}


def _full_disk(monkeypatch, under, needle: str, number: int = errno.ENOSPC) -> None:
    """``os.fsync`` of a file under ``under`` whose name holds ``needle`` fails with ``number``."""
    real = os.fsync
    under = str(under.resolve())

    def fsync(fd):
        name = os.readlink(f"/proc/self/fd/{fd}")
        if name.startswith(under) and needle in os.path.basename(name):
            raise OSError(number, os.strerror(number))
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


@pytest.mark.parametrize("number", list(MESSAGES))
def test_full_disk_stops_the_run_and_it_resumes(
    tiny_scene, reference, tmp_path, monkeypatch, number
):
    import stereodeblur.clip.worker as worker

    out = tmp_path / "out"
    out.mkdir()
    before = tree_checksums(tiny_scene)
    deblurred = []
    real_deblur = worker._deblur_views

    def counting(source, index, views, job, progress):
        deblurred.append(index)
        return real_deblur(source, index, views, job, progress)

    monkeypatch.setattr(worker, "_deblur_views", counting)
    with monkeypatch.context() as patch:
        _full_disk(patch, out / "left", "000002", number)
        result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST)
    lines = result.stderr.strip().splitlines()
    assert result.code == 1 and len(lines) == 1, result.stderr
    assert str(out / "left" / "000002.png") in lines[0] and MESSAGES[number] in lines[0]
    assert deblurred == [0, 1, 2]  # stopped at once: no further frame computed
    assert frame_files(out) == [f"{v}/00000{i}.png" for v in ("left", "right") for i in (0, 1)]
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
    assert tree_checksums(tiny_scene) == before
    events = read_run_log(out / "run-log.jsonl").events
    assert events[-1]["event"] == "interrupted" and MESSAGES[number] in events[-1]["reason"]
    assert events[-2]["storage_errno"] == number
    resumed = run_cli("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST)
    assert resumed.code == 0, resumed.stderr
    assert "4 already done" in resumed.stdout
    same_frames(out, reference)


def test_full_disk_on_the_first_frame_leaves_no_folder(tiny_scene, tmp_path, monkeypatch):
    out = tmp_path / "out"
    _full_disk(monkeypatch, tmp_path, "000000")
    result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST)
    lines = result.stderr.strip().splitlines()
    assert result.code == 1 and len(lines) == 1 and "no space left" in lines[0], lines
    assert not out.exists()


def test_full_disk_for_the_run_log(tiny_scene, tmp_path, monkeypatch):
    """The log is appended to, not replaced: the write of its first frame line fails."""
    from stereodeblur.clip import runlog

    class FullAfterTheStart:
        def __init__(self, handle):
            self.handle = handle
            self.closed = False

        def write(self, data):
            if b'"event": "frame"' in bytes(data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return self.handle.write(data)

        def close(self):
            self.handle.close()
            self.closed = True

    real_init = runlog.RunLogWriter.__init__

    def init(self, path):
        real_init(self, path)
        self._handle = FullAfterTheStart(self._handle)

    monkeypatch.setattr(runlog.RunLogWriter, "__init__", init)
    out = tmp_path / "out"
    out.mkdir()
    result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST)
    lines = result.stderr.strip().splitlines()
    assert result.code == 1 and len(lines) == 1, result.stderr
    assert str(out / "run-log.jsonl") in lines[0] and "no space left" in lines[0]
    assert len(frame_files(out)) == 2  # the first frame's views, then the run stopped


def test_full_disk_in_sceneflow(tiny_scene, tmp_path, monkeypatch):
    out = tmp_path / "out"
    _full_disk(monkeypatch, tmp_path, "000000.flo")
    result = run_cli("sceneflow", tiny_scene, "--frames", "0", "-o", out, "-q")
    lines = result.stderr.strip().splitlines()
    assert result.code == 1 and len(lines) == 1, result.stderr
    assert str(out / "flow" / "left" / "000000.flo") in lines[0] and "no space left" in lines[0]
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
