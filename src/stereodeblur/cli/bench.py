"""``stereodeblur bench planar|sceneflow|paper``: the benchmarks that print the paper's tables.

Parsing only: each runner calls a typed entry point of :mod:`stereodeblur.evaluation`.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager

from ..evaluation import paper_bench, planar_bench, sceneflow_bench
from .base import Parser, add_quiet, add_size, add_sizes, integer, names
from .printer import progress_printer
from .settings_options import add_settings_options, settings_from_arguments

RENDER_SAMPLES = (2, 1000)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="benchmarks that print the paper's tables",
        description="Quality benchmarks on the synthetic scenes.",
    )
    bench = p.add_subparsers(dest="suite", required=True, parser_class=Parser)
    _add_planar(bench)
    _add_sceneflow(bench)
    _add_paper(bench)


def _add_planar(bench) -> None:
    q = bench.add_parser(
        "planar",
        help="paper Table 2 on planar scenes",
        description="PSNR/SSIM of displacement vs homography kernels from "
        "true motion on physically rendered planar scenes.",
    )
    add_sizes(q, planar_bench.SIZES)
    q.add_argument("--scenes", type=names, help="comma-separated motion names (default: all)")
    q.add_argument(
        "--work",
        default="bench-planar",
        help="folder for rendered scenes and results (default: %(default)s)",
    )
    add_quiet(q)
    q.set_defaults(func=run_planar)


def _add_sceneflow(bench) -> None:
    q = bench.add_parser(
        "sceneflow",
        help="scene-flow accuracy (ADE, AEP, rigid-motion error) and speed",
        description="Scene-flow accuracy on the synthetic scenes (inputs blurred) and the "
        "Middlebury motorcycle pair as a static clip.",
    )
    add_sizes(q, sceneflow_bench.SIZES)
    q.add_argument(
        "--scenes",
        type=names,
        help="comma-separated planar motions and object scenes, NAME_noisy for the noisy "
        "variant (default: every planar motion and noiseless object scene)",
    )
    q.add_argument(
        "--frames",
        dest="frame",
        type=integer(0),
        metavar="I",
        default=sceneflow_bench.FRAME,
        help="the frame whose scene flow is measured in every scene, one frame number "
        "(default: %(default)s)",
    )
    q.add_argument(
        "--work",
        default="bench-sceneflow",
        help="folder for scenes and results (default: %(default)s)",
    )
    q.add_argument(
        "--no-motorcycle",
        action="store_true",
        help="skip the motorcycle check (default: off: the check runs)",
    )
    add_quiet(q)
    q.set_defaults(func=run_sceneflow)


def _add_paper(bench) -> None:
    q = bench.add_parser(
        "paper",
        help="paper Tables 2-4 on the object and planar scenes, noiseless and noisy",
        description="Deblur frame 1 of every scene with each column of the paper's Tables 2-4 "
        "(gt 2D displacement, initial optical flow, 2D projection of the scene flow, "
        "3D homographies, paper full, ours full); PSNR, SSIM, AEP, ADE as Markdown and JSON, "
        "a figure per scene. Resumable: results are cached in the work folder. The paper's "
        "columns run the paper's IRLS and CG counts unless --irls or --cg is given.",
    )
    add_size(q, paper_bench.SIZE)
    q.add_argument(
        "--scenes",
        type=names,
        help="comma-separated scene names, NAME or NAME_noisy (default: all)",
    )
    q.add_argument(
        "--work",
        default="bench-paper",
        help="folder for scenes, cache and results (default: %(default)s)",
    )
    q.add_argument(
        "--alpha-sweep",
        action="store_true",
        help="also run ours (full) at 5 fixed alphas (default: off)",
    )
    q.add_argument(
        "--no-masked",
        action="store_true",
        help="skip Table 2, the gt-masked columns (default: off: Table 2 runs)",
    )
    add_settings_options(q, ("num_samples", "num_irls", "num_cg", "num_segments"))
    q.add_argument(
        "--render-samples",
        type=integer(*RENDER_SAMPLES),
        default=paper_bench.RENDER_SAMPLES,
        help=f"instants averaged per rendered frame, {RENDER_SAMPLES[0]}..{RENDER_SAMPLES[1]} "
        "(default: %(default)s)",
    )
    add_quiet(q)
    q.set_defaults(func=run_paper)


@contextmanager
def _locked_work(work: str, command: str) -> Iterator[None]:
    """Hold the checked work folder (created if need be) while the bench runs: a second run
    into it is refused (InputError) instead of deleting the first one's half-written scenes.
    A folder created here that the bench left empty (it refused its input) is removed."""
    from ..io.outputs import LOCK_NAME, OutputLock, check_output, make_folder

    folder = check_output(work, [], command=command)
    created = not folder.exists()
    make_folder(folder)
    try:
        with OutputLock(folder):
            yield
    finally:
        if created and [p.name for p in folder.iterdir()] == [LOCK_NAME]:
            (folder / LOCK_NAME).unlink()
            folder.rmdir()


def run_planar(args: argparse.Namespace) -> int:
    from ..evaluation.planar_bench import run_planar_bench

    with _locked_work(args.work, "bench planar"):
        bench = run_planar_bench(
            args.work, sizes=args.sizes, scenes=args.scenes, progress=progress_printer(args.quiet)
        )
    print(bench.table)
    print()
    print(bench.summary)
    return 0


def run_sceneflow(args: argparse.Namespace) -> int:
    from ..evaluation.sceneflow_bench import run_sceneflow_bench

    with _locked_work(args.work, "bench sceneflow"):
        bench = run_sceneflow_bench(
            args.work,
            sizes=args.sizes,
            scenes=args.scenes,
            frame=args.frame,
            motorcycle=not args.no_motorcycle,
            progress=progress_printer(args.quiet),
        )
    print(bench.table)
    return 0


def run_paper(args: argparse.Namespace) -> int:
    from ..evaluation.paper_bench import run_paper_bench

    with _locked_work(args.work, "bench paper"):
        bench = run_paper_bench(
            args.work,
            size=args.size,
            scenes=args.scenes,
            settings=settings_from_arguments(args),
            alpha_sweep=args.alpha_sweep,
            masked=not args.no_masked,
            render_samples=args.render_samples,
            command="stereodeblur " + " ".join(args.argv),
            progress=progress_printer(args.quiet),
        )
    print(bench.text, end="")
    return 0
