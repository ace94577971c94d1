"""A first run says that it compiles the kernels: numba's cache for them is empty."""

import os
import shutil
import subprocess
import sys

from stereodeblur.cli.printer import COMPILE_NOTICE
from tests.clip.clip_helpers import run_cli

CHECK = """
from stereodeblur._kernel_cache import kernels_cached
from stereodeblur.blur.trajectories import clamp
module = ("stereodeblur.blur.trajectories",)
before = kernels_cached(module)
clamp(3.0, 2.0)  # compiles one kernel of the module and caches it
print(before, kernels_cached(module))
"""


def test_an_empty_cache_is_told_from_one_with_kernels(tmp_path):
    """With a fresh NUMBA_CACHE_DIR the kernels count as not cached until one is compiled."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    result = subprocess.run(
        [sys.executable, "-c", CHECK], env=env, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "True"]
    assert list((tmp_path / "numba").rglob("trajectories.clamp-*.nbi"))


def test_deblur_says_it_compiles_before_the_first_frame(tiny_scene, tmp_path, monkeypatch):
    from stereodeblur import _kernel_cache

    options = ["--motion-source", "gt", "--irls", "1", "--cg", "2", "--samples", "8",
               "--frames", "0", "--workers", "1"]  # fmt: skip
    monkeypatch.setattr(_kernel_cache, "kernels_cached", lambda modules: False)
    first = run_cli("deblur", tiny_scene, "-o", tmp_path / "a", *options)
    assert first.code == 0, first.stderr
    lines = first.stderr.splitlines()
    assert lines.count(f"stereodeblur: {COMPILE_NOTICE}") == 1
    assert lines.index(f"stereodeblur: {COMPILE_NOTICE}") == 0  # before any frame's progress
    quiet = run_cli("deblur", tiny_scene, "-o", tmp_path / "b", *options, "-q")
    assert COMPILE_NOTICE not in quiet.stderr
    monkeypatch.setattr(_kernel_cache, "kernels_cached", lambda modules: True)
    later = run_cli("deblur", tiny_scene, "-o", tmp_path / "c", *options)
    assert later.code == 0 and COMPILE_NOTICE not in later.stderr
    assert "frame 0: motion (gt)" in later.stderr  # the stages show in a serial run too


def test_sceneflow_says_it_compiles(tiny_scene, tmp_path, monkeypatch):
    from stereodeblur import _kernel_cache

    asked = []
    monkeypatch.setattr(_kernel_cache, "kernels_cached", lambda modules: asked.append(modules))
    result = run_cli("sceneflow", tiny_scene, "-o", tmp_path / "sf", "--frames", "0")
    assert result.code == 0, result.stderr
    assert result.stderr.splitlines()[0] == f"stereodeblur: {COMPILE_NOTICE}"
    assert asked == [_kernel_cache.SCENEFLOW_MODULES]


def test_bad_input_is_one_line_on_a_first_run(tiny_scene, tmp_path, monkeypatch):
    """The notice waits for the inputs to be checked: a bad frame on a fresh install still
    gives one line, as on any other run."""
    from stereodeblur import _kernel_cache

    monkeypatch.setattr(_kernel_cache, "kernels_cached", lambda modules: False)
    scene = shutil.copytree(tiny_scene, tmp_path / "bad-scene")
    (scene / "left" / "000001.png").write_bytes(b"not a png")
    for command in ("deblur", "sceneflow"):
        result = run_cli(command, scene, "-o", tmp_path / f"out-{command}")
        assert result.code == 2, result.stderr
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr
        assert COMPILE_NOTICE not in result.stderr
