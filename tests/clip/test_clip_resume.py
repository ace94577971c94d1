"""A killed run, run again, ends with exactly the frames of an uninterrupted run."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from tests.clip.clip_helpers import FAST, frame_files, run_cli

KILL_AFTER = 4  # frames written before the kill


def test_killed_run_resumes_to_the_uninterrupted_result(clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    argv = ["deblur", str(clip_scene), "-o", str(out), "--workers", "1", "-q", *FAST]
    process = subprocess.Popen(
        [sys.executable, "-m", "stereodeblur.cli", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        start_new_session=True,  # its own process group: the kill reaches nothing else
    )
    deadline = time.monotonic() + 240
    try:
        while len(frame_files(out)) < KILL_AFTER:
            if process.poll() is not None:
                pytest.fail(f"the run ended before it could be killed: {process.stderr.read()}")
            if time.monotonic() > deadline:
                pytest.fail("no frames written within 240 s")
            time.sleep(0.01)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=60)
        process.stderr.close()
    assert process.returncode == -signal.SIGKILL
    written = frame_files(out)
    assert KILL_AFTER <= len(written) < 24, written
    before = {name: (out / name).read_bytes() for name in written}

    result = run_cli(*argv)
    assert result.code == 0, result.stderr
    assert frame_files(out) == frame_files(reference_run.output)
    for name in frame_files(out):
        assert (out / name).read_bytes() == (reference_run.output / name).read_bytes(), name
    for name, data in before.items():  # finished frames were skipped, not redone
        assert (out / name).read_bytes() == data
    log = []
    for line in (out / "run-log.jsonl").read_text().splitlines():
        try:
            log.append(json.loads(line))
        except json.JSONDecodeError:  # a line the kill cut short
            continue
    starts = [r for r in log if r.get("event") == "start"]
    assert len(starts) == 2 and starts[1]["skipped"] == len(written)
    assert log[-1]["event"] == "end" and log[-1]["done"] == 24 - len(written)
    leftovers = [p.name for view in ("left", "right") for p in (out / view).iterdir()]
    assert sorted(leftovers) == sorted(n.split("/")[1] for n in frame_files(out))


def test_interrupt_stops_the_workers_and_keeps_finished_frames(clip_scene, reference_run, tmp_path):
    out = tmp_path / "out"
    argv = ["deblur", str(clip_scene), "-o", str(out), "--workers", "2", *FAST]
    process = subprocess.Popen(
        [sys.executable, "-m", "stereodeblur.cli", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + 240
    try:
        while len(frame_files(out)) < 2 and time.monotonic() < deadline:
            assert process.poll() is None, process.stderr.read()
            time.sleep(0.01)
        os.killpg(process.pid, signal.SIGINT)  # Ctrl-C: the whole foreground group
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(timeout=60)
    assert process.returncode == 130
    assert err.strip().splitlines()[-1] == "stereodeblur: interrupted"
    with pytest.raises(ProcessLookupError):  # no worker left behind in the group
        for _ in range(100):
            os.killpg(process.pid, 0)
            time.sleep(0.05)
    written = frame_files(out)
    assert 2 <= len(written) < 24
    result = run_cli(*argv, "-q")
    assert result.code == 0, result.stderr
    for name in frame_files(reference_run.output):
        assert (out / name).read_bytes() == (reference_run.output / name).read_bytes(), name
