"""Every kind of bad input: one line naming the file or value, exit code 2, no output."""

import json
import os
import subprocess
import sys

from stereodeblur.cli import main
from tests.conftest import write_tiny_scene


def _run(capsys, *argv):
    code = main(list(argv))
    err = capsys.readouterr().err.strip().splitlines()
    return code, [line for line in err if not line.startswith("[")]


def _assert_one_line(code, err, *fragments, output=None):
    assert code == 2
    assert len(err) == 1, err
    assert err[0].startswith("stereodeblur: error: ")
    assert "Traceback" not in err[0]
    for f in fragments:
        assert f in err[0], (f, err[0])
    if output is not None:
        assert not output.exists(), "partial output left behind"


def test_missing_scene_folder(tmp_path, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tmp_path / "nope"), "-o", str(out))
    _assert_one_line(code, err, "nope", output=out)


def test_missing_camera_json(tiny_scene, tmp_path, capsys):
    (tiny_scene / "camera.json").unlink()
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, "camera.json", output=out)


def test_missing_frame_file(tiny_scene, tmp_path, capsys):
    (tiny_scene / "right" / "000002.png").unlink()
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, output=out)


def test_frames_of_different_sizes(tmp_path, capsys):
    scene = write_tiny_scene(tmp_path / "scene")
    other = write_tiny_scene(tmp_path / "other", size=(48, 32))
    os.replace(other / "left" / "000001.png", scene / "left" / "000001.png")
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(scene), "-o", str(out))
    _assert_one_line(code, err, "000001.png", output=out)


def test_malformed_camera_json(tiny_scene, tmp_path, capsys):
    (tiny_scene / "camera.json").write_text('{"format": "stereo-video/1", "K": [[1, 0]')
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, "camera.json", output=out)


def test_camera_json_with_wrong_k(tiny_scene, tmp_path, capsys):
    cam = json.loads((tiny_scene / "camera.json").read_text())
    cam["K"] = [[50, 0, 20], [0, 50, 16]]
    (tiny_scene / "camera.json").write_text(json.dumps(cam))
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, "camera.json", "K", output=out)


def test_exposure_longer_than_frame_interval(tiny_scene, tmp_path, capsys):
    cam = json.loads((tiny_scene / "camera.json").read_text())
    cam["exposure"] = 0.08
    (tiny_scene / "camera.json").write_text(json.dumps(cam))
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, "exposure", "0.08", output=out)


def test_unreadable_png(tiny_scene, tmp_path, capsys):
    (tiny_scene / "left" / "000001.png").write_bytes(b"this is not a png at all")
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out))
    _assert_one_line(code, err, "000001.png", output=out)


def test_single_frame(tmp_path, capsys):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=1)
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(scene), "-o", str(out))
    _assert_one_line(code, err, "two frames", output=out)


def test_bad_frame_list(tiny_scene, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = _run(capsys, "deblur", str(tiny_scene), "-o", str(out), "--frames", "7")
    _assert_one_line(code, err, "--frames", output=out)


def test_output_into_input_is_refused(tiny_scene, capsys):
    before = sorted(p.name for p in (tiny_scene / "left").iterdir())
    code, err = _run(
        capsys, "deblur", str(tiny_scene), "-o", str(tiny_scene), "--motion-source", "gt"
    )
    _assert_one_line(code, err, "input")
    assert sorted(p.name for p in (tiny_scene / "left").iterdir()) == before


def test_unknown_option_is_usage_error(capsys):
    assert main(["deblur", "--no-such-option"]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_no_traceback_in_a_real_process(tmp_path):
    scene = write_tiny_scene(tmp_path / "scene", num_frames=1)
    proc = subprocess.run(
        [sys.executable, "-m", "stereodeblur.cli", "deblur", str(scene), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
