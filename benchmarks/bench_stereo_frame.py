"""Seconds and peak memory of deblurring one 640x480 stereo frame as a whole process.

Run from the repository root::

    python benchmarks/bench_stereo_frame.py                  # spheres, 640x480, median of 3
    python benchmarks/bench_stereo_frame.py --scene squares --repeats 5 --json out.json
    python benchmarks/bench_stereo_frame.py --scene long_exposure_roll   # a planar scene: arcs
    python benchmarks/bench_stereo_frame.py --alpha cross-view   # a setting other than the default
    python benchmarks/bench_stereo_frame.py --observations all --irls 6 --cg 10
    python benchmarks/bench_stereo_frame.py --interpolation bilinear   # the paper's sampling
    python benchmarks/bench_stereo_frame.py --local-alpha always

An object scene (``stereodeblur.synth.objects``) or a planar motion's scene
(``stereodeblur.synth.planar``) is rendered once into ``--work``. A
warm-up process on a 64x48 rendering of the same scene compiles the numba kernels into
their on-disk cache first (its wall time is reported apart). Each
repetition is a fresh Python process (``--child``) that imports the package, deblurs
frame 1 of both views with the default settings (estimated scene flow, 70 samples,
4 IRLS x 25 CG, one process: what ``stereodeblur deblur SCENE -o OUT --frames 1
--views both --workers 1`` does) and writes the two frames. Reported: the median wall
time of the processes, the largest peak resident memory (``ru_maxrss`` of each
child process), and per stage the median seconds the pipeline measured: reading, motion
(scene flow, dense flow and trust, shared by both views), and per view the blur
operator and the deconvolution. Printed as JSON (and written to ``--json FILE``).
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from stereodeblur.settings import LOCAL_ALPHA_MODES

VIEWS = ("left", "right")
INDEX = 1


def render(work: Path, name: str, size: tuple[int, int]) -> Path:
    """The object scene or planar motion ``name`` at ``size`` in ``work`` (rendered once)."""
    from stereodeblur.synth.objects import make_object_scene
    from stereodeblur.synth.planar import PLANAR_MOTIONS, make_planar_scene, write_rendered_scene

    root = work / f"{name}-{size[0]}x{size[1]}"
    if not (root / "camera.json").is_file():
        make = make_planar_scene if name in PLANAR_MOTIONS else make_object_scene
        write_rendered_scene(make(name, size=size), root, overwrite=True)
    return root


def child(scene_path: str, output: str, options: dict) -> None:
    """One stereo frame in this process (``options``: settings instead of the default,
    ``alpha`` as on the command line); prints the stage timings as JSON."""
    start = time.perf_counter()
    from stereodeblur import pipeline
    from stereodeblur.cli.settings_options import alpha as alpha_option
    from stereodeblur.io.scene import SceneWriter, open_scene

    scene = open_scene(scene_path)
    if "alpha" in options:
        options = options | {"alpha": alpha_option(options["alpha"])}
    settings = pipeline.DeblurSettings(**options)
    stereo = pipeline.deblur_stereo_frame(scene, INDEX, views=VIEWS, settings=settings)
    frames = stereo.frames
    stages = dict(stereo.timings)
    writer = SceneWriter(output, scene.info, overwrite=True)
    for view, result in frames.items():
        writer.write_frame(view, INDEX, result.image)
        for stage, seconds in result.timings.items():
            if stage != "motion" or "motion" not in stages:  # the stereo frame's is shared
                stages[f"{stage} {view}"] = seconds
    stages["process"] = time.perf_counter() - start
    stages["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(stages))


def process(scene: Path, output: Path, options: dict) -> tuple[float, dict]:
    """Wall seconds and the stage timings of one child process."""
    command = [sys.executable, __file__, "--child", str(scene), str(output)]
    for name, value in options.items():
        command += [f"--{name}", str(value)]
    start = time.perf_counter()
    done = subprocess.run(command, check=True, capture_output=True, text=True)
    return time.perf_counter() - start, json.loads(done.stdout.strip().splitlines()[-1])


def run(scene: Path, output: Path, repeats: int, warmup: Path, options: dict) -> dict:
    """Median wall seconds and stage timings of ``repeats`` child processes."""
    warm, _ = process(warmup, output.with_name(output.name + "-warmup"), options)
    walls, runs = [], []
    for _ in range(repeats):
        wall, stages = process(scene, output, options)
        walls.append(wall)
        runs.append(stages)
    stages = {key: round(statistics.median(r[key] for r in runs), 2) for key in runs[0]}
    return {
        "scene": scene.name,
        "settings": options or "default",
        "repeats": repeats,
        "warmup_s": round(warm, 2),
        "wall_s": round(statistics.median(walls), 2),
        "wall_all_s": [round(w, 2) for w in walls],
        "peak_rss_mib": round(max(r["peak_rss_mib"] for r in runs)),
        "stages_s": {k: v for k, v in stages.items() if k != "peak_rss_mib"},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scene", default="spheres", help="object scene or planar motion (default %(default)s)"
    )
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default %(default)s)")
    parser.add_argument(
        "--repeats", type=int, default=3, help="timed processes (default %(default)s)"
    )
    parser.add_argument(
        "--work",
        type=Path,
        default=Path(tempfile.gettempdir()) / "sd-bench",
        help="folder for the rendered scene and outputs (default %(default)s)",
    )
    parser.add_argument("--json", type=Path, help="also write the result here")
    parser.add_argument("--alpha", help="--alpha of the run (default: the settings' default)")
    parser.add_argument("--observations", help="--observations of the run (default: the default)")
    parser.add_argument("--interpolation", help="--interpolation of the run (default: the default)")
    parser.add_argument(
        "--num_irls",
        "--irls",
        dest="num_irls",
        type=int,
        help="IRLS iterations (default: the default)",
    )
    parser.add_argument(
        "--num_cg",
        "--cg",
        dest="num_cg",
        type=int,
        help="CG steps per iteration (default: the default)",
    )
    parser.add_argument(
        "--relabel-radius",
        dest="relabel_radius",
        type=int,
        help="--relabel-radius of the run (default: the default)",
    )
    parser.add_argument(
        "--local_alpha",
        "--local-alpha",
        dest="local_alpha",
        choices=LOCAL_ALPHA_MODES,
        help="--local-alpha of the run (default: the default)",
    )
    parser.add_argument("--child", nargs=2, metavar=("SCENE", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    options = {
        name: getattr(args, name)
        for name in (
            "alpha",
            "observations",
            "interpolation",
            "num_irls",
            "num_cg",
            "relabel_radius",
            "local_alpha",
        )
        if getattr(args, name) is not None
    }
    if args.child:
        child(*args.child, options)
        return
    width, height = (int(v) for v in args.size.lower().split("x"))
    args.work.mkdir(parents=True, exist_ok=True)
    scene = render(args.work, args.scene, (width, height))
    warmup = render(args.work, args.scene, (64, 48))
    result = run(scene, args.work / f"{scene.name}-out", args.repeats, warmup, options)
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
