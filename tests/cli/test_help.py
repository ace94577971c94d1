"""``--help`` of the tool and of every command works and names the command."""

import pytest

from stereodeblur.cli import main

COMMANDS = [
    [],
    ["deblur"],
    ["sceneflow"],
    ["demo"],
    ["synth", "planar"],
    ["synth", "objects"],
    ["synth", "average"],
    ["render-view"],
    ["kernels"],
    ["bench", "planar"],
    ["bench", "sceneflow"],
    ["bench", "paper"],
]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c) or "stereodeblur")
def test_help(command, capsys):
    assert main([*command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: stereodeblur " + " ".join(command))


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("stereodeblur ")
