"""Helpers of the refusal tests: run the CLI in this process, checksum an input tree."""

import hashlib
from pathlib import Path

from stereodeblur.cli import main


def tree_checksums(root) -> dict[str, str]:
    """SHA-256 of every file under ``root`` (symlinks followed), by relative path."""
    root = Path(root)
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def refused(capsys, argv, *, inputs=(), outputs=(), fragments=()) -> str:
    """Run ``stereodeblur ARGV``; check exit 2, one error line holding every fragment,
    no traceback, no input byte changed and no output written. Returns the line."""
    before = {str(p): tree_checksums(p) for p in inputs}
    capsys.readouterr()
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if not line.startswith("[")]
    assert code == 2, (code, captured.err)
    assert len(lines) == 1, lines
    assert lines[0].startswith("stereodeblur: error: "), lines
    assert "Traceback" not in captured.err
    for fragment in fragments:
        assert str(fragment) in lines[0], (fragment, lines[0])
    for p in inputs:
        assert tree_checksums(p) == before[str(p)], f"input {p} changed"
    for p in outputs:
        assert not Path(p).exists(), f"{p} was written"
    return lines[0]
