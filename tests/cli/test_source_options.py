"""``--exposure`` and ``--overwrite`` do what their help says."""

import json

import pytest

from stereodeblur.cli import main
from tests.cli.refusals import refused, tree_checksums
from tests.conftest import write_tiny_scene

# Ground-truth motion and the fewest iterations: these tests are about the options.
FAST = ["--motion-source", "gt", "--samples", "2", "--irls", "1", "--cg", "1"]
FAST += ["--views", "left", "--frames", "1", "--workers", "1", "-q"]


def test_exposure_given_overrides_the_one_the_source_states(tiny_scene, tmp_path):
    stated = json.loads((tiny_scene / "camera.json").read_text())["exposure"]
    out = tmp_path / "out"
    assert main(["deblur", str(tiny_scene), "-o", str(out), "--exposure", "0.01", *FAST]) == 0
    written = json.loads((out / "camera.json").read_text())
    assert stated != 0.01 and written["exposure"] == 0.01


def _with_stray_file(folder):
    folder.mkdir()
    (folder / "notes.txt").write_text("not a scene")
    return folder


@pytest.mark.parametrize("command", ["deblur", "synth average"])
def test_overwrite_allows_a_folder_with_other_files(tiny_scene, tmp_path, capsys, command):
    out = _with_stray_file(tmp_path / "out")
    if command == "deblur":
        argv = ["deblur", tiny_scene, "-o", out, *FAST]
    else:
        argv = ["synth", "average", tiny_scene, out, "--window", "1", "-q"]
    refused(capsys, argv, inputs=[tiny_scene], fragments=["not empty"])
    assert not (out / "left").exists()
    assert main([str(a) for a in [*argv, "--overwrite"]]) == 0
    assert (out / "notes.txt").read_text() == "not a scene"
    assert (out / "left" / "000001.png").is_file()


@pytest.mark.parametrize("command", ["deblur", "synth average"])
def test_overwrite_never_writes_into_another_scene(tiny_scene, tmp_path, capsys, command):
    other = write_tiny_scene(tmp_path / "other", seed=1)
    if command == "deblur":
        argv = ["deblur", tiny_scene, "-o", other, "--overwrite", *FAST]
    else:
        argv = ["synth", "average", tiny_scene, other, "--window", "1", "--overwrite"]
    before = tree_checksums(other)
    refused(capsys, argv, inputs=[tiny_scene, other], fragments=["another scene"])
    assert tree_checksums(other) == before


def test_overwrite_deblurs_finished_frames_again(tiny_scene, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["deblur", str(tiny_scene), "-o", str(out), *FAST[:-1]]
    assert main(argv) == 0
    assert main(argv) == 0
    assert "1 already done" in capsys.readouterr().out
    assert main([*argv, "--overwrite"]) == 0
    assert "already done" not in capsys.readouterr().out
