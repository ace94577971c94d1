"""``stereodeblur deblur``: deblur frames of a clip and write them as a scene."""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import replace

from ..errors import FrameWarning, InputError, StorageError
from ..settings import DASK_CONNECT_TIMEOUT
from .base import EXIT_FAILED, EXIT_USAGE, add_quiet, integer
from .printer import (
    print_compile_notice,
    print_warnings,
    progress_printer,
    with_compile_notice,
)
from .settings_options import add_settings_options, settings_from_arguments
from .sources import (
    AUTO,
    add_frames_option,
    add_source_argument,
    add_source_options,
    input_paths,
    open_source,
    select_frames,
    source_spec,
)

VIEWS = {"left": ("left",), "right": ("right",), "both": ("left", "right")}


def add_parser(sub) -> None:
    p = sub.add_parser(
        "deblur",
        help="deblur frames of a scene",
        description="Deblur frames of a scene folder (stereo-video/1 format), a KITTI folder "
        "or a video pair and write them as a scene.",
    )
    add_source_argument(p)
    p.add_argument("-o", "--output", required=True, help="output scene folder")
    add_frames_option(p, "to deblur")
    p.add_argument(
        "--views",
        choices=list(VIEWS),
        default="both",
        help="views to deblur and write (default: %(default)s)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="deblur again the frames the output already holds, and write into a folder that "
        "holds other files or an earlier 'deblur' output of another input, other settings or "
        "another camera; never into an input nor into another scene (camera.json and frames "
        "not written by 'deblur') (default: off: finished frames are skipped and such "
        "folders refused)",
    )
    add_quiet(p)
    p.add_argument(
        "--sceneflow",
        metavar="FILE",
        help="reuse a scene flow saved by 'stereodeblur sceneflow' (OUT/sceneflow/NNNNNN.npz) "
        "for the one frame given with --frames (default: none: the scene flow is estimated)",
    )
    p.add_argument(
        "--point-cloud",
        action="store_true",
        help="also write a coloured PLY per frame (OUT/pointcloud/VIEW/NNNNNN.ply) (default: off)",
    )
    r = p.add_argument_group("running")
    r.add_argument(
        "--workers",
        type=integer(1, 1024),
        help="local worker processes (default: one per core, as memory allows; 1: in process)",
    )
    r.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a Dask distributed scheduler, tcp://HOST:PORT (needs stereodeblur[dask]); "
        "input and output paths must be shared with its workers; an address that does not answer "
        f"as a scheduler within {DASK_CONNECT_TIMEOUT:g} s is refused (default: none: run on this "
        "machine)",
    )
    add_source_options(p)
    add_settings_options(p)
    p.set_defaults(func=run)


def views_of(args: argparse.Namespace) -> tuple[str, ...]:
    """The views ``--views`` selects."""
    return VIEWS[args.views]


def run(args: argparse.Namespace) -> int:
    from ..io.outputs import check_output

    settings = settings_from_arguments(args)
    spec = source_spec(args)
    try:
        source = open_source(spec)
    except InputError as err:  # a source that states no exposure: estimate it
        if err.parameter != "exposure" or args.exposure is not None:
            raise
        spec = replace(spec, require_exposure=False)
        source = open_source(spec)
        args.exposure = AUTO
    if args.exposure == AUTO:
        settings = replace(settings, exposure="auto")
    written = [*views_of(args), *(["pointcloud"] if args.point_cloud else [])]
    check_output(args.output, input_paths(spec), subfolders=written, command="deblur")
    frames = None if args.frames is None else select_frames(args.frames, source)
    views = views_of(args)
    if args.sceneflow:
        return _deblur_with_saved_sceneflow(args, settings, spec, source, frames, views)
    return _deblur_clip(args, settings, spec, frames, views, source)


def _kernel_modules(settings) -> tuple[str, ...]:
    """The modules whose kernels a run with ``settings`` compiles first."""
    from .._kernel_cache import DEBLUR_MODULES, SCENEFLOW_MODULES

    estimated = settings.motion_source == "sceneflow"
    return DEBLUR_MODULES + (SCENEFLOW_MODULES if estimated else ())


def _deblur_clip(args, settings, spec, frames, views, source) -> int:
    """Run :func:`~stereodeblur.clip.deblur_clip`; print its warnings ``source`` has not shown
    yet; frames are named in the source's numbers."""
    from ..clip import deblur_clip

    try:
        report = deblur_clip(
            spec,
            args.output,
            frames=None if frames is None else list(frames),
            views=list(views),
            settings=settings,
            overwrite=args.overwrite,
            point_cloud=args.point_cloud,
            workers=args.workers,
            scheduler=args.scheduler,
            progress=with_compile_notice(
                progress_printer(args.quiet), args.quiet, _kernel_modules(settings)
            )
            or False,
            command=["stereodeblur", *args.argv],
        )
    except StorageError as err:
        print(
            f"stereodeblur: error: {err}; the run stopped, finished frames are kept: "
            "make room and run the same command again to resume",
            file=sys.stderr,
        )
        return EXIT_FAILED
    print_warnings(w for w in report.warnings if w not in source.warnings)
    print_warnings(alert for record in report.records for alert in record.alerts)
    failed = report.failed
    if failed:
        first = failed[0]
        log = f"; see {report.log}" if report.log is not None and report.log.is_file() else ""
        print(
            f"stereodeblur: error: {len(failed)} of {len(report.records)} frame(s) failed "
            f"(first: frame {source.numbering.number(first.index)} {first.view}: {first.error})"
            f"{log}",
            file=sys.stderr,
        )
        return EXIT_USAGE if all(r.input_error for r in failed) else EXIT_FAILED
    skipped = f", {len(report.skipped)} already done" if report.skipped else ""
    print(f"wrote {report.done} frame(s) to {report.output}{skipped}")
    return 0


def _deblur_with_saved_sceneflow(args, settings, spec, source, frames, views) -> int:
    """``deblur --sceneflow FILE``: one frame, its motion read from ``stereodeblur sceneflow``."""
    from ..io.outputs import check_output, mark_output
    from ..io.scene import SceneWriter
    from ..pipeline import deblur_stereo_frame
    from ..sceneflow.storage import load_sceneflow

    if settings.motion_source != "sceneflow" or frames is None or len(frames) != 1:
        raise InputError(
            "--sceneflow FILE needs --frames with the one frame the file describes "
            "and --motion-source sceneflow"
        )
    index = frames[0]
    try:
        sceneflow = load_sceneflow(args.sceneflow)
    except (InputError, FileNotFoundError) as err:
        raise InputError(f"--sceneflow: {err}") from None
    if sceneflow.shape != tuple(source.shape):
        raise InputError(
            f"{args.sceneflow}: scene flow of size {sceneflow.shape}, "
            f"frames are {tuple(source.shape)}"
        )
    check_output(args.output, [args.sceneflow], command="deblur")
    progress = progress_printer(args.quiet)
    print_compile_notice(args.quiet, _kernel_modules(settings))
    writer = SceneWriter(
        args.output,
        source.info,
        overwrite=args.overwrite,
        protect=[source.root],
        numbering=source.numbering,
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FrameWarning)
        stereo = deblur_stereo_frame(
            source, index, views=views, settings=settings, sceneflow=sceneflow, progress=progress
        )
    for w in caught:  # the libraries' as before
        if w.category is not FrameWarning:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    print_warnings(str(w.message) for w in caught if w.category is FrameWarning)
    for view in views:
        writer.write_frame(view, index, stereo.frames[view].image)
    mark_output(writer.root, "deblur")
    print(f"wrote {len(views)} frame(s) to {writer.root}")
    return 0
