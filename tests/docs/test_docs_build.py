"""The documentation builds without a warning, and its gallery's figures are drawn by the build.

Runs the build command of the README (``python -m sphinx -W --keep-going -b html docs OUT``)
with the output and the doctrees in a temporary folder. Sphinx-gallery writes the gallery's
pages into ``docs/auto_examples/`` (ignored by git) and runs every example on every build.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(p.stem for p in (ROOT / "examples").glob("plot_*.py"))
# The whole build, gallery included, takes 1-3 min on 2 cores.
BUILD_TIMEOUT = 1800


def test_there_are_gallery_examples():
    assert len(EXAMPLES) >= 4, EXAMPLES


def test_docs_build_without_warnings(tmp_path: Path):
    out = tmp_path / "html"
    command = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html"]
    command += ["-d", str(tmp_path / "doctrees"), "docs", str(out)]
    env = dict(os.environ, MPLBACKEND="Agg")
    start = time.time()
    run = subprocess.run(
        command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=BUILD_TIMEOUT
    )
    if run.returncode != 0:
        pytest.fail(
            f"the documentation build failed (exit {run.returncode}):\n"
            f"{run.stdout[-4000:]}\n{run.stderr[-8000:]}",
            pytrace=False,
        )
    for page in ("index", "method", "api/index", "auto_examples/index"):
        assert (out / f"{page}.html").is_file(), page
    drawn = ROOT / "docs" / "auto_examples" / "images"
    for name in EXAMPLES:
        assert (out / "auto_examples" / f"{name}.html").is_file(), name
        figures = sorted((out / "_images").glob(f"sphx_glr_{name}_[0-9][0-9][0-9].png"))
        assert figures, f"no figure of {name} in the built pages"
        # Each figure shown was drawn by this build, not left by an earlier one.
        stale = [p.name for p in figures if (drawn / p.name).stat().st_mtime < start - 1]
        assert not stale, f"figures of {name} not drawn by this build: {stale}"
