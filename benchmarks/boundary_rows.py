"""Where the true motion's lead over the estimated scene flow comes from (issue 13).

Run from the repository root, after ``stereodeblur bench paper --size 640x480 --work W``
(its scenes and cached scene-flow estimates are reused)::

    python benchmarks/boundary_rows.py --work /tmp/paperbench/640x480 --jobs 2 \\
        --output benchmarks/results/boundary_rows_640x480.md

``bench paper``'s "ours, true motion" beats "ours (full)" on the object scenes by about
1.8 dB. The two differ in the motion and in the blur the operator takes near motion
boundaries: with the estimated scene flow the default takes the dense optical flow's rows
there (``boundary_flow``), with the true motion there is no dense flow and the operator
is occlusion-aware. This script deblurs frame 1 (left view, every other setting the
default's) with four motions, each under both operators:

- ``estimated``: the scene-flow estimate ``bench paper`` cached, its boundaries as estimated;
- ``moved``: the same with its boundaries moved to the dense flow's (``relabel_radius``, the
  default since stop 34);
- ``relabelled``: the estimate's planes and motions, each pixel given the segment within
  6 px whose plane and motion come nearest the true disparity and flow (an oracle: how far
  better boundaries alone would go);
- ``true``: the scene flow fitted to the true disparity and flow
  (:func:`stereodeblur.sceneflow.from_gt.sceneflow_from_gt`).

Output: PSNR and the error in the pixels whose exposure mixes surfaces (gt/mixed, MSE x
1000) per object scene and the means per group, as Markdown on stdout and in ``--output``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

RADIUS = 6
"""Pixels within which ``relabelled`` looks for a better segment."""

MOTIONS = ("estimated", "moved", "relabelled", "true")
OPERATORS = {True: "dense-flow rows", False: "occlusion-aware"}


def true_sceneflow(scene):
    """The scene flow the true-motion columns deblur frame 1 with, fitted to its true
    disparity and flow (:func:`stereodeblur.pipeline.motion.gt_motions`)."""
    from stereodeblur.pipeline import DeblurSettings
    from stereodeblur.pipeline.motion import gt_motions
    from stereodeblur.pipeline.window import read_window

    settings = DeblurSettings(motion_source="gt")
    window = read_window(scene, 1, ("left",), settings)
    return gt_motions(scene, window, ("left",), settings)["left"].sceneflow


def relabelled(sceneflow, disparity: np.ndarray, flow: np.ndarray):
    """``sceneflow`` with every pixel given the segment within :data:`RADIUS` px whose plane
    and motion come nearest ``disparity`` and ``flow`` (px of flow plus px of disparity)."""
    from stereodeblur.sceneflow.model import SceneFlow

    def error(sf):
        return np.linalg.norm(sf.flow() - flow, axis=-1) + np.abs(sf.disparity() - disparity)

    height, width = sceneflow.shape
    labels, best = sceneflow.labels, error(sceneflow)
    out = labels.copy()
    padded = np.pad(labels, RADIUS, mode="edge")
    for dy in range(2 * RADIUS + 1):
        for dx in range(2 * RADIUS + 1):
            shifted = padded[dy : dy + height, dx : dx + width]
            if np.array_equal(shifted, labels):
                continue
            candidate = SceneFlow(
                sceneflow.camera, shifted, sceneflow.normals, sceneflow.twists,
                sceneflow.occlusion, sceneflow.view,
            )  # fmt: skip
            e = error(candidate)
            better = e < best
            best[better], out[better] = e[better], shifted[better]
    return SceneFlow(
        sceneflow.camera, out, sceneflow.normals, sceneflow.twists, sceneflow.occlusion,
        sceneflow.view,
    )  # fmt: skip


def evaluate(work: Path, name: str, chosen=MOTIONS) -> dict:
    """PSNR and gt/mixed MSE of the ``chosen`` motions under both operators on scene ``name``."""
    from stereodeblur.evaluation.metrics import border_for, masked_mse, psnr
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import DeblurSettings, deblur_stereo_frame
    from stereodeblur.sceneflow.storage import load_sceneflow

    scene = open_scene(work / "scenes" / name)
    estimate = load_sceneflow(work / "cache" / name / "sceneflow.npz")
    sharp = scene.read_gt_sharp("left", 1)
    mixed = scene.read_gt_mixed("left", 1) > 0
    border = border_for(sharp.shape[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disparity, flow = scene.read_gt_disparity("left", 1), scene.read_gt_flow("left", 1)
        motions = {
            "estimated": lambda: estimate,
            "moved": lambda: estimate,
            "relabelled": lambda: relabelled(estimate, disparity, flow),
            "true": lambda: true_sceneflow(scene),
        }
        row = {"scene": name}
        for motion in chosen:
            sceneflow = motions[motion]()
            radius = DeblurSettings().relabel_radius if motion == "moved" else 0
            for dense in OPERATORS:
                settings = replace(DeblurSettings(), boundary_flow=dense, relabel_radius=radius)
                result = deblur_stereo_frame(
                    scene, 1, views=("left",), settings=settings, sceneflow=sceneflow
                ).frames["left"]
                row[motion, dense] = (
                    psnr(result.image, sharp, border=border),
                    1000 * masked_mse(result.image, sharp, mixed, border=border),
                )
    return row


def report(rows, *, command: str, minutes: float, chosen=MOTIONS) -> str:
    """The Markdown tables of ``rows`` (of the ``chosen`` motions)."""
    from stereodeblur.evaluation.paper_bench import scene_groups

    keys = [(m, d) for m in chosen for d in OPERATORS]
    head = " | ".join(f"{m}, {OPERATORS[d]}" for m, d in keys)
    lines = [
        "# Motion and boundary rows: the true motion's lead, taken apart",
        "",
        f"Command: `{command}`; {minutes:.1f} min (2 cores). Frame 1, left view, "
        "`bench paper`'s object scenes at 640x480; every setting the default's but the motion "
        "and `boundary_flow` (dense-flow rows: the default; occlusion-aware: "
        "`--no-boundary-flow`). `moved`: the estimate with its boundaries moved to the dense "
        "flow's (the default `--relabel-radius`; every other motion with `--relabel-radius 0`). "
        "`relabelled` is an oracle (the estimate's planes and motions, "
        f"each pixel given the segment within {RADIUS} px nearest the true disparity and "
        "flow).",
    ]
    groups = scene_groups([r["scene"] for r in rows])
    by_name = {r["scene"]: r for r in rows}
    for metric, title in ((0, "PSNR (dB)"), (1, "gt/mixed MSE x 1000")):
        lines += ["", f"## {title}", "", f"| scene | {head} |", "|---" * (len(keys) + 1) + "|"]
        for label, names in groups:
            group = [by_name[n] for n in names]
            for r in group:
                cells = " | ".join(f"{r[k][metric]:.2f}" for k in keys)
                lines.append(f"| {r['scene']} | {cells} |")
            means = " | ".join(f"**{np.mean([r[k][metric] for r in group]):.2f}**" for k in keys)
            lines.append(f"| mean, {label} | {means} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, required=True, help="bench paper's size folder")
    parser.add_argument("--jobs", type=int, default=1, help="scenes at once (default: 1)")
    parser.add_argument("--output", type=Path, help="also write the report here")
    parser.add_argument(
        "--motions", default=",".join(MOTIONS), help="comma-separated (default: all of them)"
    )
    args = parser.parse_args(argv)
    chosen = tuple(m for m in MOTIONS if m in args.motions.split(","))
    if not chosen or set(args.motions.split(",")) - set(MOTIONS):
        print(
            f"error: --motions {args.motions}: expected some of {','.join(MOTIONS)}",
            file=sys.stderr,
        )
        return 2
    from stereodeblur.evaluation.motion_cache import is_stored
    from stereodeblur.evaluation.paper_bench import default_scenes, scene_kind
    from stereodeblur.io.outputs import atomic_write_text
    from stereodeblur.settings import DeblurSettings

    names = [n for n in default_scenes() if scene_kind(n) == "object"]
    settings = DeblurSettings()
    missing = [n for n in names if not is_stored(args.work / "cache" / n, "sceneflow", settings)]
    if missing:
        print(
            f"error: {args.work}: no scene flow of {', '.join(missing)} stored with today's "
            "estimator settings; run stereodeblur bench paper --work on it first",
            file=sys.stderr,
        )
        return 2
    start = time.perf_counter()
    from stereodeblur.clip.worker import watch_parent

    workers = max(1, args.jobs)  # they end with this process (a killed run leaves none)
    with ProcessPoolExecutor(workers, initializer=watch_parent, initargs=(os.getpid(),)) as pool:
        rows = list(pool.map(evaluate, [args.work] * len(names), names, [chosen] * len(names)))
    command = "python benchmarks/boundary_rows.py " + " ".join(argv or sys.argv[1:])
    minutes = (time.perf_counter() - start) / 60
    text = report(rows, command=command, minutes=minutes, chosen=chosen)
    print(text, end="")
    if args.output:
        atomic_write_text(args.output, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
