"""Scene-flow quality, time and memory on the planar scenes, plus the motorcycle check.

Run from the repository root::

    python benchmarks/bench_sceneflow.py                       # all planar scenes, 640x480
    python benchmarks/bench_sceneflow.py --scenes forward,yaw --size 320x240
    python benchmarks/bench_sceneflow.py --no-motorcycle --root /tmp/planar

Scenes are rendered with :func:`stereodeblur.synth.planar.write_planar_set` into
``--root`` (default ``$TMPDIR/stereodeblur_planar_WxH``) unless they are there already.
Each scene is then evaluated in its own subprocess by
:func:`stereodeblur.evaluation.sceneflow_bench.evaluate_scene` on the blurred frames
1 and 2, so that the peak resident memory (``resource.getrusage``) belongs to that
scene alone; the time is the wall time of ``estimate_scene_flow`` (numba kernels
are cached on disk, a first warm-up run compiles them) and its CPU time (all
threads; wall time on an idle 2-core machine lies between half of it and all of
it, so CPU time is the figure to compare when the machine is shared). The
motorcycle check runs
in a subprocess too. Output: Markdown tables (stdout), and ``--json FILE`` with
all numbers.

Targets: at 640x480, planar scenes, every pixel counted: scene-flow AEP
<= 0.5 px, ADE <= 1 px; <= 15 s per frame pair on a 2-core machine, peak memory
<= 3 GB; motorcycle: fewer > 2 px disparity errors than plain SGBM.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path


def _worker_scene(root: str) -> None:
    from stereodeblur.evaluation.sceneflow_bench import evaluate_scene

    result = evaluate_scene(root, frame=1)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB -> MiB
    print(json.dumps({"result": asdict(result), "peak_mib": peak}))


def _worker_motorcycle() -> None:
    from stereodeblur.evaluation.sceneflow_bench import run_motorcycle_check

    result = run_motorcycle_check()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"result": asdict(result), "peak_mib": peak}))


def _warm_up() -> None:
    """Compile (or load) the numba kernels once, on a tiny pair."""
    import warnings

    import numpy as np

    from stereodeblur.geometry import StereoCamera
    from stereodeblur.sceneflow import estimate_scene_flow

    rng = np.random.default_rng(0)
    tex = rng.random((48, 80)).astype(np.float32)
    cam = StereoCamera([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]], 0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        estimate_scene_flow(tex[:, 8:72], tex[:, 10:74], tex[:, 9:73], tex[:, 11:75], cam)


def _run(args: list[str]) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--size", default="640x480", help="WIDTHxHEIGHT of the planar scenes (default %(default)s)"
    )
    parser.add_argument(
        "--scenes", default=None, help="comma-separated planar scene names (default: all nine)"
    )
    parser.add_argument(
        "--root",
        default=None,
        help="folder of (cached) rendered scenes (default: $TMPDIR/stereodeblur_planar_WxH)",
    )
    parser.add_argument(
        "--no-motorcycle", action="store_true", help="skip the motorcycle disparity check"
    )
    parser.add_argument("--json", default=None, help="write all numbers to this file")
    parser.add_argument("--_worker", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args._worker == "motorcycle":
        _worker_motorcycle()
        return 0
    if args._worker is not None:
        _worker_scene(args._worker)
        return 0

    from stereodeblur.evaluation.sceneflow_bench import (
        MotorcycleResult,
        ObjectMotionError,
        SceneFlowBenchResult,
        format_sceneflow_table,
    )
    from stereodeblur.synth.planar import PLANAR_MOTIONS, write_planar_set

    width, height = (int(v) for v in args.size.lower().split("x"))
    names = list(PLANAR_MOTIONS) if args.scenes is None else args.scenes.split(",")
    default = Path(tempfile.gettempdir()) / f"stereodeblur_planar_{width}x{height}"
    root = Path(args.root) if args.root else default
    missing = [n for n in names if not (root / n / "camera.json").is_file()]
    if missing:
        print(f"rendering {', '.join(missing)} into {root} ...", file=sys.stderr)
        write_planar_set(root, size=(width, height), names=missing)
    _warm_up()
    results, peaks = [], {}
    for name in names:
        data = _run(["--_worker", str(root / name)])
        r = data["result"]
        r["objects"] = tuple(ObjectMotionError(**o) for o in r["objects"])
        r["size"] = tuple(r["size"])
        r["warnings"] = tuple(r["warnings"])
        results.append(SceneFlowBenchResult(**r))
        peaks[name] = data["peak_mib"]
        print(
            f"{name}: AEP {r['aep']:.3f} ADE {r['ade']:.3f} {r['seconds']:.1f} s "
            f"(CPU {r['cpu_seconds']:.1f} s) {data['peak_mib']:.0f} MiB",
            file=sys.stderr,
        )
    motorcycle = None
    if not args.no_motorcycle:
        data = _run(["--_worker", "motorcycle"])
        m = data["result"]
        m["size"] = tuple(m["size"])
        m["warnings"] = tuple(m["warnings"])
        motorcycle = MotorcycleResult(**m)
        peaks["motorcycle"] = data["peak_mib"]
    print(format_sceneflow_table(results, motorcycle))
    seconds = [r.seconds for r in results]
    if seconds:
        median = sorted(seconds)[len(seconds) // 2]
        cpu = sorted(r.cpu_seconds for r in results)
        print(
            f"time per frame pair ({width}x{height}): median {median:.1f} s, "
            f"max {max(seconds):.1f} s wall; CPU median {cpu[len(cpu) // 2]:.1f} s, "
            f"max {cpu[-1]:.1f} s; peak memory max {max(peaks.values()):.0f} MiB; "
            f"load average {os.getloadavg()[0]:.1f}"
        )
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {
                    "scenes": [asdict(r) for r in results],
                    "motorcycle": None if motorcycle is None else asdict(motorcycle),
                    "peak_mib": peaks,
                },
                indent=2,
            )
            + "\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
