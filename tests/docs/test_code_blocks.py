"""Every Python block of the README and of the documentation pages runs as written.

The blocks of one file run in order, in one namespace and one fresh Python process, in a
temporary folder in which ``stereodeblur demo`` (the README's first command, default
arguments) has run first: a block may read the demo's output ``stereodeblur-demo/`` or make
its own data. A block is a fenced block whose info string is ``python``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
# Folders under docs/ that the build writes: not pages anyone wrote.
GENERATED = {"_build", "auto_examples", "gen_modules", "jupyter_execute"}
DEMO_FOLDER = "stereodeblur-demo"
# One file's blocks: the slowest deblur a frame or two of the 320x240 demo scene.
FILE_TIMEOUT = 900
OPENING = re.compile(r"^(?P<indent> {0,3})(?P<fence>`{3,}|~{3,})\s*(?P<info>[^`\s]*)")


@dataclass(frozen=True)
class Block:
    """One fenced Python block: its source and the line of its opening fence (1-based)."""

    line: int
    source: str


def python_blocks(text: str) -> list[Block]:
    """The ``python`` fenced blocks of a Markdown text, in order (CommonMark fences)."""
    blocks = []
    lines = text.splitlines()
    k = 0
    while k < len(lines):
        match = OPENING.match(lines[k])
        if match is None:
            k += 1
            continue
        fence, indent = match["fence"], len(match["indent"])
        closing = re.compile(rf"^ {{0,3}}{fence[0]}{{{len(fence)},}}\s*$")
        end = k + 1
        while end < len(lines) and not closing.match(lines[end]):
            end += 1
        if match["info"].lower() == "python":
            body = [_unindent(line, indent) for line in lines[k + 1 : end]]
            blocks.append(Block(k + 1, textwrap.dedent("\n".join(body)) + "\n"))
        k = end + 1
    return blocks


def _unindent(line: str, indent: int) -> str:
    """``line`` without up to ``indent`` leading spaces (those of its opening fence)."""
    return line[min(indent, len(line) - len(line.lstrip(" "))) :]


def documented_files() -> list[Path]:
    """README.md and every Markdown page under docs/ (generated folders excepted)."""
    pages = sorted(p for p in DOCS.rglob("*.md") if not GENERATED & set(p.relative_to(DOCS).parts))
    return [ROOT / "README.md", *pages]


def files_with_blocks() -> list[Path]:
    return [p for p in documented_files() if python_blocks(p.read_text(encoding="utf-8"))]


DRIVER = """\
import json, sys
namespace = {"__name__": "__main__"}
for path in json.loads(sys.argv[1]):
    print(f"--- running {path}", flush=True)
    with open(path, encoding="utf-8") as file:
        code = compile(file.read(), path, "exec")
    exec(code, namespace)
"""


def _environment() -> dict:
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"  # a block that plots must not open a window
    return env


def _demo_command() -> list[str]:
    # The console script installed beside this interpreter, else the one on PATH.
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    script = shutil.which("stereodeblur", path=path)
    return [script, "demo"] if script else [sys.executable, "-m", "stereodeblur.cli", "demo"]


@pytest.fixture(scope="module")
def demo_output(tmp_path_factory) -> Path:
    """The folder ``stereodeblur demo`` wrote, run once in a fresh working folder."""
    work = tmp_path_factory.mktemp("demo")
    run = subprocess.run(
        _demo_command(), cwd=work, env=_environment(), capture_output=True, text=True,
        timeout=FILE_TIMEOUT,
    )  # fmt: skip
    assert run.returncode == 0, f"stereodeblur demo failed:\n{run.stdout}\n{run.stderr}"
    assert (work / DEMO_FOLDER / "demo.png").is_file()
    return work / DEMO_FOLDER


def test_python_blocks_are_found():
    text = textwrap.dedent(
        """\
        ```python
        a = 1
        ```
        ````markdown
        ```python
        not a block of its own
        ```
        ````
        ~~~ python
        b = a + 1
        ~~~
        ```pycon
        >>> skipped
        ```
          ```python
          c = b
          ```
        """
    )
    blocks = python_blocks(text)
    assert [b.source for b in blocks] == ["a = 1\n", "b = a + 1\n", "c = b\n"]
    assert [b.line for b in blocks] == [1, 9, 15]


def test_the_readme_has_python_blocks():
    assert python_blocks((ROOT / "README.md").read_text(encoding="utf-8"))


@pytest.mark.parametrize(
    "page", files_with_blocks(), ids=lambda p: str(p.relative_to(ROOT))
)  # fmt: skip
def test_python_blocks_run(page: Path, demo_output: Path, tmp_path: Path):
    name = page.relative_to(ROOT)
    work = tmp_path / "work"
    work.mkdir()
    shutil.copytree(demo_output, work / DEMO_FOLDER)
    scripts = []
    for k, block in enumerate(python_blocks(page.read_text(encoding="utf-8")), start=1):
        # The file name shows in tracebacks: the page, the block and its line.
        stem = re.sub(r"[^A-Za-z0-9]+", "_", str(name))
        script = tmp_path / f"{stem}-block{k}-line{block.line}.py"
        script.write_text(block.source, encoding="utf-8")
        scripts.append(str(script))
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER, encoding="utf-8")
    run = subprocess.run(
        [sys.executable, str(driver), json.dumps(scripts)], cwd=work, env=_environment(),
        capture_output=True, text=True, timeout=FILE_TIMEOUT,
    )  # fmt: skip
    if run.returncode != 0:
        pytest.fail(
            f"a Python block of {name} failed (the traceback's file name gives the block and "
            f"the line of its opening fence):\n{run.stdout[-3000:]}\n{run.stderr[-6000:]}",
            pytrace=False,
        )
