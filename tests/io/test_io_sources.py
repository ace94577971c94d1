"""Detecting the kind of input, and timing/colour overrides on scene folders."""

import os

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.scene import Scene
from stereodeblur.io.sources import SourceSpec, detect_source, open_source
from tests.conftest import write_tiny_scene


def test_scene_folder_is_a_scene(tiny_scene):
    assert detect_source([tiny_scene]) == "scene"
    scene = open_source(tiny_scene)
    assert isinstance(scene, Scene) and scene.info.exposure.exposure == 0.04
    assert scene.name == "scene"


def test_overrides_apply_to_scene_folders(tiny_scene):
    stored = open_source(tiny_scene).read_frame("left", 1)
    scene = open_source(tiny_scene, exposure=0.01, frame_rate=25.0, color="srgb")
    assert (scene.info.exposure.frame_rate, scene.info.exposure.exposure) == (25.0, 0.01)
    decoded = scene.read_frame("left", 1)
    np.testing.assert_array_equal(scene.read_frame("left", 1, linear=False), stored)
    assert np.all(decoded <= stored + 1e-7) and np.any(decoded < stored - 1e-3)


def test_spec_reopens_the_same_source_from_another_folder(tiny_scene, monkeypatch):
    spec = SourceSpec.from_arguments(os.path.relpath(tiny_scene), exposure=0.01)
    assert os.path.isabs(spec.paths[0])
    monkeypatch.chdir("/")
    assert spec.open().info.exposure.exposure == 0.01
    assert hash(spec) == hash(SourceSpec.from_arguments(tiny_scene, exposure=0.01))


@pytest.mark.parametrize(
    "case, error, fragment",
    [
        ("missing", FileNotFoundError, "not found"),
        ("single file", InputError, "single file"),
        ("three paths", InputError, "got 3 paths"),
        ("unknown folder", InputError, "not a scene folder"),
        ("calib for a folder", InputError, "calib is only for video pairs"),
        ("sequence for a scene", InputError, "sequence is only for KITTI"),
        ("bad colour", InputError, "color must be 'linear' or 'srgb'"),
        ("negative exposure", InputError, "exposure must be a non-negative number"),
    ],
)
def test_bad_inputs(case, error, fragment, tmp_path):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=2)
    (tmp_path / "file.txt").write_text("x")
    (tmp_path / "empty").mkdir()
    paths, options = [scene], {}
    if case == "missing":
        paths = [tmp_path / "nope"]
    elif case == "single file":
        paths = [tmp_path / "file.txt"]
    elif case == "three paths":
        paths = [scene, scene, scene]
    elif case == "unknown folder":
        paths = [tmp_path / "empty"]
    elif case == "calib for a folder":
        options["calib"] = tmp_path / "file.txt"
    elif case == "sequence for a scene":
        options["sequence"] = 3
    elif case == "bad colour":
        options["color"] = "gamma"
    elif case == "negative exposure":
        options["exposure"] = -1
    with pytest.raises(error, match=fragment) as raised:
        open_source(paths, **options)
    assert "--" not in str(raised.value)  # the library names parameters, not options
    if options:
        assert raised.value.parameter == next(iter(options))


def test_the_command_line_names_its_option_for_a_parameter(tmp_path, capsys):
    from stereodeblur.cli import main

    scene = write_tiny_scene(tmp_path / "scene", num_frames=2)
    out = tmp_path / "out"
    code = main(["deblur", str(scene), "--exposure", "-1", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "exposure" in err[0] and "--exposure" in err[0]
    assert not out.exists()
