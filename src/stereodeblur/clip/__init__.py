"""Deblur a whole clip: every frame of both views, resumable, in parallel or on a Dask cluster.

Each stereo frame is one task: its views are deblurred together, the motion computed once
(:func:`stereodeblur.pipeline.deblur_stereo_frame`); a resumed run deblurs only the views
not yet finished. Frame i uses frames i and i + 1; the last frame uses i - 1.

Output
------
``OUT`` is a scene (SCENE_FORMAT.md) with the source's ``camera.json`` (its colour encoding
too: results are written back in the input's); a task writes ``OUT/VIEW/NAME.png`` (16 bit,
``NAME`` the source's own frame name: ``NNNNNN``, KITTI's ``000005_10`` or ``0000000042``,
:mod:`stereodeblur.io.numbering`) through a temporary file and a rename, after
``OUT/pointcloud/VIEW/NAME.ply`` when point clouds are asked for, so a frame whose PNG
exists and is complete is finished. Re-running skips finished frames unless ``overwrite``; a
killed run loses at most the frames in flight. ``OUT/run-log.jsonl`` records every run
(:mod:`stereodeblur.clip.runlog`); ``OUT/.lock`` keeps a second run out while one runs.

Modules
-------
:mod:`~stereodeblur.clip.frames` (frame selections), :mod:`~stereodeblur.clip.job` (tasks and
what is finished), :mod:`~stereodeblur.clip.checks` (everything checked before the first
frame), :mod:`~stereodeblur.clip.worker` (one task), :mod:`~stereodeblur.clip.executors`
(serial, process pool, Dask), :mod:`~stereodeblur.clip.runlog`,
:mod:`~stereodeblur.clip.progress` and :mod:`~stereodeblur.clip.run` (a whole run).
"""

from ..io.outputs import RUN_LOG as LOG_NAME
from .executors import default_workers
from .frames import parse_frames
from .job import ClipJob, ClipReport, FrameRecord
from .progress import ProgressBar
from .run import Terminated, deblur_clip
from .runlog import RunLogContents, parse_run_log, read_run_log
from .worker import process_task

__all__ = [
    "LOG_NAME",
    "ClipJob",
    "ClipReport",
    "FrameRecord",
    "ProgressBar",
    "RunLogContents",
    "Terminated",
    "deblur_clip",
    "default_workers",
    "parse_frames",
    "parse_run_log",
    "process_task",
    "read_run_log",
]
