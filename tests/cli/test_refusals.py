"""Inputs never written, bad values and absurd motions refused before anything runs.

Every case: exit 2, one line on stderr naming the file or value and what is accepted, no
traceback, no input byte changed (checksums), nothing written.
"""

import numpy as np
import pytest

from stereodeblur.io.formats import write_flo, write_pfm
from tests.cli.refusals import refused
from tests.conftest import write_tiny_scene


@pytest.mark.parametrize("inside", ["gt", "sf", "left"])
def test_sceneflow_output_inside_the_scene_is_refused(tiny_scene, capsys, inside):
    out = tiny_scene / inside
    existed = out.exists()
    line = refused(
        capsys,
        ["sceneflow", tiny_scene, "--frames", "1", "-o", out, "-q"],
        inputs=[tiny_scene],
        outputs=[] if existed else [out],
        fragments=[str(out)],
    )
    assert "input" in line


def test_sceneflow_output_through_a_symlink_into_the_scene_is_refused(tiny_scene, tmp_path, capsys):
    link = tmp_path / "link"
    link.symlink_to(tiny_scene / "gt")
    argv = ["sceneflow", tiny_scene, "--frames", "1", "-o", link, "-q"]
    refused(capsys, argv, inputs=[tiny_scene], fragments=["link", "input"])


def test_sceneflow_frame_out_of_range_names_the_option_and_the_range(tiny_scene, tmp_path, capsys):
    out = tmp_path / "sf"
    argv = ["sceneflow", tiny_scene, "--frames", "99", "-o", out]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=["--frames '99'", "0..2"])


@pytest.mark.parametrize("kind", ["camera.json", "junk.npz", "text.npz"])
def test_saved_sceneflow_that_is_no_sceneflow_file(tiny_scene, tmp_path, capsys, kind):
    if kind == "camera.json":
        bad = tiny_scene / "camera.json"
    elif kind == "junk.npz":
        bad = tmp_path / kind
        bad.write_bytes(np.random.default_rng(0).bytes(300))
    else:
        bad = tmp_path / kind
        np.savez(bad, something=np.zeros(3))
    out = tmp_path / "out"
    argv = ["deblur", tiny_scene, "-o", out, "--frames", "1", "--sceneflow", bad]
    line = refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=[bad.name])
    assert "unsafe" not in line and "pickle" not in line


def _scene_with_gt(tmp_path, *, disparity=None, flow=None):
    scene = write_tiny_scene(tmp_path / "scene")
    if disparity is not None:
        write_pfm(scene / "gt" / "disparity" / "left" / "000001.pfm", disparity)
    if flow is not None:
        write_flo(scene / "gt" / "flow" / "left" / "000001.flo", flow)
    return scene


SHAPE = (32, 40)


@pytest.mark.parametrize(
    "case, fragments",
    [
        ("flow 5000 px", ["000001.flo", "diagonal", "51 px"]),
        ("flow unknown", ["000001.flo", "no known flow"]),
        ("disparity 1e-30", ["000001.pfm", "[0.001, 40] px"]),
        ("disparity beyond the width", ["000001.pfm", "[0.001, 40] px"]),
        ("disparity NaN", ["000001.pfm", "no known disparity"]),
        ("disparity negative", ["000001.pfm", "no known disparity"]),
    ],
)
def test_absurd_ground_truth_motion_is_refused(tmp_path, capsys, case, fragments):
    h, w = SHAPE
    disparity = flow = None
    if case == "flow 5000 px":
        flow = np.full((h, w, 2), [5000.0, 0.0], np.float32)
    elif case == "flow unknown":
        flow = np.full((h, w, 2), 1e10, np.float32)
    elif case == "disparity 1e-30":
        disparity = np.full((h, w), 1e-30, np.float32)
    elif case == "disparity beyond the width":
        disparity = np.full((h, w), 2.0, np.float32)
        disparity[3, 4] = 5000.0
    elif case == "disparity NaN":
        disparity = np.full((h, w), np.nan, np.float32)
    else:
        disparity = np.full((h, w), -3.0, np.float32)
    scene = _scene_with_gt(tmp_path, disparity=disparity, flow=flow)
    out = tmp_path / "out"
    argv = ["deblur", scene, "-o", out, "--frames", "1", "--motion-source", "gt"]
    refused(capsys, argv, inputs=[scene], outputs=[out], fragments=fragments)


def test_deblur_output_into_another_scene_is_refused(tmp_path, capsys):
    scene = write_tiny_scene(tmp_path / "a")
    other = write_tiny_scene(tmp_path / "b", seed=1)
    argv = ["deblur", scene, "-o", other, "--frames", "1", "--motion-source", "gt", "-q"]
    refused(capsys, argv, inputs=[scene, other], fragments=[str(other), "another scene"])


@pytest.mark.parametrize("command", ["synth planar", "synth objects", "demo"])
def test_writing_commands_refuse_a_scene_folder(tiny_scene, capsys, command):
    argv = command.split() + (["-o", tiny_scene] if command == "demo" else [tiny_scene])
    refused(capsys, [*argv, "--size", "32x24"], inputs=[tiny_scene], fragments=["another scene"])


def test_synth_average_into_its_input_is_refused(tiny_scene, capsys):
    argv = ["synth", "average", tiny_scene, tiny_scene / "avg", "--window", "3"]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[tiny_scene / "avg"], fragments=["input"])


def test_render_view_onto_its_cloud_is_refused(tmp_path, capsys):
    cloud = tmp_path / "cloud.ply"
    cloud.write_bytes(b"ply\nformat binary_little_endian 1.0\nend_header\n")
    argv = ["render-view", cloud, "-o", cloud]
    refused(capsys, argv, inputs=[tmp_path], fragments=["cloud.ply", "input"])


@pytest.mark.parametrize("command", ["planar", "sceneflow", "paper"])
def test_bench_work_folder_that_is_a_scene_is_refused(tiny_scene, capsys, command):
    argv = ["bench", command, "--work", tiny_scene]
    refused(capsys, argv, inputs=[tiny_scene], fragments=["another scene"])


def test_deblur_output_whose_left_folder_links_into_the_input_is_refused(tmp_path, capsys):
    scene = write_tiny_scene(tmp_path / "scene")
    out = tmp_path / "out"
    out.mkdir()
    (out / "left").symlink_to(scene / "left")
    argv = ["deblur", scene, "-o", out, "--frames", "1", "--motion-source", "gt", "--overwrite"]
    refused(capsys, [*argv, "-q"], inputs=[scene], fragments=["out", "input"])
    assert sorted(p.name for p in out.iterdir()) == ["left"]


def test_output_through_a_dangling_symlink_is_refused(tiny_scene, tmp_path, capsys):
    out = tmp_path / "out"
    out.symlink_to(tmp_path / "nowhere")
    argv = ["sceneflow", tiny_scene, "--frames", "1", "-o", out]
    refused(capsys, argv, inputs=[tiny_scene], fragments=["out", "does not exist"])
    assert not (tmp_path / "nowhere").exists()


@pytest.mark.parametrize("options", [["--motion-source", "gt"], []])
def test_saved_sceneflow_needs_one_frame_and_the_sceneflow_source(tiny_scene, tmp_path, capsys,
                                                                  options):  # fmt: skip
    saved = tmp_path / "000001.npz"
    np.savez(saved, labels=np.zeros((2, 2)))
    out = tmp_path / "out"
    argv = ["deblur", tiny_scene, "-o", out, "--sceneflow", saved, *options]
    if options:
        argv += ["--frames", "1"]
    refused(capsys, argv, inputs=[tiny_scene], outputs=[out], fragments=["--sceneflow", "--frames"])


@pytest.mark.parametrize(
    "command",
    [
        ["synth", "planar", "{out}"],
        ["synth", "objects", "{out}"],
        ["bench", "planar", "--work", "{out}"],
        ["bench", "sceneflow", "--work", "{out}", "--no-motorcycle"],
        ["bench", "paper", "--work", "{out}"],
    ],
    ids=lambda c: " ".join(c[:2]),
)
def test_unknown_scene_names_are_refused_before_rendering(tmp_path, capsys, command):
    out = tmp_path / "out"
    argv = [str(out) if a == "{out}" else a for a in command]
    refused(
        capsys, [*argv, "--scenes", "nosuch"], outputs=[out], fragments=["'nosuch'", "--scenes"]
    )


@pytest.mark.parametrize("command", ["planar", "sceneflow", "paper"])
def test_bench_into_a_work_folder_another_run_holds_is_refused(tmp_path, capsys, command):
    """Two benches into one work folder: the second would delete the first one's
    half-rendered scenes; it is refused before it touches anything."""
    from stereodeblur.io.outputs import OutputLock

    work = tmp_path / "work"
    work.mkdir()
    with OutputLock(work):
        argv = ["bench", command, "--work", work]
        refused(capsys, argv, fragments=["in use by another run", work])
    assert [p.name for p in work.iterdir()] == [".lock"]
