"""``stereodeblur demo``: render a small scene, deblur it, print the PSNRs."""

from __future__ import annotations

import argparse

from ..demo import DEMO_SIZE
from .base import add_quiet, add_size
from .printer import progress_printer

SUBFOLDERS = ("scene", "deblurred")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "demo",
        help="render a small scene, deblur it, write a side-by-side picture",
        description="Render a built-in blurred stereo scene, deblur it and write "
        "blurred | deblurred | sharp as a PNG; prints the PSNRs.",
    )
    p.add_argument(
        "-o",
        "--output",
        default="stereodeblur-demo",
        help="output folder, in the working folder by default (default: %(default)s)",
    )
    add_size(p, DEMO_SIZE)
    add_quiet(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..demo import run_demo
    from ..io.outputs import check_output

    check_output(args.output, [], subfolders=SUBFOLDERS, command="demo")
    result = run_demo(args.output, size=args.size, progress=progress_printer(args.quiet))
    width, height = result.size
    settings = result.settings
    gain = result.psnr_deblurred - result.psnr_blurred
    print(
        f"scene: {result.scene}, {width}x{height}, motion from {settings.motion_source}, "
        f"{settings.kernels} kernels"
    )
    print(f"PSNR blurred   {result.psnr_blurred:6.2f} dB")
    print(f"PSNR deblurred {result.psnr_deblurred:6.2f} dB  ({gain:+.2f} dB)")
    print(f"picture (blurred | deblurred | sharp): {result.picture}")
    return 0
