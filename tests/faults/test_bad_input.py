"""Every runner case of bad input: exit 2, one line on stderr naming the file or value (and the
accepted range), no traceback, no input byte changed, nothing written."""

import shutil
import subprocess

import numpy as np
import pytest

from stereodeblur.io.formats import write_flo, write_pfm
from tests.faults.helpers import FAST, refused


@pytest.fixture
def scene(tiny_scene, tmp_path):
    """A private copy of the tiny clip, free to damage."""
    return shutil.copytree(tiny_scene, tmp_path / "scene")


def test_output_left_a_symlink_into_the_input_with_overwrite(scene, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "left").symlink_to(scene / "left")
    argv = ["deblur", scene, "-o", out, "--overwrite", "--frames", "0", *FAST]
    refused(argv, [scene, out], "left")


def test_output_that_is_another_scene(scene, tiny_scene, tmp_path):
    other = shutil.copytree(tiny_scene, tmp_path / "other")
    refused(["deblur", scene, "-o", other, *FAST], [scene, other], other)
    refused(["deblur", scene, "-o", other, "--overwrite", *FAST], [scene, other], other)


@pytest.mark.parametrize("where", ["scene", "scene/out", "scene/left"])
def test_output_inside_or_equal_to_the_input(scene, tmp_path, where):
    refused(["deblur", scene, "-o", tmp_path / where, *FAST], [tmp_path], "input")


def test_output_through_a_dangling_symlink(scene, tmp_path):
    (tmp_path / "out").symlink_to(tmp_path / "missing")
    refused(["deblur", scene, "-o", tmp_path / "out", *FAST], [scene], "does not exist")
    assert not (tmp_path / "missing").exists()


def test_output_that_is_a_file(scene, tmp_path):
    (tmp_path / "out").write_text("mine")
    refused(["deblur", scene, "-o", tmp_path / "out", *FAST], [scene, tmp_path], "out")


def test_output_in_an_immutable_folder(scene, tmp_path):
    chattr = shutil.which("chattr")
    folder = tmp_path / "locked"
    folder.mkdir()
    if chattr is None or subprocess.run([chattr, "+i", str(folder)]).returncode != 0:
        pytest.skip("chattr +i is not available here")
    try:
        refused(["deblur", scene, "-o", folder / "out", *FAST], [scene, folder], folder)
    finally:
        subprocess.run([chattr, "-i", str(folder)], check=True)


@pytest.mark.parametrize(
    ("frames", "needles"),
    [("0:100000000000", ["0:100000000000", "0..5"]), ("6", ["6", "0..5"]), ("x", ["'x'"])],
)
def test_frame_selection_out_of_range(scene, tmp_path, frames, needles):
    out = tmp_path / "out"
    refused(["deblur", scene, "-o", out, "--frames", frames, *FAST], [scene, out], *needles)


@pytest.mark.parametrize("workers", ["0", "-1", "two"])
def test_bad_worker_count(scene, tmp_path, workers):
    out = tmp_path / "out"
    refused(["deblur", scene, "-o", out, "--workers", workers, *FAST], [scene, out], "workers")


@pytest.mark.parametrize("damage", ["truncated", "empty", "not a png"])
def test_bad_input_frame_is_found_before_the_first_frame(scene, tmp_path, damage):
    path = scene / "right" / "000004.png"
    data = path.read_bytes()
    path.write_bytes({"truncated": data[:60], "empty": b"", "not a png": b"GIF89a" * 9}[damage])
    out = tmp_path / "out"
    refused(["deblur", scene, "-o", out, *FAST], [scene, out], path)


@pytest.mark.parametrize("unknown", ["nan disparity", "negative disparity", "nan flow"])
def test_ground_truth_unknown_everywhere(scene, tmp_path, unknown):
    shape = (32, 48)
    if unknown == "nan flow":
        path = scene / "gt" / "flow" / "left" / "000002.flo"
        write_flo(path, np.full((*shape, 2), np.nan, np.float32))
    else:
        path = scene / "gt" / "disparity" / "left" / "000002.pfm"
        value = np.nan if unknown == "nan disparity" else -3.0
        write_pfm(path, np.full(shape, value, np.float32))
    out = tmp_path / "out"
    refused(["deblur", scene, "-o", out, *FAST], [scene, out], path, "unknown")
