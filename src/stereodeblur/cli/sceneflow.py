"""``stereodeblur sceneflow``: estimate and write the scene flow of frames of a clip."""

from __future__ import annotations

import argparse

from ..errors import InputError
from .base import add_quiet
from .printer import print_compile_notice, print_warnings, progress_printer
from .settings_options import add_settings_options, settings_from_arguments
from .sources import (
    add_frames_option,
    add_source_argument,
    add_source_options,
    input_paths,
    open_source,
    select_frames,
    source_spec,
)

_VIEWS = ("left", "right")
# What the command writes under OUT (the layout of a scene's gt/ folder, a folder per
# reference view): each is checked, so a symlinked ``OUT/disparity/left`` is caught too.
SUBFOLDERS = (
    *(f"{kind}/{view}" for kind in ("disparity", "flow", "occlusion") for view in _VIEWS),
    "sceneflow",
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sceneflow",
        help="estimate the piecewise-rigid scene flow of frames",
        description="Estimate planes, rigid motions and occlusion of the left view of each "
        "frame (towards the next frame; the last frame towards the previous one) and write "
        "them in the layout of a scene's gt/, one file of each kind per frame, named as the source "
        "names the frame. Reads every source 'deblur' reads.",
    )
    add_source_argument(p)
    p.add_argument("-o", "--output", required=True, help="output folder")
    add_frames_option(p, "whose scene flow is estimated")
    p.add_argument(
        "--debug-dir",
        metavar="DIR",
        help="also write captioned pictures of the segments, disparity, flow and occlusion of "
        "each frame into DIR/NAME/, NAME the frame's (default: none)",
    )
    add_quiet(p)
    add_source_options(p, require_exposure=False)
    add_settings_options(p, ("num_segments",), title="scene flow")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import warnings
    from pathlib import Path

    from .._kernel_cache import SCENEFLOW_MODULES
    from ..io.outputs import check_output
    from ..pipeline import neighbour_of
    from ..sceneflow.estimate import SceneFlowWarning, estimate_scene_flow
    from ..sceneflow.storage import write_sceneflow_outputs

    settings = settings_from_arguments(args)
    spec = source_spec(args, require_exposure=False)
    source = open_source(spec)
    if source.num_frames < 2:
        raise InputError(f"{source.root}: the scene flow needs two frames, the clip has one")
    frames = select_frames(args.frames, source)
    protect = input_paths(spec)
    check_output(args.output, protect, subfolders=SUBFOLDERS, command="sceneflow")
    if args.debug_dir is not None:
        check_output(args.debug_dir, protect, command="sceneflow")
    progress = progress_printer(args.quiet)
    for count, index in enumerate(frames):
        neighbour = neighbour_of(index, source.num_frames)
        images = [source.read_frame(v, i) for i in (index, neighbour) for v in ("left", "right")]
        if count == 0:  # the first frames read: the estimate is about to compile
            print_compile_notice(args.quiet, SCENEFLOW_MODULES)
        name = source.numbering.name(index)
        debug = None if args.debug_dir is None else Path(args.debug_dir) / name
        with warnings.catch_warnings():  # printed below as one line each
            warnings.simplefilter("ignore", SceneFlowWarning)
            estimate = estimate_scene_flow(
                *images,
                source.info.camera,
                num_segments=settings.num_segments,
                exposure=source.info.exposure,
                progress=progress,
                debug_dir=debug,
            )
        number, next_number = (source.numbering.number(i) for i in (index, neighbour))
        print_warnings(f"frame {number}: {message}" for message in estimate.warnings)
        written = write_sceneflow_outputs(args.output, estimate.sceneflow, index, name=name)
        print(f"scene flow of frame {number} -> {next_number} written to {args.output}")
        for path in written.values():
            print(f"  {path}")
    return 0
