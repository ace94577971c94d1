"""A multi-worker run with numba's cache empty, as on the first run after ``pip install .``."""

import os
import subprocess
import sys

import pytest

from tests.faults.helpers import FAST, same_frames

pytestmark = pytest.mark.slow


def test_a_two_worker_run_compiles_in_its_workers(tiny_scene, reference, tmp_path):
    """Every frame failed here while the workers set NUMBA_NUM_THREADS after numba loaded
    (warm caches in the source tree hid it: only a compilation fails)."""
    out = tmp_path / "out"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    argv = ["deblur", tiny_scene, "-o", out, "--workers", "2", "-q", *FAST]
    run = subprocess.run(
        [sys.executable, "-m", "stereodeblur.cli", *map(str, argv)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    assert any((tmp_path / "numba-cache").rglob("*.nbi"))  # the workers did compile
    same_frames(out, reference)
