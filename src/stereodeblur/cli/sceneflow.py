"""``stereodeblur sceneflow``: estimate and write the scene flow of one frame."""

from __future__ import annotations

import argparse

from ..errors import InputError
from .base import add_quiet, integer
from .printer import progress_printer
from .settings_options import SEGMENTS

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
        help="estimate the piecewise-rigid scene flow of a frame",
        description="Estimate planes, rigid motions and occlusion of a frame "
        "(towards the next frame) and write them in the layout of a scene's gt/.",
    )
    p.add_argument("scene", help="input scene folder")
    p.add_argument("--frame", type=integer(0), required=True, help="frame index")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument(
        "--segments",
        type=integer(*SEGMENTS),
        default=None,
        help="superpixels (default: 1200 at 640x480, scaled with area)",
    )
    p.add_argument("--debug-dir", help="write pictures of segments, disparity, flow, occlusion")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..io.outputs import check_output
    from ..io.scene import open_scene
    from ..pipeline import neighbour_of
    from ..sceneflow.estimate import estimate_scene_flow
    from ..sceneflow.storage import write_sceneflow_outputs

    scene = open_scene(args.scene)
    index = args.frame
    if not 0 <= index < scene.num_frames:
        raise InputError(f"--frame {index}: {scene.root} has frames 0..{scene.num_frames - 1}")
    check_output(args.output, [scene.root], subfolders=SUBFOLDERS, command="sceneflow")
    if args.debug_dir is not None:
        check_output(args.debug_dir, [scene.root], command="sceneflow")
    neighbour = neighbour_of(index, scene.num_frames)
    frames = [scene.read_frame(v, i) for i in (index, neighbour) for v in ("left", "right")]
    progress = progress_printer(args.quiet)
    estimate = estimate_scene_flow(
        *frames,
        scene.info.camera,
        num_segments=args.segments,
        exposure=scene.info.exposure,
        progress=progress,
        debug_dir=args.debug_dir,
    )
    written = write_sceneflow_outputs(args.output, estimate.sceneflow, index)
    print(f"scene flow of frame {index} -> {neighbour} written to {args.output}")
    for path in written.values():
        print(f"  {path}")
    return 0
