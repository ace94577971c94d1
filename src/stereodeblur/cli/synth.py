"""``stereodeblur synth planar|objects|average``: write synthetic benchmark scenes."""

from __future__ import annotations

import argparse

from ..errors import InputError
from .base import Parser, add_quiet, add_size, names
from .printer import progress_printer
from .sources import (
    SOURCE_HELP,
    add_source_options,
    input_paths,
    open_source,
    source_spec,
)

# The size of write_planar_set and write_object_set (tests/cli/test_help.py checks they agree).
SIZE = (640, 480)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "synth",
        help="render synthetic benchmark scenes",
        description="Render physically blurred benchmark scenes with ground truth.",
    )
    synth = p.add_subparsers(dest="kind", required=True, parser_class=Parser)
    q = synth.add_parser(
        "planar",
        help="textured planes under the paper's motions",
        description="Textured planes under the paper's 3D motions.",
    )
    q.add_argument("output", help="folder to write one scene per motion into")
    add_size(q, SIZE)
    q.add_argument("--scenes", type=names, help="comma-separated motion names (default: all)")
    add_quiet(q)
    q.set_defaults(func=run_planar)
    q = synth.add_parser(
        "objects",
        help="moving spheres, boxes, planes and a cylinder before a background",
        description="Several textured objects with independent rigid motions in front of a "
        "textured background (the paper's ray-traced scenes), each also with sensor noise "
        "(sigma = 0.01) as NAME_noisy.",
    )
    q.add_argument("output", help="folder to write one scene per name into")
    add_size(q, SIZE)
    q.add_argument("--scenes", type=names, help="comma-separated scene names (default: all)")
    q.add_argument(
        "--no-noisy",
        action="store_true",
        help="skip the NAME_noisy variants (default: off: they are written)",
    )
    add_quiet(q)
    q.set_defaults(func=run_objects)
    _add_average(synth)


def _add_average(synth) -> None:
    q = synth.add_parser(
        "average",
        help="blurred benchmark from sharp high-frame-rate footage",
        description="Average --window consecutive sharp frames of a fast stereo clip into each "
        "blurred frame of a new scene; the centre frame is stored as gt/sharp.",
    )
    q.add_argument("source", nargs="+", help=f"the sharp clip; {SOURCE_HELP} (with --calib)")
    q.add_argument("output", help="output scene folder")
    q.add_argument(
        "--window",
        type=int,
        metavar="K",
        required=True,
        help="source frames averaged per blurred frame, odd",
    )
    q.add_argument(
        "--stride",
        type=int,
        metavar="S",
        help="source frames between the starts of two blurred frames, at least K "
        "(default: K: windows side by side)",
    )
    q.add_argument(
        "--overwrite",
        action="store_true",
        help="write into a folder that holds other files or an earlier 'synth average' output "
        "of another camera; never into an input nor into another scene (camera.json and "
        "frames not written by 'synth average') (default: off: such folders are refused)",
    )
    add_quiet(q)
    add_source_options(q, require_exposure=False)
    q.set_defaults(func=run_average)


def _check_set_output(output: str, command: str) -> None:
    """A folder of scenes: never inside an input (none here) nor a scene folder itself."""
    from ..io.outputs import check_output

    check_output(output, [], command=command)


def run_planar(args: argparse.Namespace) -> int:
    from ..synth.planar import PLANAR_MOTIONS, write_planar_set

    unknown = [n for n in args.scenes or () if n not in PLANAR_MOTIONS]
    if unknown:
        raise InputError(
            f"--scenes: unknown planar scene {unknown[0]!r}, expected one of "
            f"{', '.join(PLANAR_MOTIONS)}"
        )
    _check_set_output(args.output, "synth planar")
    roots = write_planar_set(
        args.output, size=args.size, names=args.scenes, progress=progress_printer(args.quiet)
    )
    print(f"wrote {len(roots)} scene(s) to {args.output}")
    return 0


def run_objects(args: argparse.Namespace) -> int:
    from ..synth.objects import OBJECT_SCENES, write_object_set

    unknown = [n for n in args.scenes or () if n.removesuffix("_noisy") not in OBJECT_SCENES]
    if unknown:
        raise InputError(
            f"--scenes: unknown object scene {unknown[0]!r}, expected one of "
            f"{', '.join(OBJECT_SCENES)} (each also as NAME_noisy)"
        )
    _check_set_output(args.output, "synth objects")
    roots = write_object_set(
        args.output,
        size=args.size,
        names=args.scenes,
        noise_variants=not args.no_noisy,
        progress=progress_printer(args.quiet),
    )
    print(f"wrote {len(roots)} scene(s) to {args.output}")
    return 0


def run_average(args: argparse.Namespace) -> int:
    from ..io.outputs import check_output, mark_output
    from ..synth.average import average_clip

    spec = source_spec(args, require_exposure=False)
    source = open_source(spec)
    protect = input_paths(spec)
    check_output(args.output, protect, subfolders=("left", "right", "gt"), command="synth average")
    root = average_clip(
        source,
        args.output,
        window=args.window,
        stride=args.stride,
        overwrite=args.overwrite,
        protect=protect,
        progress=progress_printer(args.quiet),
    )
    mark_output(root, "synth average")
    print(f"wrote {root}")
    return 0
