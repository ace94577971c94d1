"""Damage a run leaves or suffers (a corrupt run log, a 0-byte or truncated result, a
half-written temporary file) is recovered from on resume: the output ends byte-identical to
an uninterrupted run."""

import json
import shutil

import numpy as np
import pytest

from stereodeblur.clip import parse_run_log, read_run_log
from stereodeblur.errors import InputError
from stereodeblur.io.formats import write_png
from tests.faults.helpers import FAST, run_cli, same_frames


def _copy(reference, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    return out


def _resume(tiny_scene, out, *extra):
    result = run_cli("deblur", tiny_scene, "-o", out, "--workers", "1", "-q", *FAST, *extra)
    assert result.code == 0, result.stderr
    return result


def test_corrupt_run_log_lines_are_skipped_and_noted(tiny_scene, reference, tmp_path):
    out = _copy(reference, tmp_path)
    log = out / "run-log.jsonl"
    log.write_bytes(log.read_bytes() + b'\xff\xfe\x00garbage\n[1, 2]\n{"event": "fra')
    (out / "left" / "000002.png").unlink()
    result = _resume(tiny_scene, out)
    assert "1 frame(s)" in result.stdout and "11 already done" in result.stdout
    same_frames(out, reference)
    contents = read_run_log(log)
    assert len(contents.problems) == 3, contents.problems
    start = contents.last_start()
    assert sum("skipped" in w for w in start["warnings"]) == 3
    assert contents.events[-1]["event"] == "end"  # the cut line did not swallow new events


@pytest.mark.parametrize("damage", ["empty", "truncated", "not a png", "other size"])
def test_damaged_results_are_deblurred_again(tiny_scene, reference, tmp_path, damage):
    out = _copy(reference, tmp_path)
    path = out / "right" / "000003.png"
    data = path.read_bytes()
    if damage == "empty":
        path.write_bytes(b"")
    elif damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "not a png":
        path.write_bytes(b"hello" * 100)
    else:  # a whole PNG of another size
        write_png(path, np.zeros((8, 8), np.float32))
    result = _resume(tiny_scene, out)
    assert "1 frame(s)" in result.stdout, result.stdout
    same_frames(out, reference)


def test_half_written_temporaries_are_removed(tiny_scene, reference, tmp_path):
    out = _copy(reference, tmp_path)
    (out / "left" / "000004.png").unlink()
    temporary = out / "left" / ".000004.png.0123456789ab.tmp"
    temporary.write_bytes(b"\x89PNG\r\n\x1a\n half")
    _resume(tiny_scene, out)
    assert not temporary.exists()
    same_frames(out, reference)
    start = read_run_log(out / "run-log.jsonl").last_start()
    assert any("half-written" in w for w in start["warnings"])


def test_run_log_that_is_a_folder_is_an_input_error(tiny_scene, reference, tmp_path):
    out = _copy(reference, tmp_path)
    (out / "run-log.jsonl").unlink()
    (out / "run-log.jsonl").mkdir()
    result = run_cli("deblur", tiny_scene, "-o", out, "-q", *FAST)
    lines = result.stderr.strip().splitlines()
    assert result.code == 2 and len(lines) == 1 and str(out) in lines[0], lines
    with pytest.raises(InputError, match="is not a file"):
        read_run_log(out / "run-log.jsonl")


def test_parse_run_log_examples():
    good = json.dumps({"event": "start", "frames": [1]}).encode()
    contents = parse_run_log(good + b"\n\n" + b"\xc3\x28\n" + b"7\n" + b'{"event": 3}\n')
    assert contents.events == ({"event": "start", "frames": [1]},)
    assert len(contents.problems) == 3
    with pytest.raises(InputError):
        parse_run_log("text")
