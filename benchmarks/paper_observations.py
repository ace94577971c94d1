"""What each observation contributes (issue 13): ``bench paper``'s scenes, one run.

Run from the repository root::

    python benchmarks/paper_observations.py --work /tmp/paperbench \
        --output benchmarks/results/paper_observations_640x480.md

Frame 1 (left) of every scene of ``stereodeblur bench paper`` (the same work folder layout,
so a ``bench paper`` run's renders, scene flows and columns are reused), deblurred with the
estimated scene flow by "ours" (gated boundaries, auto alpha) from the view's own blurred
frame only, + the other view, + the neighbouring frames, and all three
(``DeblurSettings.observations``), next to the monocular path with the same defaults and
the initial optical flow at the paper's settings; and ours from the single observation and
from all with 6 IRLS x 10 CG iterations instead of the paper's 10 x 25 (:data:`FEWER`).
Writes PSNR and the mean squared error in the gt/mixed pixels per scene and the means per
scene group to ``--output``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.paper_columns import COLUMNS
from stereodeblur.io.outputs import atomic_write_text
from stereodeblur.settings import OBSERVATIONS, DeblurSettings

TITLES = {
    "single": "same view only",
    "other-view": "+ other view",
    "neighbours": "+ frames t-1, t+1",
    "all": "+ both",
}


FEWER = (6, 10)
"""``--irls 6 --cg 10``: the faster setting, measured beside the paper's 10 x 25."""


def columns():
    """The monocular and initial-flow columns, then ours with each set of observations."""
    base = {c.key: c for c in COLUMNS}
    out = [base["initial-flow"], base["monocular"]]
    for name in OBSERVATIONS:
        title = f"ours, {TITLES[name]}"
        out.append(replace(base["ours-full"], key=f"ours-{name}", title=title, observations=name))
    return out


def fewer_columns():
    """Ours from the single observation and from all, with :data:`FEWER` iterations."""
    ours = next(c for c in COLUMNS if c.key == "ours-full")
    tag = "x".join(map(str, FEWER))
    return [
        replace(
            ours, key=f"ours-{name}-{tag}", title=f"ours, {TITLES[name]}, {tag}", observations=name
        )
        for name in ("single", "all")
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--work", default="/tmp/paperbench", help="bench paper's work folder")
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scenes", default=None, help="comma-separated (default: all)")
    parser.add_argument("--output", default=None, help="Markdown (default: print only)")
    args = parser.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    folder = Path(args.work) / args.size
    names = args.scenes.split(",") if args.scenes else paper_bench.default_scenes()
    chosen, fewer = columns(), fewer_columns()
    start = time.perf_counter()
    paper_bench.render_missing(folder / "scenes", names, size)
    rows = {}
    for name in names:
        root, cache = folder / "scenes" / name, folder / "cache" / name
        row = paper_bench.evaluate_scene(root, cache, chosen, DeblurSettings())
        iterations = DeblurSettings(num_irls=FEWER[0], num_cg=FEWER[1])
        rows[name] = (
            row.columns | paper_bench.evaluate_scene(root, cache, fewer, iterations).columns
        )
        print(
            name, " ".join(f"{rows[name][c.key]['psnr']:.2f}" for c in chosen + fewer), flush=True
        )
    chosen += fewer
    minutes = (time.perf_counter() - start) / 60
    print("\n".join(report(rows, chosen, minutes, sys.argv[1:])))
    if args.output:
        atomic_write_text(
            Path(args.output), "\n".join(report(rows, chosen, minutes, sys.argv[1:])) + "\n"
        )
    return 0


def _cell(psnrs, mses) -> str:
    mse = np.mean(mses)
    return f"{np.mean(psnrs):.2f} / " + ("–" if np.isnan(mse) else f"{1000 * mse:.2f}")


def report(rows, chosen, minutes, argv) -> list[str]:
    head = " | ".join(c.title for c in chosen)
    seconds = {
        c.key: np.median([values[c.key]["seconds"] for values in rows.values()]) for c in chosen
    }
    lines = [
        "# What each observation contributes: bench paper's scenes",
        "",
        f"Command: `python benchmarks/paper_observations.py {' '.join(argv)}`; {minutes:.1f} min "
        "(cached columns reused). Frame 1, left view, estimated scene flow. Per cell: PSNR dB / "
        "mean squared error in the gt/mixed pixels x 1000 (2.5 % border).",
        "",
        f"| scene | {head} |",
        "|---|" + "---|" * len(chosen),
    ]
    for name, values in rows.items():
        cells = [_cell([values[c.key]["psnr"]], [values[c.key]["mixed_mse"]]) for c in chosen]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"| mean | {head} |", "|---|" + "---|" * len(chosen)]
    for label, names in paper_bench.scene_groups(rows):
        psnrs = [[rows[n][c.key]["psnr"] for n in names] for c in chosen]
        mses = [[rows[n][c.key]["mixed_mse"] for n in names] for c in chosen]
        cells = [_cell(p, m) for p, m in zip(psnrs, mses, strict=True)]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    cells = [f"{seconds[c.key]:.1f}" for c in chosen]
    lines.append("| median seconds per frame (one view, 2 cores) | " + " | ".join(cells) + " |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
