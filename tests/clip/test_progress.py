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
