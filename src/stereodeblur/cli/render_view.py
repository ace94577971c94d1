"""``stereodeblur render-view``: a point cloud seen from a shifted camera, as a PNG."""

from __future__ import annotations

import argparse
import math
import re

from ..errors import InputError
from .base import positive_number, size


def vector3(text: str) -> tuple[float, float, float]:
    """Option type: three finite numbers like ``0.1,0,0``."""
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected three numbers like 0.1,0,0, got {text!r}")
    return values


def add_parser(sub) -> None:
    p = sub.add_parser(
        "render-view",
        help="render a point cloud (--point-cloud output) from a shifted viewpoint",
        description="Render a PLY point cloud written by 'deblur --point-cloud' from a camera "
        "moved by --shift and turned by --rotate; '--colors both' puts deblurred and blurred "
        "colours side by side.",
    )
    p.add_argument("cloud", help="PLY file written by 'deblur --point-cloud'")
    p.add_argument("-o", "--output", required=True, help="output PNG")
    p.add_argument(
        "--shift",
        type=vector3,
        default="0,0,0",
        metavar="X,Y,Z",
        help="camera centre in scene units (default: %(default)s: the frame's camera)",
    )
    p.add_argument(
        "--rotate",
        type=vector3,
        default="0,0,0",
        metavar="X,Y,Z",
        help="camera rotation vector in degrees (default: %(default)s: no rotation)",
    )
    p.add_argument(
        "--colors",
        choices=["deblurred", "blurred", "both"],
        help="which colours (default: both side by side when the cloud has blurred ones, "
        "else deblurred)",
    )
    p.add_argument("--size", type=size, help="WIDTHxHEIGHT of the picture (default: the frame's)")
    p.add_argument(
        "--focal", type=positive_number, help="focal length in pixels (default: the frame's)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..io.formats import write_png
    from ..io.outputs import check_output
    from ..pointcloud import read_ply, render_view

    check_output(args.output, [args.cloud], kind="file", command="render-view")
    cloud = read_ply(args.cloud)
    K = None
    if args.focal is not None:
        if args.size is None and cloud.size is None:
            raise InputError("--focal needs --size: the point cloud states no image size")
        w, h = args.size or cloud.size
        K = np.array([[args.focal, 0, (w - 1) / 2], [0, args.focal, (h - 1) / 2], [0, 0, 1]])
    rendered = render_view(
        cloud,
        rotation=np.deg2rad(np.array(args.rotate)),
        translation=np.array(args.shift),
        K=K,
        size=args.size,
        colors=args.colors or ("deblurred" if cloud.blurred_colors is None else "both"),
    )
    write_png(args.output, rendered.image, bit_depth=8)
    print(
        f"wrote {args.output}: {len(cloud)} points, {100 * rendered.mask.mean():.1f} % of "
        "pixels covered"
    )
    return 0
