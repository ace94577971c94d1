"""Frames per minute of whole-clip deblurring at 640x480: 1 and 2 local workers, a LocalCluster.

Run from the repository root::

    python benchmarks/bench_clip.py                       # 4 frames, both views, scene flow
    python benchmarks/bench_clip.py --frames 6 --motion-source gt --json out.json

A planar clip (``forward_yaw``) is rendered once into ``--work`` and deblurred with
the default settings (70 samples, 4 IRLS x 25 CG) by ``stereodeblur.clip.deblur_clip``
in three ways, each from scratch (``overwrite``):

- ``workers=1``: in this process (numba uses every core);
- ``workers=2``: two spawned worker processes with ``cores // 2`` threads each;
- ``LocalCluster``: a Dask cluster of two worker processes (one thread each) on
  loopback, started before the clock runs (``--no-dask`` skips it).

Reported per way: wall seconds, view-frames (frames x views) per minute of wall time,
median seconds per task (one stereo frame, both views, motion computed once) as the
workers measured it, and PSNR of the deblurred left frames against the ground truth.
Wall time includes starting worker processes (numba loads its cached kernels in each); a
warm-up frame in this process compiles them first.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path


def render_clip(work: Path, size: tuple[int, int], num_frames: int) -> Path:
    from stereodeblur.synth.planar import make_planar_scene, write_rendered_scene

    root = work / f"forward_yaw-{size[0]}x{size[1]}-{num_frames}"
    if not (root / "camera.json").is_file():
        scene = make_planar_scene("forward_yaw", size=size, num_frames=num_frames)
        write_rendered_scene(scene, root, overwrite=True)
    return root


def measure(name, clip, output, settings, frames, **where) -> dict:
    from stereodeblur.clip import deblur_clip
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.io.scene import open_scene
    from stereodeblur.io.sources import SourceSpec

    shutil.rmtree(output, ignore_errors=True)
    start = time.perf_counter()
    report = deblur_clip(
        SourceSpec.from_arguments(clip),
        output,
        frames=frames,
        settings=settings,
        progress=False,
        **where,
    )
    wall = time.perf_counter() - start
    if report.failed:
        raise RuntimeError(f"{name}: {report.failed[0].error}")
    source, result = open_scene(clip), open_scene(output)
    gains = [
        psnr(result.read_frame("left", i), source.read_gt_sharp("left", i))
        - psnr(source.read_frame("left", i), source.read_gt_sharp("left", i))
        for i in frames
    ]
    return {
        "way": name,
        "views": len(report.records),
        "wall_s": round(wall, 1),
        "frames_per_minute": round(len(report.records) / wall * 60, 2),
        "median_task_s": round(
            statistics.median({r.index: r.seconds for r in report.records}.values()), 1
        ),
        "psnr_gain_db": round(statistics.mean(gains), 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default %(default)s)")
    parser.add_argument(
        "--frames", type=int, default=4, help="frames (x 2 views) per way (default %(default)s)"
    )
    parser.add_argument(
        "--motion-source",
        default="sceneflow",
        choices=["sceneflow", "gt"],
        help="estimated scene flow or the true motion (default %(default)s)",
    )
    parser.add_argument(
        "--work",
        default=str(Path(tempfile.gettempdir()) / "stereodeblur_bench_clip"),
        help="folder for the clip and outputs (default %(default)s)",
    )
    parser.add_argument("--no-dask", action="store_true", help="skip the LocalCluster")
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()

    from stereodeblur.pipeline import DeblurSettings, deblur_frame

    width, height = (int(v) for v in args.size.split("x"))
    work = Path(args.work)
    clip = render_clip(work, (width, height), args.frames + 1)
    frames = list(range(args.frames))
    settings = DeblurSettings(motion_source=args.motion_source)
    from stereodeblur.io.scene import open_scene

    deblur_frame(open_scene(clip), 0, settings=settings)  # warm-up: numba kernels compiled
    cores = len(os.sched_getaffinity(0))
    rows = [
        measure("1 worker", clip, work / "out-1", settings, frames, workers=1),
        measure("2 workers", clip, work / "out-2", settings, frames, workers=2),
    ]
    if not args.no_dask:
        import logging

        from distributed import LocalCluster

        with LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster:
            rows.append(
                measure(
                    "LocalCluster 2x1",
                    clip,
                    work / "out-dask",
                    settings,
                    frames,
                    scheduler=cluster.scheduler_address,
                )
            )
    print(
        f"{args.size}, {args.frames} frames x 2 views, motion {args.motion_source}, "
        f"default settings, {cores} cores, load average {os.getloadavg()[0]:.1f}"
    )
    print(f"{'way':>18} {'views':>5} {'wall s':>7} {'frames/min':>10} {'s/task':>7} {'dB gain':>7}")
    for row in rows:
        print(
            f"{row['way']:>18} {row['views']:>5} {row['wall_s']:>7} "
            f"{row['frames_per_minute']:>10} {row['median_task_s']:>7} {row['psnr_gain_db']:>7}"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
