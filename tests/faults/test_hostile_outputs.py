"""Output folders that lead into an input: another scene's folder around the output, symlinks
in place of the files a run writes. Nothing is written into an input: the run is refused
(exit 2, one line) or replaces the symlink with its own file."""

import shutil

import pytest

from tests.faults.helpers import FAST, refused, run_cli, tree_checksums


@pytest.fixture
def scene(tiny_scene, tmp_path):
    """A private copy of the tiny clip (the input)."""
    return shutil.copytree(tiny_scene, tmp_path / "scene")


@pytest.fixture
def other(tiny_scene, tmp_path):
    """Another scene, with ground truth, that no run here may change."""
    return shutil.copytree(tiny_scene, tmp_path / "other")


@pytest.mark.parametrize("where", ["gt", "gt/estimated", "left/new"])
def test_sceneflow_into_another_scenes_folder(scene, other, where):
    argv = ["sceneflow", scene, "--frames", "0", "-o", other / where, "-q"]
    refused(argv, [scene, other], other / where, "another scene")
    assert not (other / where).exists() or where == "gt"


def test_sceneflow_debug_pictures_into_another_scenes_folder(scene, other, tmp_path):
    argv = ["sceneflow", scene, "--frames", "0", "-o", tmp_path / "out"]
    refused([*argv, "--debug-dir", other / "gt" / "debug"], [scene, other], "another scene")
    assert not (tmp_path / "out").exists()


def test_deblur_into_another_scenes_folder(scene, other):
    refused(["deblur", scene, "-o", other / "gt" / "deblurred", *FAST], [scene, other], other)


def test_sceneflow_view_folder_a_symlink_into_the_input(scene, tmp_path):
    out = tmp_path / "out"
    (out / "disparity").mkdir(parents=True)
    (out / "disparity" / "left").symlink_to(scene / "gt" / "disparity" / "left")
    argv = ["sceneflow", scene, "--frames", "0", "-o", out, "-q"]
    refused(argv, [scene, out], "disparity/left", "overlaps input")


@pytest.mark.parametrize(
    ("name", "target"),
    [
        ("run-log.jsonl", "gt/objects.json"),  # appended to, were the link followed
        ("run-log.jsonl", "gt/new.jsonl"),  # dangling: would be created
        (".lock", "gt/new.lock"),
        (".lock", "camera.json"),
    ],
)
def test_file_written_in_place_a_symlink_into_the_input(scene, tmp_path, name, target):
    out = tmp_path / "out"
    out.mkdir()
    (out / name).symlink_to(scene / target)
    line = refused(["deblur", scene, "-o", out, "--frames", "0", *FAST], [scene, out], out / name)
    assert "symlink" in line
    assert not (scene / target).exists() or target in ("gt/objects.json", "camera.json")


def test_results_that_are_symlinks_into_the_input_are_replaced(scene, reference, tmp_path):
    """Frames, point clouds and temporaries at symlinks into the input: the links are
    replaced by (or, for a temporary, removed like) the run's own files."""
    out = shutil.copytree(reference, tmp_path / "out")
    (out / "run-log.jsonl").unlink()  # its source is another copy of the clip
    (out / "pointcloud" / "left").mkdir(parents=True)
    for name in ("left/000000.png", "right/000000.png"):
        (out / name).unlink()
    (out / "left" / "000000.png").symlink_to(scene / "left" / "000000.png")  # a valid frame
    (out / "right" / "000000.png").symlink_to(scene / "gt" / "new.png")  # dangling
    (out / "pointcloud" / "left" / "000000.ply").symlink_to(scene / "gt" / "objects.json")
    (out / "left" / ".000000.png.0123456789ab.tmp").symlink_to(scene / "right" / "000000.png")
    before = tree_checksums(scene)
    result = run_cli("deblur", scene, "-o", out, "--frames", "0", "--point-cloud", "-q", *FAST)
    assert result.code == 0, result.stderr
    assert tree_checksums(scene) == before
    for name in ("left/000000.png", "right/000000.png", "pointcloud/left/000000.ply"):
        assert not (out / name).is_symlink() and (out / name).stat().st_size > 0, name
    for name in ("left/000000.png", "right/000000.png"):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
    assert not list(out.rglob("*.tmp"))


def test_sceneflow_files_that_are_symlinks_into_the_input_are_replaced(scene, tmp_path):
    out = tmp_path / "out"
    (out / "sceneflow").mkdir(parents=True)
    (out / "sceneflow" / "000000.npz").symlink_to(scene / "gt" / "objects.json")
    before = tree_checksums(scene)
    result = run_cli("sceneflow", scene, "--frames", "0", "-o", out, "-q")
    assert result.code == 0, result.stderr
    assert tree_checksums(scene) == before
    assert not (out / "sceneflow" / "000000.npz").is_symlink()
