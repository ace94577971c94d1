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

import importlib

# Where each public name lives. They are loaded on first use, so that importing one module
# of the package (a pool worker unpickling its start function) loads only that module and
# a worker watches its parent before numba and the pipeline are imported.
_HOMES = {
    "LOG_NAME": ("..io.outputs", "RUN_LOG"),
    "ClipJob": (".job", "ClipJob"),
    "ClipReport": (".job", "ClipReport"),
    "FrameRecord": (".job", "FrameRecord"),
    "ProgressBar": (".progress", "ProgressBar"),
    "RunLogContents": (".runlog", "RunLogContents"),
    "Terminated": (".run", "Terminated"),
    "deblur_clip": (".run", "deblur_clip"),
    "default_workers": (".executors", "default_workers"),
    "parse_frames": (".frames", "parse_frames"),
    "parse_run_log": (".runlog", "parse_run_log"),
    "process_task": (".worker", "process_task"),
    "read_run_log": (".runlog", "read_run_log"),
}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _HOMES[name]
    value = getattr(importlib.import_module(module, __name__), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_HOMES])


__all__ = list(_HOMES)
