"""What each observation contributes: ``bench paper``'s scenes, one run.

Run from the repository root::

    python benchmarks/paper_observations.py --work /tmp/paperbench \
        --output benchmarks/results/paper_observations_640x480.md

Frame 1 (left) of every scene of ``stereodeblur bench paper`` (the same work folder layout, so a
``bench paper`` run's renders, scene flows and columns are reused), deblurred with the estimated
scene flow by "ours" (``bench paper``'s "ours (full)" column) from the view's own blurred frame
only, + the other view, + the neighbouring frames, and all three
(``DeblurSettings.observations``), next to the monocular path with the same defaults and the
initial optical flow at the paper's settings; and ours from the single observation and from all
with the paper's 10 IRLS x 25 CG iterations (:data:`PAPER_COUNTS`) instead of the default
counts. Writes PSNR and the mean squared error in the gt/mixed pixels per scene and the means
per scene group to ``--output``.
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
from stereodeblur.settings import OBSERVATIONS, PAPER_CG, PAPER_IRLS, DeblurSettings

TITLES = {
    "single": "same view only",
    "other-view": "+ other view",
    "neighbours": "+ frames t-1, t+1",
    "all": "+ both",
}


PAPER_COUNTS = (PAPER_IRLS, PAPER_CG)
"""``--irls 10 --cg 25``: the paper's iteration counts, beside the default ones."""


def columns(observations=OBSERVATIONS, baselines: bool = True):
    """The monocular and initial-flow columns (unless not ``baselines``), then ours with each
    set of ``observations``."""
    base = {c.key: c for c in COLUMNS}
    out = [base["initial-flow"], base["monocular"]] if baselines else []
    for name in observations:
        title = f"ours, {TITLES[name]}"
        out.append(replace(base["ours-full"], key=f"ours-{name}", title=title, observations=name))
    return out


def paper_count_columns():
    """Ours from the single observation and from all, with :data:`PAPER_COUNTS`."""
    ours = next(c for c in COLUMNS if c.key == "ours-full")
    tag = "x".join(map(str, PAPER_COUNTS))
    return [
        replace(
            ours, key=f"ours-{name}-{tag}", title=f"ours, {TITLES[name]}, {tag}", observations=name
        )
        for name in ("single", "all")
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument(
        "--work", default="/tmp/paperbench", help="bench paper's work folder (default %(default)s)"
    )
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scenes", default=None, help="comma-separated (default: all)")
    parser.add_argument(
        "--observations",
        default=",".join(OBSERVATIONS),
        help="ours' columns, comma-separated (default: all of them)",
    )
    parser.add_argument(
        "--no-paper-counts", action="store_true", help="without the 10 x 25 columns"
    )
    parser.add_argument(
        "--no-baselines",
        action="store_true",
        help="without the initial-flow and monocular columns (no scene flow in them)",
    )
    parser.add_argument("--output", default=None, help="Markdown (default: print only)")
    args = parser.parse_args(argv)
    observations = tuple(o for o in args.observations.split(",") if o)
    if not observations or set(observations) - set(OBSERVATIONS):
        parser.error(f"--observations must name some of {', '.join(OBSERVATIONS)}")
    size = tuple(int(v) for v in args.size.lower().split("x"))
    folder = Path(args.work) / args.size
    names = args.scenes.split(",") if args.scenes else paper_bench.default_scenes()
    chosen = columns(observations, baselines=not args.no_baselines)
    paper = [] if args.no_paper_counts else paper_count_columns()
    start = time.perf_counter()
    paper_bench.render_missing(folder / "scenes", names, size)
    rows = {}
    iterations = DeblurSettings(num_irls=PAPER_COUNTS[0], num_cg=PAPER_COUNTS[1])
    for name in names:
        root, cache = folder / "scenes" / name, folder / "cache" / name
        row = paper_bench.evaluate_scene(root, cache, chosen, DeblurSettings())
        rows[name] = (
            row.columns | paper_bench.evaluate_scene(root, cache, paper, iterations).columns
        )
        print(
            name, " ".join(f"{rows[name][c.key]['psnr']:.2f}" for c in chosen + paper), flush=True
        )
    chosen += paper
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
