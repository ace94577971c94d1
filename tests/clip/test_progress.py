"""The clip's progress: a bar on a stream, or Progress reports to a callable."""

import io

from stereodeblur.clip import FrameRecord, ProgressBar
from stereodeblur.clip.progress import make_progress


def test_progress_bar_and_reports():
    stream = io.StringIO()
    bar = make_progress(stream, 2, 0)
    assert isinstance(bar, ProgressBar)
    bar.update(FrameRecord(0, "left", "done", seconds=1.0))
    bar.update(FrameRecord(0, "right", "failed", error="bad"))
    text = stream.getvalue()
    assert "2/2 frames" in text and "ETA" in text and "FAILED (bad)" in text and "1 failed" in text
    reports = []
    progress = make_progress(reports.append, 2, 0)
    progress.update(FrameRecord(3, "left", "done"))
    assert [(p.stage, p.done, p.total) for p in reports] == [("frame 3 left done", 1, 2)]
    assert make_progress(False, 2, 0) is None and make_progress(True, 0, 5) is None


def test_frames_are_named_by_the_sources_numbers():
    from stereodeblur.io.numbering import FrameNumbering

    reports, stream = [], io.StringIO()
    kitti = FrameNumbering(first=10, digits=2, prefix="000000_")
    make_progress(reports.append, 1, 0, kitti).update(FrameRecord(1, "left", "done"))
    make_progress(stream, 1, 0, kitti).update(FrameRecord(1, "left", "done"))
    assert reports[0].stage == "frame 11 left done" and "frame 11 left done" in stream.getvalue()


def _stages_of_a_run(clip_scene, out, workers):
    from stereodeblur.clip import deblur_clip
    from stereodeblur.pipeline import DeblurSettings

    reports = []
    settings = DeblurSettings(motion_source="gt", num_irls=1, num_cg=2, num_samples=8)
    report = deblur_clip(
        clip_scene, out, frames=[2, 3], settings=settings, workers=workers,
        progress=reports.append,
    )  # fmt: skip
    assert report.done == 4
    return [p.stage for p in reports]


def test_the_stages_show_when_frames_run_in_worker_processes(clip_scene, tmp_path):
    """Two worker processes: each frame's stages (motion, operator, deconvolution) reach the
    caller's progress, as in a serial run, besides the frames finished."""
    stages = {w: _stages_of_a_run(clip_scene, tmp_path / f"out{w}", w) for w in (1, 2)}
    for found in stages.values():
        for frame in (2, 3):
            assert f"frame {frame}: motion (gt)" in found
            assert any(s.startswith(f"frame {frame} left: blur operator") for s in found)
            assert any(s.startswith(f"frame {frame} right: IRLS") for s in found), found
        assert {"frame 2 left done", "frame 3 right done"} <= set(found)
    assert set(stages[2]) == set(stages[1])
