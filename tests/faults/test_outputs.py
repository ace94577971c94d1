"""Output safety rules (stereodeblur.io.outputs): symlinks, other scenes, permissions, lock."""

import json
import os

import pytest

from stereodeblur.errors import InputError
from stereodeblur.io.outputs import (
    MARKER,
    RUN_LOG,
    OutputLock,
    atomic_write_text,
    check_output,
    is_own_output,
    make_folder,
    mark_output,
    open_in_place,
    writing_errors,
)


def _scene(root):
    (root / "left").mkdir(parents=True)
    (root / "camera.json").write_text("{}")
    (root / "left" / "000000.png").write_bytes(b"x")
    return root


def test_separate_output_is_accepted(tmp_path):
    scene = _scene(tmp_path / "scene")
    out = check_output(tmp_path / "out", [scene], subfolders=["left", "right"])
    assert out == (tmp_path / "out").resolve()
    assert not (tmp_path / "out").exists()  # checking writes nothing


@pytest.mark.parametrize("where", ["scene", "scene/gt", "scene/sf/deep", "."])
def test_output_overlapping_the_input_is_refused(tmp_path, where):
    scene = _scene(tmp_path / "scene")
    with pytest.raises(InputError, match="overlaps input"):
        check_output(tmp_path / where, [scene])


def test_input_file_overlap_through_symlinked_parent(tmp_path):
    scene = _scene(tmp_path / "scene")
    (tmp_path / "link").symlink_to(scene)
    with pytest.raises(InputError, match="overlaps input"):
        check_output(tmp_path / "link" / "gt", [scene])
    with pytest.raises(InputError, match="overlaps input"):
        check_output(tmp_path / "x.png", [tmp_path / "x.png"], kind="file")


def test_subfolder_symlink_into_the_input_is_refused(tmp_path):
    scene = _scene(tmp_path / "scene")
    out = tmp_path / "out"
    out.mkdir()
    (out / "left").symlink_to(scene / "left")
    with pytest.raises(InputError, match=r"through .*scene/left.* overlaps input"):
        check_output(out, [scene], subfolders=["left", "right"], command="deblur")


def test_dangling_symlink_is_an_input_error(tmp_path):
    (tmp_path / "out").symlink_to(tmp_path / "missing")
    with pytest.raises(InputError, match="does not exist"):
        check_output(tmp_path / "out")
    with pytest.raises(InputError, match="does not exist"):
        check_output(tmp_path / "out" / "sub")


def test_symlink_loop_is_an_input_error(tmp_path):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    with pytest.raises(InputError):
        check_output(tmp_path / "a")


def test_another_scene_is_refused_unless_our_own(tmp_path):
    other = _scene(tmp_path / "other")
    with pytest.raises(InputError, match="another scene"):
        check_output(other, [tmp_path / "input"], command="deblur")
    mark_output(other, "synth")
    assert is_own_output(other, "synth") and not is_own_output(other, "deblur")
    with pytest.raises(InputError, match="another scene"):
        check_output(other, command="deblur")
    assert check_output(other, command="synth") == other.resolve()
    (other / RUN_LOG).write_text("")
    assert check_output(other, command="deblur") == other.resolve()
    assert json.loads((other / MARKER).read_text()) == {"command": "synth"}


def test_subfolder_symlink_into_another_scene_is_refused(tmp_path):
    other = _scene(tmp_path / "other")
    out = tmp_path / "out"
    out.mkdir()
    (out / "left").symlink_to(other / "left")
    with pytest.raises(InputError, match="another scene"):
        check_output(out, subfolders=["left"], command="deblur")


def test_output_that_is_a_file_or_folder_of_the_wrong_kind(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        check_output(tmp_path / "f")
    with pytest.raises(InputError, match="not a folder"):
        check_output(tmp_path / "f" / "sub")
    with pytest.raises(InputError, match="is a folder"):
        check_output(tmp_path, kind="file")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_unwritable_folder_is_an_input_error(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        with pytest.raises(InputError, match="permission denied"):
            check_output(folder / "out")
    finally:
        folder.chmod(0o700)


def test_immutable_folder_is_an_input_error(tmp_path):
    import shutil
    import subprocess

    folder = tmp_path / "immutable"
    folder.mkdir()
    chattr = shutil.which("chattr")
    if chattr is None or subprocess.run([chattr, "+i", str(folder)]).returncode != 0:
        pytest.skip("chattr +i is not available here")
    try:
        with pytest.raises(InputError, match=r"cannot write to .*immutable"):
            check_output(folder / "out")
        with pytest.raises(InputError, match=r"cannot write to .*immutable"):
            check_output(folder)
    finally:
        subprocess.run([chattr, "-i", str(folder)], check=True)
    assert os.listdir(folder) == []


def test_writing_errors_become_input_errors(tmp_path):
    with pytest.raises(InputError, match="cannot write"):
        with writing_errors(tmp_path):
            raise PermissionError(13, "Permission denied", str(tmp_path / "x"))
    with pytest.raises(OSError, match="other"):
        with writing_errors(tmp_path):
            raise OSError(5, "other")
    (tmp_path / "file").write_text("")
    with pytest.raises(InputError, match="not a folder"):
        make_folder(tmp_path / "file")


def test_atomic_write_text_leaves_no_temporary(tmp_path):
    atomic_write_text(tmp_path / "a" / "b.txt", "hello")
    assert (tmp_path / "a" / "b.txt").read_text() == "hello"
    assert os.listdir(tmp_path / "a") == ["b.txt"]


def test_output_lock_refuses_a_second_holder(tmp_path):
    import subprocess
    import sys

    code = (
        "import sys\nfrom stereodeblur.io.outputs import OutputLock\n"
        "from stereodeblur.errors import InputError\n"
        "try:\n    OutputLock(sys.argv[1]).__enter__()\nexcept InputError as e:\n"
        "    print(e); sys.exit(2)\n"
    )
    with OutputLock(tmp_path):
        other = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True
        )
        assert other.returncode == 2 and "in use by another run" in other.stdout
    other = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True)
    assert other.returncode == 0


def test_a_waiting_output_lock_is_granted_when_the_holder_releases(tmp_path):
    import subprocess
    import sys
    import time

    code = (
        "import sys, time\nfrom stereodeblur.io.outputs import OutputLock\n"
        "with OutputLock(sys.argv[1], name='.x.lock', wait=True):\n    print(time.time())\n"
    )
    with OutputLock(tmp_path, name=".x.lock"):
        other = subprocess.Popen(
            [sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True
        )
        time.sleep(2.0)  # the other process starts and waits meanwhile
        assert other.poll() is None
        released = time.time()
    out, _ = other.communicate(timeout=60)
    assert other.returncode == 0 and float(out) >= released
    with OutputLock(tmp_path):  # another name is another lock
        pass


def test_a_folder_inside_another_scene_is_refused_unless_our_own(tmp_path):
    other = _scene(tmp_path / "other")
    for where in (other / "gt", other / "gt" / "deep", other / "left" / "new"):
        with pytest.raises(InputError, match="another scene"):
            check_output(where, command="sceneflow")
    mark_output(other, "deblur")
    assert check_output(other / "gt", command="deblur") == (other / "gt").resolve()


def test_files_written_in_place_may_not_be_symlinks(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / RUN_LOG).symlink_to(tmp_path / "elsewhere.jsonl")
    assert check_output(out) == out.resolve()
    with pytest.raises(InputError, match=r"run-log.jsonl is a symlink .*elsewhere.jsonl"):
        check_output(out, in_place=[RUN_LOG, ".lock"])
    with pytest.raises(InputError, match="is a symlink"):
        open_in_place(out / RUN_LOG, os.O_WRONLY | os.O_APPEND)
    (out / ".lock").symlink_to(tmp_path / "target.lock")
    with pytest.raises(InputError, match="is a symlink"), OutputLock(out):
        pass
    assert not (tmp_path / "elsewhere.jsonl").exists() and not (tmp_path / "target.lock").exists()
