"""Killing the main process of a multi-worker run leaves no process of the run alive, and the
interrupted run resumes to the output of an uninterrupted one."""

import json
import signal
import subprocess
import sys
import time

import pytest

from tests.faults.helpers import (
    FAST,
    SLOW,
    run_cli,
    same_frames,
    start_run,
    tagged_processes,
    wait_until,
)

pytestmark = pytest.mark.slow


def _kill_when_workers_are_busy(scene, out, sig, settings=FAST):
    """Start a 2-worker run, send ``sig`` to its main process only while both workers work."""
    run = start_run("deblur", scene, "-o", out, "--workers", "2", "-q", *settings)
    process = run.process
    try:
        # Main process, two workers and the pool's resource tracker.
        wait_until(lambda: len(tagged_processes(run.mark)) >= 4, 60, "the workers", process)
        wait_until(lambda: (out / "run-log.jsonl").exists(), 60, "the run log", process)
        process.send_signal(sig)
        process.wait(timeout=30)
        # A worker still starting up ends once it finds its parent gone: generous on a
        # loaded machine, and the run's processes must all end.
        deadline = time.monotonic() + 20
        while tagged_processes(run.mark) and time.monotonic() < deadline:
            time.sleep(0.05)
        left = tagged_processes(run.mark)
        assert left == [], f"processes of the run still alive after {sig!r}: {left}"
    finally:
        for pid in tagged_processes(run.mark):
            import os

            os.kill(pid, signal.SIGKILL)
        if process.poll() is None:
            process.kill()
        process.wait(timeout=30)
        err = process.stderr.read().decode("utf-8", "replace")
        process.stderr.close()
    return process.returncode, err


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_killed_main_process_leaves_no_worker_and_resumes(tiny_scene, reference, tmp_path, sig):
    out = tmp_path / "out"
    out.mkdir()  # not created by the run: kept with its log when the run stops
    code, err = _kill_when_workers_are_busy(tiny_scene, out, sig)
    if sig == signal.SIGKILL:
        assert code == -signal.SIGKILL
    else:  # handled like Ctrl-C: a clean stop, recorded in the log
        assert code == 130, err
        assert "Traceback" not in err
        events = [json.loads(line) for line in (out / "run-log.jsonl").read_text().splitlines()]
        assert events[-1]["event"] == "interrupted" and events[-1]["reason"] == "SIGTERM"
    result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "2", "-q", *FAST)
    assert result.code == 0, result.stderr
    same_frames(out, reference)
    assert not list(out.rglob("*.tmp"))


def test_a_starting_worker_watches_its_parent_before_the_heavy_imports():
    """A pool worker unpickles its start function (``clip.worker.init_worker``) before it can
    watch its parent; that import must not pull in numba and the pipeline, which take seconds on
    a loaded machine while a killed run's worker lives on."""
    code = (
        "import sys, stereodeblur.clip.worker; "
        "print(sorted(m for m in ('numba', 'stereodeblur.pipeline', 'stereodeblur.sceneflow') "
        "if m in sys.modules))"
    )
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert loaded == "[]"


def test_sigterm_before_the_first_frame_removes_the_folder_it_created(slow_scene, tmp_path):
    out = tmp_path / "out"
    code, err = _kill_when_workers_are_busy(slow_scene, out, signal.SIGTERM, SLOW)
    assert code == 130, err
    assert not out.exists()
    assert "run-log" not in err  # no pointer to a file that is gone


def test_resuming_a_finished_output_with_workers_runs_nothing(tiny_scene, reference, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(reference, out)
    result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "2", *FAST)
    assert result.code == 0, result.stderr
    assert "wrote 0 frame(s)" in result.stdout and "12 already done" in result.stdout
    assert result.stderr == ""
    same_frames(out, reference)


def test_an_interrupt_inside_exec_still_exits_130(tmp_path):
    """Ctrl-C landing in an ``exec`` of a string (a dataclass being created as a module is
    imported mid-run) exits 130 like any other; CPython alone ends such a ``python -m`` process
    by SIGINT."""
    (tmp_path / "interrupted_cli.py").write_text(
        "import argparse, importlib\n"
        "cli = importlib.import_module('stereodeblur.cli.main')\n"
        "def interrupted(args):\n"
        "    exec('raise KeyboardInterrupt')\n"
        "class Parser:\n"
        "    def parse_args(self, argv):\n"
        "        return argparse.Namespace(func=interrupted)\n"
        "cli.build_parser = Parser\n"
        "cli.run()\n"
    )
    done = subprocess.run(
        [sys.executable, "-m", "interrupted_cli"], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 130, done.stderr
    assert done.stderr == "stereodeblur: interrupted\n"
