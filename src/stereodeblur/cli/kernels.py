"""``stereodeblur kernels``: homography- vs flow-induced blur kernels (paper Fig. 3)."""

from __future__ import annotations

import argparse

from ..evaluation import kernels_figure
from .base import add_size


def add_parser(sub) -> None:
    p = sub.add_parser(
        "kernels",
        help="picture of homography- vs flow-induced blur kernels (paper Fig. 3)",
        description="Blur kernels of a yawing plane at a grid of pixels: from 3D homographies, "
        "from the 2D flow (displacement model), and their difference, side by side as a PNG.",
    )
    p.add_argument("-o", "--output", required=True, help="output PNG")
    add_size(p, kernels_figure.SIZE)
    p.add_argument(
        "--yaw",
        type=float,
        default=kernels_figure.YAW,
        help="radians per frame interval (default: %(default)s)",
    )
    p.add_argument(
        "--depth",
        type=float,
        default=kernels_figure.DEPTH,
        help="plane distance in metres (default: %(default)s)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..evaluation.kernels_figure import write_kernel_figure
    from ..io.outputs import check_output

    check_output(args.output, [], kind="file", command="kernels")
    kernels = write_kernel_figure(args.output, size=args.size, yaw=args.yaw, depth=args.depth)
    norms = kernels.difference_norm()
    print(f"wrote {args.output}: {norms.shape[1]} x {norms.shape[0]} kernels, yaw {args.yaw} rad")
    print("L1 difference of homography and flow kernels (0 = equal, 2 = disjoint):")
    for line, pixels in zip(norms, kernels.pixels, strict=True):
        print(
            "  "
            + "  ".join(f"({x:3d},{y:3d}) {v:.3f}" for (x, y), v in zip(pixels, line, strict=True))
        )
    return 0
