"""Helpers of the clip tests: the CLI in this process, listing written frames."""

import io
from contextlib import redirect_stderr, redirect_stdout
from types import SimpleNamespace

from stereodeblur.cli import main

NUM_FRAMES = 12
SIZE = (64, 48)
# Ground-truth motion and few iterations: these tests are about plumbing, not speed.
FAST = ["--motion-source", "gt", "--irls", "2", "--cg", "5", "--samples", "16"]


def run_cli(*argv) -> SimpleNamespace:
    """``stereodeblur ARGV`` in this process; exit code, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main([str(a) for a in argv])
    return SimpleNamespace(code=code, stdout=out.getvalue(), stderr=err.getvalue())


def frame_files(root, views=("left", "right")):
    """Relative paths of the frame PNGs written under ``root``."""
    if not root.exists():
        return []
    return sorted(f"{view}/{p.name}" for view in views for p in (root / view).glob("[0-9]*.png"))
