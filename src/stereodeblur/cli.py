"""Command-line interface: parse, configure, call the pipeline, write.

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import shutil
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
    g.add_argument("--alpha", type=float, default=1e-3, help="prior weight (paper: 0.001)")
    g.add_argument("--irls", type=int, default=10, help="IRLS iterations (paper: 10)")
    g.add_argument("--cg", type=int, default=25, help="CG steps per IRLS iteration (paper: 25)")
    g.add_argument(
        "--segments",
        type=int,
        default=None,
        help="superpixels (default: 1200 at 640x480, scaled with area)",
    )


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
    )


def cmd_deblur(args) -> int:
    from .io.scene import SceneWriter, open_scene
    from .pipeline import deblur_frame

    say = Progress(args.quiet)
    settings = _settings(args)
    scene = open_scene(args.scene)
    frames = parse_frames(args.frames, scene.num_frames)
    if args.frames is None and settings.motion_source == "gt":
        frames = [i for i in frames if scene.has_gt("flow", "left", i)]
        if not frames:
            raise InputError(f"--motion-source gt: {args.scene} has no gt/flow/left/*.flo")
    views = ["left", "right"] if args.views == "both" else [args.views]
    output = Path(args.output)
    created = not output.exists()
    writer = SceneWriter(output, scene.info, overwrite=args.overwrite, protect=[scene.root])
    total = len(frames) * len(views)
    done = 0
    try:
        for index in frames:
            for view in views:
                result = deblur_frame(scene, index, view=view, settings=settings, progress=say)
                writer.write_frame(view, index, result.image)
                done += 1
                t = result.timings
                say(
                    f"frame {index} {view} written ({done}/{total}): motion {t['motion']:.1f} s, "
                    f"operator {t['operator']:.1f} s, deconvolution {t['deconvolution']:.1f} s"
                )
    except BaseException:
        if created and done == 0:  # leave nothing half-written behind
            shutil.rmtree(output, ignore_errors=True)
        raise
    print(f"wrote {done} frame(s) to {writer.root}")
    return 0


def cmd_synth(args) -> int:
    from .synth.planar import write_planar_set

    say = Progress(args.quiet)
    size = parse_size(args.size)
    names = args.scenes.split(",") if args.scenes else None
    roots = write_planar_set(args.output, size=size, names=names, progress=say)
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
        progress=lambda stage, fraction: say(f"scene flow: {stage} ({100 * fraction:.0f} %)"),
        debug_dir=args.debug_dir,
    )
    written = write_sceneflow_outputs(args.output, estimate.sceneflow, index)
    print(f"scene flow of frame {index} -> {neighbour} written to {args.output}")
    for path in written if isinstance(written, list | tuple) else []:
        print(f"  {path}")
    return 0


def cmd_bench(args) -> int:
    if args.suite == "planar":
        from .evaluation.planar_bench import main as bench_main
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
    p.add_argument("scene", help="input scene folder")
    p.add_argument("-o", "--output", required=True, help="output scene folder")
    p.add_argument("--frames", help="frames to deblur: '1,3', '2:10' (default: all)")
    p.add_argument("--views", choices=["left", "right", "both"], default="left")
    p.add_argument("--overwrite", action="store_true", help="allow writing into a non-empty folder")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
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
