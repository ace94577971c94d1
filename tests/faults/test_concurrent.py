"""Two runs into one output folder: the second is refused while the first holds the folder,
and an interrupted run never deletes what another run wrote."""

import os
import signal

import pytest

from stereodeblur.clip import read_run_log
from tests.faults.helpers import FAST, frame_files, run_cli, same_frames, start_run, wait_until

pytestmark = pytest.mark.slow


def _started(out, count):
    def check():
        try:
            starts = [e for e in read_run_log(out / "run-log.jsonl").events]
        except Exception:  # the log is being created
            return False
        return sum(e["event"] == "start" for e in starts) >= count

    return check


def test_second_run_is_refused_while_the_first_runs(tiny_scene, reference, tmp_path):
    out = tmp_path / "out"
    first = start_run("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST)
    try:
        wait_until(_started(out, 1), 60, "the first run to start", first.process)
        second = run_cli("deblur", tiny_scene, "-o", out, "--frames", "5", "-q", *FAST)
        lines = second.stderr.strip().splitlines()
        assert second.code == 2 and len(lines) == 1, lines
        assert "in use by another run" in lines[0] and str(out) in lines[0]
        assert first.process.wait(timeout=120) == 0, first.process.stderr.read()
    finally:
        if first.process.poll() is None:
            first.process.kill()
            first.process.wait()
        first.process.stderr.close()
    same_frames(out, reference)
    events = read_run_log(out / "run-log.jsonl").events
    assert [e["event"] for e in events].count("start") == 1  # the refused run wrote nothing


def test_an_interrupted_run_keeps_the_frames_of_another_run(slow_scene, tmp_path):
    reference = tmp_path / "reference"
    assert run_cli("deblur", slow_scene, "-o", reference, "-q", *FAST).code == 0
    out = tmp_path / "out"
    done = run_cli("deblur", slow_scene, "-o", out, "--frames", "0", "-q", *FAST)
    assert done.code == 0, done.stderr
    kept = {name: (out / name).read_bytes() for name in frame_files(out)}
    assert len(kept) == 2
    second = start_run("deblur", slow_scene, "-o", out, "--frames", "1", "-q", *FAST)
    try:
        wait_until(_started(out, 2), 60, "the second run to start", second.process)
        os.killpg(second.process.pid, signal.SIGINT)  # about 2 s before its first frame
        assert second.process.wait(timeout=60) == 130
    finally:
        if second.process.poll() is None:
            os.killpg(second.process.pid, signal.SIGKILL)
            second.process.wait()
        second.process.stderr.close()
    assert {name: (out / name).read_bytes() for name in kept} == kept
    assert (out / "camera.json").is_file() and (out / "run-log.jsonl").is_file()
    result = run_cli("deblur", slow_scene, "-o", out, "-q", *FAST)
    assert result.code == 0, result.stderr
    same_frames(out, reference)
