"""deblur_clip as a library: failures keep their log, a locked output is refused, the
libraries' messages stay off the terminal, SIGTERM stops a run like Ctrl-C."""

import os
import shutil
import signal
import warnings

import pytest

from stereodeblur.clip import Terminated, deblur_clip, read_run_log
from stereodeblur.clip.worker import captured_stderr
from stereodeblur.errors import InputError
from stereodeblur.io.outputs import OutputLock
from stereodeblur.io.sources import SourceSpec
from stereodeblur.pipeline import DeblurSettings
from tests.clip.clip_helpers import frame_files

SETTINGS = DeblurSettings(motion_source="gt", num_irls=1, num_cg=2, num_samples=8)


def _run(scene, out, **options):
    return deblur_clip(
        SourceSpec.from_arguments(scene), out, settings=SETTINGS, progress=False, **options
    )


def test_failed_frames_keep_the_log_they_point_to(clip_scene, tmp_path, monkeypatch):
    import stereodeblur.pipeline as pipeline

    def broken(*args, **kwargs):
        print("libfoo: noise on the standard error", file=__import__("sys").stderr)
        raise RuntimeError("solver exploded")

    monkeypatch.setattr(pipeline, "deblur_stereo_frame", broken)
    out = tmp_path / "out"
    report = _run(clip_scene, out, frames=[2, 3], workers=1)
    assert report.done == 0 and len(report.failed) == 4
    assert report.log is not None and report.log.is_file()
    frames = [e for e in read_run_log(report.log).events if e["event"] == "frame"]
    assert all("solver exploded" in e["error"] and "Traceback" in e["details"] for e in frames)
    assert "libfoo: noise on the standard error" in frames[0]["warnings"]


def test_a_locked_output_is_refused_and_kept(clip_scene, tmp_path):
    out = tmp_path / "out"
    assert _run(clip_scene, out, frames=[0], workers=1).done == 2
    before = {name: (out / name).read_bytes() for name in frame_files(out)}
    with OutputLock(out), pytest.raises(InputError, match="in use by another run"):
        _run(clip_scene, out, frames=[1], workers=1)
    assert {name: (out / name).read_bytes() for name in frame_files(out)} == before
    assert len(read_run_log(out / "run-log.jsonl").events) == 4  # start, 2 frames, end


def test_library_messages_are_captured_not_shown(capfd):
    lines = []
    with captured_stderr(lines):
        os.write(2, b"libpng warning: iCCP: known incorrect sRGB profile\n")
        print("[ WARN:0] OpenCV says something", file=__import__("sys").stderr)
    assert lines == [
        "libpng warning: iCCP: known incorrect sRGB profile",
        "[ WARN:0] OpenCV says something",
    ]
    assert capfd.readouterr().err == ""


def test_python_warnings_of_a_frame_go_to_the_log(clip_scene, tmp_path, monkeypatch):
    import stereodeblur.pipeline as pipeline

    original = pipeline.deblur_stereo_frame

    def warning(*args, **kwargs):
        warnings.warn("a library is unhappy", RuntimeWarning, stacklevel=1)
        return original(*args, **kwargs)

    monkeypatch.setattr(pipeline, "deblur_stereo_frame", warning)
    report = _run(clip_scene, tmp_path / "out", frames=[4], workers=1)
    assert report.done == 2
    assert all("a library is unhappy" in r.warnings for r in report.records)


def test_sigterm_stops_the_run_like_an_interrupt(clip_scene, tmp_path):
    out = tmp_path / "out"
    shutil.rmtree(out, ignore_errors=True)

    def terminate(record):
        os.kill(os.getpid(), signal.SIGTERM)

    previous = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated):
        _run(clip_scene, out, frames=[5, 6], workers=1, on_frame=terminate)
    assert signal.getsignal(signal.SIGTERM) == previous  # restored after the run
    events = read_run_log(out / "run-log.jsonl").events
    assert events[-1]["event"] == "interrupted" and events[-1]["reason"] == "SIGTERM"
    assert len(frame_files(out)) == 2  # the finished frame is kept


def test_a_run_refused_by_the_lock_removes_nothing_even_if_it_made_the_folder(
    clip_scene, tmp_path, monkeypatch
):
    import stereodeblur.clip.run as run

    out = tmp_path / "out"
    out.mkdir()
    (out / "camera.json").write_text("{}")  # what the other run has written so far
    monkeypatch.setattr(run, "_make_output", lambda output: True)  # "this run made it"
    with OutputLock(out), pytest.raises(InputError, match="in use"):
        _run(clip_scene, out, frames=[0], workers=1)
    assert sorted(p.name for p in out.iterdir()) == [".lock", "camera.json"]
