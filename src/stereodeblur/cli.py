"""Command-line interface: parse, configure, call the pipeline, write.

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from .errors import InputError

EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit code 2, as argparse does, with our prefix
        self.exit(EXIT_USAGE, f"stereodeblur: error: {message}\n")


class Progress:
    """Progress lines on stderr with elapsed time; silent when ``quiet``."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.start = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(
                f"[{time.perf_counter() - self.start:7.1f} s] {message}",
                file=sys.stderr,
                flush=True,
            )


def parse_size(text: str) -> tuple[int, int]:
    """``'640x480'`` -> ``(640, 480)`` (width, height)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"size must look like WIDTHxHEIGHT (e.g. 640x480), got {text!r}") from None
    if w < 16 or h < 16:
        raise InputError(f"size must be at least 16x16, got {text!r}")
    return w, h


def parse_frames(text: str | None, num_frames: int) -> list[int]:
    """Frame list: ``'1,3,5'``, ``'2:10'`` (end exclusive), ``'4:'`` or a mix; None: all."""
    if text is None:
        return list(range(num_frames))
    frames: list[int] = []
    for part in text.split(","):
        part = part.strip()
        try:
            if ":" in part:
                a, b = part.split(":", 1)
                frames.extend(range(int(a) if a else 0, int(b) if b else num_frames))
            else:
                frames.append(int(part))
        except ValueError:
            raise InputError(f"--frames must be like '1,3' or '2:10', got {text!r}") from None
    bad = [f for f in frames if not 0 <= f < num_frames]
    if bad or not frames:
        raise InputError(f"--frames {text!r}: the scene has frames 0..{num_frames - 1}")
    return sorted(set(frames))


def _add_deblur_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("method (every variant of the paper's tables is a combination)")
    g.add_argument(
        "--kernels",
        choices=["homography", "displacement"],
        default="homography",
        help="blur kernels from 3D homographies (paper) or 2D displacements (baseline)",
    )
    g.add_argument(
        "--motion-source",
        choices=["gt", "sceneflow", "initial-flow"],
        default=_default_motion_source(),
        help="where the motion comes from (default: %(default)s)",
    )
    g.add_argument("--samples", type=int, default=70, help="time samples per exposure (paper: 70)")
    g.add_argument(
        "--alpha",
        type=_alpha,
        default="auto",
        help="prior weight, or 'auto': from the input's noise level (default; paper: 0.001)",
    )
    w = g.add_mutually_exclusive_group()
    w.add_argument(
        "--boundary-weights",
        choices=["adaptive", "paper"],
        default="adaptive",
        help="motion boundaries: adaptive (default: blur from the dense optical flow near "
        "motion boundaries; without one, each instant shows the surface covering the pixel "
        "then, pixels showing surfaces hidden at the frame centre are down-weighted and the "
        "blurred frame is kept where the motion does not predict the neighbouring frames) or "
        "paper (Eq. 5 data weights as published)",
    )
    w.add_argument(
        "--no-boundary-weights",
        dest="boundary_weights",
        action="store_const",
        const="none",
        help="no motion-boundary handling (w = 1)",
    )
    g.add_argument(
        "--boundary-mask",
        choices=["gt"],
        help="gt: give the scene's gt/mixed pixels weight 0 (the paper's masked experiment)",
    )
    g.add_argument("--irls", type=int, default=10, help="IRLS iterations (paper: 10)")
    g.add_argument("--cg", type=int, default=25, help="CG steps per IRLS iteration (paper: 25)")
    g.add_argument(
        "--segments",
        type=int,
        default=None,
        help="superpixels (default: 1200 at 640x480, scaled with area)",
    )


def _alpha(text: str):
    """``--alpha``: 'auto' or a positive number."""
    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _default_motion_source() -> str:
    from importlib.util import find_spec

    return "sceneflow" if find_spec("stereodeblur.sceneflow.estimate") else "gt"


def _settings(args):
    from .pipeline import DeblurSettings

    return DeblurSettings(
        kernels=args.kernels,
        motion_source=args.motion_source,
        num_samples=args.samples,
        alpha=args.alpha,
        num_irls=args.irls,
        num_cg=args.cg,
        num_segments=args.segments,
        boundary_weights=args.boundary_weights,
        boundary_mask=args.boundary_mask,
    )


def _source_spec(args, *, require_exposure: bool = True):
    from .io.sources import SourceSpec

    return SourceSpec.from_arguments(
        args.source,
        calib=args.calib,
        exposure=args.exposure,
        frame_rate=args.frame_rate,
        color=args.color,
        sequence=args.sequence,
        require_exposure=require_exposure,
    )


def _add_source_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("input (scene folder, KITTI folder, or LEFT_VIDEO RIGHT_VIDEO)")
    g.add_argument("--calib", help="stereo calibration of a video pair: OpenCV YAML or camera.json")
    g.add_argument("--exposure", type=float, help="exposure in seconds (if the input has none)")
    g.add_argument("--frame-rate", type=float, help="frames per second (if the input has none)")
    g.add_argument(
        "--color",
        choices=["linear", "srgb"],
        help="encoding of the input's values (default: the input's, else linear)",
    )
    g.add_argument("--sequence", help="KITTI 2012/2015 sequence number, e.g. 5 or 000005")


def cmd_deblur(args) -> int:
    from .clip import deblur_clip

    settings = _settings(args)
    spec = _source_spec(args)
    source = spec.open()
    frames = None if args.frames is None else parse_frames(args.frames, source.num_frames)
    views = ["left", "right"] if args.views == "both" else [args.views]
    if args.sceneflow:
        return _deblur_with_saved_sceneflow(args, settings, source, frames, views)
    report = deblur_clip(
        spec,
        args.output,
        frames=frames,
        views=views,
        settings=settings,
        overwrite=args.overwrite,
        point_cloud=args.point_cloud,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.quiet,
        command=sys.argv,
    )
    failed = report.failed
    if failed:
        first = failed[0]
        print(
            f"stereodeblur: error: {len(failed)} of {len(report.records)} frame(s) failed "
            f"(first: frame {first.index} {first.view}: {first.error}); see {report.log}",
            file=sys.stderr,
        )
        return EXIT_USAGE if all(r.input_error for r in failed) else 1
    skipped = f", {len(report.skipped)} already done" if report.skipped else ""
    print(f"wrote {report.done} frame(s) to {report.output}{skipped}")
    return 0


def _deblur_with_saved_sceneflow(args, settings, source, frames, views) -> int:
    """``deblur --sceneflow FILE``: one frame, its motion read from ``stereodeblur sceneflow``."""
    from .io.scene import SceneWriter
    from .pipeline import deblur_frame, neighbour_of, sceneflow_motion, with_boundary_flow
    from .sceneflow.storage import load_sceneflow

    if settings.motion_source == "initial-flow" or frames is None or len(frames) != 1:
        raise InputError(
            "--sceneflow FILE needs --frames with the one frame the file describes "
            "and --motion-source sceneflow"
        )
    index = frames[0]
    sceneflow = load_sceneflow(args.sceneflow)
    if sceneflow.shape != tuple(source.shape):
        raise InputError(
            f"{args.sceneflow}: scene flow of size {sceneflow.shape}, "
            f"frames are {tuple(source.shape)}"
        )
    neighbour = neighbour_of(index, source.num_frames)
    say = Progress(args.quiet)
    writer = SceneWriter(args.output, source.info, overwrite=args.overwrite, protect=[source.root])
    for view in views:
        motion = sceneflow_motion(sceneflow, index, neighbour, view)
        motion = with_boundary_flow(motion, source, settings, source.read_frame(view, index))
        result = deblur_frame(
            source, index, view=view, settings=settings, motion=motion, progress=say
        )
        writer.write_frame(view, index, result.image)
    print(f"wrote {len(views)} frame(s) to {writer.root}")
    return 0


def cmd_synth_average(args) -> int:
    from .synth.average import average_clip

    say = Progress(args.quiet)
    source = _source_spec(args, require_exposure=False).open()
    protect = list(getattr(source, "paths", [])) or [source.root]
    root = average_clip(
        source,
        args.output,
        window=args.window,
        stride=args.stride,
        overwrite=args.overwrite,
        protect=protect,
        progress=say,
    )
    print(f"wrote {root}")
    return 0


def cmd_render_view(args) -> int:
    import numpy as np

    from .io.formats import write_png
    from .pointcloud import parse_vector, read_ply, render_view

    cloud = read_ply(args.cloud)
    size = parse_size(args.size) if args.size else None
    K = None
    if args.focal is not None:
        if size is None and cloud.size is None:
            raise InputError("--focal needs --size: the point cloud states no image size")
        w, h = size or cloud.size
        K = np.array([[args.focal, 0, (w - 1) / 2], [0, args.focal, (h - 1) / 2], [0, 0, 1]])
    rendered = render_view(
        cloud,
        rotation=np.deg2rad(parse_vector(args.rotate, "--rotate")),
        translation=parse_vector(args.shift, "--shift"),
        K=K,
        size=size,
        colors=args.colors or ("deblurred" if cloud.blurred_colors is None else "both"),
    )
    write_png(args.output, rendered.image, bit_depth=8)
    print(
        f"wrote {args.output}: {len(cloud)} points, {100 * rendered.mask.mean():.1f} % of "
        "pixels covered"
    )
    return 0


def cmd_synth(args) -> int:
    from .synth.planar import write_planar_set

    say = Progress(args.quiet)
    size = parse_size(args.size)
    names = args.scenes.split(",") if args.scenes else None
    roots = write_planar_set(args.output, size=size, names=names, progress=say)
    print(f"wrote {len(roots)} scene(s) to {args.output}")
    return 0


def cmd_synth_objects(args) -> int:
    from .synth.objects import write_object_set

    say = Progress(args.quiet)
    size = parse_size(args.size)
    names = args.scenes.split(",") if args.scenes else None
    roots = write_object_set(
        args.output, size=size, names=names, noise_variants=not args.no_noisy, progress=say
    )
    print(f"wrote {len(roots)} scene(s) to {args.output}")
    return 0


def cmd_demo(args) -> int:
    from .demo import run_demo

    return run_demo(Path(args.output), size=parse_size(args.size), progress=Progress(args.quiet))


def cmd_sceneflow(args) -> int:
    from .io.scene import open_scene
    from .pipeline import neighbour_of
    from .sceneflow.estimate import estimate_scene_flow
    from .sceneflow.storage import write_sceneflow_outputs

    say = Progress(args.quiet)
    scene = open_scene(args.scene)
    index = parse_frames(str(args.frame), scene.num_frames)[0]
    neighbour = neighbour_of(index, scene.num_frames)
    frames = [scene.read_frame(v, i) for i in (index, neighbour) for v in ("left", "right")]
    estimate = estimate_scene_flow(
        *frames,
        scene.info.camera,
        num_segments=args.segments,
        exposure=scene.info.exposure,
        progress=lambda stage, fraction: say(f"scene flow: {stage} ({100 * fraction:.0f} %)"),
        debug_dir=args.debug_dir,
    )
    written = write_sceneflow_outputs(args.output, estimate.sceneflow, index)
    print(f"scene flow of frame {index} -> {neighbour} written to {args.output}")
    for path in written.values():
        print(f"  {path}")
    return 0


def cmd_kernels(args) -> int:
    from .evaluation.kernels_figure import main as kernels_main

    return kernels_main(args)


def cmd_bench(args) -> int:
    if args.suite == "planar":
        from .evaluation.planar_bench import main as bench_main
    elif args.suite == "paper":
        from .evaluation.paper_bench import main as bench_main
    else:
        from .evaluation.sceneflow_bench import main as bench_main
    return bench_main(args)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="stereodeblur",
        description="Remove motion blur from rectified stereo video "
        "(Sellent, Rother, Roth, ECCV 2016).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser(
        "deblur",
        help="deblur frames of a scene",
        description=(
            "Deblur frames of a scene folder (stereo-video/1 format) and write them as a scene."
        ),
    )
    p.add_argument(
        "source",
        nargs="+",
        help="input: a scene folder, a KITTI folder, or two videos LEFT RIGHT (with --calib)",
    )
    p.add_argument("-o", "--output", required=True, help="output scene folder")
    p.add_argument("--frames", help="frames to deblur: '1,3', '10:200' (default: all)")
    p.add_argument("--views", choices=["left", "right", "both"], default="both")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="deblur finished frames again; allow writing into a folder of another scene",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p.add_argument(
        "--sceneflow",
        metavar="FILE",
        help="reuse a scene flow saved by 'stereodeblur sceneflow' (OUT/sceneflow/NNNNNN.npz) "
        "for the one frame given with --frames",
    )
    p.add_argument(
        "--point-cloud",
        action="store_true",
        help="also write a coloured PLY per frame (OUT/pointcloud/VIEW/NNNNNN.ply)",
    )
    r = p.add_argument_group("running")
    r.add_argument(
        "--workers",
        type=int,
        help="local worker processes (default: one per core, as memory allows; 1: in process)",
    )
    r.add_argument(
        "--scheduler",
        help="address of a Dask distributed scheduler, tcp://HOST:PORT (needs stereodeblur[dask]); "
        "input and output paths must be shared with its workers",
    )
    _add_source_options(p)
    _add_deblur_options(p)
    p.set_defaults(func=cmd_deblur)

    p = sub.add_parser(
        "sceneflow",
        help="estimate the piecewise-rigid scene flow of a frame",
        description="Estimate planes, rigid motions and occlusion of a frame "
        "(towards the next frame) and write them in the layout of a scene's gt/.",
    )
    p.add_argument("scene", help="input scene folder")
    p.add_argument("--frame", type=int, required=True, help="frame index")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument(
        "--segments",
        type=int,
        default=None,
        help="superpixels (default: 1200 at 640x480, scaled with area)",
    )
    p.add_argument("--debug-dir", help="write pictures of segments, disparity, flow, occlusion")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_sceneflow)

    p = sub.add_parser(
        "demo",
        help="render a small scene, deblur it, write a side-by-side picture",
        description="Render a built-in blurred stereo scene, deblur it and write "
        "blurred | deblurred | sharp as a PNG; prints the PSNRs.",
    )
    p.add_argument("-o", "--output", default="stereodeblur-demo", help="output folder")
    p.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser(
        "synth",
        help="render synthetic benchmark scenes",
        description="Render physically blurred benchmark scenes with ground truth.",
    )
    synth = p.add_subparsers(dest="kind", required=True, parser_class=_Parser)
    q = synth.add_parser(
        "planar",
        help="textured planes under the paper's motions",
        description="Textured planes under the paper's 3D motions.",
    )
    q.add_argument("output", help="folder to write one scene per motion into")
    q.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default: %(default)s)")
    q.add_argument("--scenes", help="comma-separated motion names (default: all)")
    q.add_argument("-q", "--quiet", action="store_true")
    q.set_defaults(func=cmd_synth)
    q = synth.add_parser(
        "objects",
        help="moving spheres, boxes, planes and a cylinder before a background",
        description="Several textured objects with independent rigid motions in front of a "
        "textured background (the paper's ray-traced scenes), each also with sensor noise "
        "(sigma = 0.01) as NAME_noisy.",
    )
    q.add_argument("output", help="folder to write one scene per name into")
    q.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default: %(default)s)")
    q.add_argument("--scenes", help="comma-separated scene names (default: all)")
    q.add_argument("--no-noisy", action="store_true", help="skip the NAME_noisy variants")
    q.add_argument("-q", "--quiet", action="store_true")
    q.set_defaults(func=cmd_synth_objects)
    q = synth.add_parser(
        "average",
        help="blurred benchmark from sharp high-frame-rate footage",
        description="Average --window consecutive sharp frames of a fast stereo clip into each "
        "blurred frame of a new scene; the centre frame is stored as gt/sharp.",
    )
    q.add_argument(
        "source", nargs="+", help="sharp clip: scene or KITTI folder, or two videos LEFT RIGHT"
    )
    q.add_argument("output", help="output scene folder")
    q.add_argument("--window", type=int, required=True, help="frames per blurred frame (odd)")
    q.add_argument("--stride", type=int, help="source frames between blurred frames (default: K)")
    q.add_argument("--overwrite", action="store_true", help="allow writing into another scene")
    q.add_argument("-q", "--quiet", action="store_true")
    _add_source_options(q)
    q.set_defaults(func=cmd_synth_average)

    p = sub.add_parser(
        "render-view",
        help="render a point cloud (--point-cloud output) from a shifted viewpoint",
        description="Render a PLY point cloud written by 'deblur --point-cloud' from a camera "
        "moved by --shift and turned by --rotate; '--colors both' puts deblurred and blurred "
        "colours side by side.",
    )
    p.add_argument("cloud", help="PLY file")
    p.add_argument("-o", "--output", required=True, help="output PNG")
    p.add_argument("--shift", default="0,0,0", help="camera centre X,Y,Z in scene units")
    p.add_argument("--rotate", default="0,0,0", help="camera rotation vector in degrees")
    p.add_argument(
        "--colors",
        choices=["deblurred", "blurred", "both"],
        help="which colours (default: both side by side when the cloud has blurred ones)",
    )
    p.add_argument("--size", help="WIDTHxHEIGHT (default: the frame's)")
    p.add_argument("--focal", type=float, help="focal length in pixels (default: the frame's)")
    p.set_defaults(func=cmd_render_view)

    p = sub.add_parser(
        "kernels",
        help="picture of homography- vs flow-induced blur kernels (paper Fig. 3)",
        description="Blur kernels of a yawing plane at a grid of pixels: from 3D homographies, "
        "from the 2D flow (displacement model), and their difference, side by side as a PNG.",
    )
    p.add_argument("-o", "--output", required=True, help="output PNG")
    p.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default: %(default)s)")
    p.add_argument(
        "--yaw", type=float, default=0.3, help="radians per frame interval (default: %(default)s)"
    )
    p.add_argument("--depth", type=float, default=3.0, help="plane distance in metres")
    p.set_defaults(func=cmd_kernels)

    p = sub.add_parser(
        "bench",
        help="benchmarks that print the paper's tables",
        description="Quality benchmarks on the synthetic scenes.",
    )
    bench = p.add_subparsers(dest="suite", required=True, parser_class=_Parser)
    q = bench.add_parser(
        "planar",
        help="paper Table 2 on planar scenes",
        description="PSNR/SSIM of displacement vs homography kernels from "
        "true motion on physically rendered planar scenes.",
    )
    q.add_argument("--sizes", default="320x240,640x480", help="comma-separated WIDTHxHEIGHT")
    q.add_argument("--scenes", help="comma-separated motion names (default: all)")
    q.add_argument("--work", default="bench-planar", help="folder for rendered scenes and results")
    q.add_argument("-q", "--quiet", action="store_true")
    q.set_defaults(func=cmd_bench)
    q = bench.add_parser(
        "sceneflow",
        help="scene-flow accuracy (ADE, AEP, rigid-motion error) and speed",
        description="Scene-flow accuracy on the synthetic scenes (inputs blurred) and the "
        "Middlebury motorcycle pair as a static clip.",
    )
    q.add_argument("--sizes", default="640x480", help="comma-separated WIDTHxHEIGHT")
    q.add_argument(
        "--scenes",
        help="comma-separated planar motions and object scenes, NAME_noisy for the noisy "
        "variant (default: every planar motion and noiseless object scene)",
    )
    q.add_argument("--frame", type=int, default=1, help="frame whose motion is estimated")
    q.add_argument("--work", default="bench-sceneflow", help="folder for scenes and results")
    q.add_argument("--no-motorcycle", action="store_true", help="skip the motorcycle check")
    q.add_argument("-q", "--quiet", action="store_true")
    q.set_defaults(func=cmd_bench)
    q = bench.add_parser(
        "paper",
        help="paper Tables 2-4 on the object and planar scenes, noiseless and noisy",
        description="Deblur frame 1 of every scene with each column of the paper's Tables 2-4 "
        "(gt 2D displacement, initial optical flow, 2D projection of the scene flow, "
        "3D homographies, paper full, ours full); PSNR, SSIM, AEP, ADE as Markdown and JSON, "
        "a figure per scene. Resumable: results are cached in the work folder.",
    )
    q.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default: %(default)s)")
    q.add_argument(
        "--scenes", help="comma-separated scene names, NAME or NAME_noisy (default: all)"
    )
    q.add_argument("--work", default="bench-paper", help="folder for scenes, cache and results")
    q.add_argument(
        "--alpha-sweep", action="store_true", help="also run ours (full) at 5 fixed alphas"
    )
    q.add_argument("--no-masked", action="store_true", help="skip Table 2 (gt-masked columns)")
    q.add_argument("--samples", type=int, default=70, help="time samples per exposure (70)")
    q.add_argument("--irls", type=int, default=10, help="IRLS iterations (paper: 10)")
    q.add_argument("--cg", type=int, default=25, help="CG steps per IRLS iteration (paper: 25)")
    q.add_argument("--segments", type=int, default=None, help="superpixels of the scene flow")
    q.add_argument(
        "--render-samples", type=int, default=48, help="instants averaged per rendered frame"
    )
    q.add_argument("-q", "--quiet", action="store_true")
    q.set_defaults(func=cmd_bench, argv=None)
    return parser


def _version() -> str:
    from . import __version__

    return __version__


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (InputError, FileNotFoundError, NotADirectoryError, IsADirectoryError) as err:
        message = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f"stereodeblur: error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("stereodeblur: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
