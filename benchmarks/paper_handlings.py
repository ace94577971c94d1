"""``bench paper``'s scenes with other boundary handlings and alpha rules for "ours (full)".

Run from the repository root::

    python benchmarks/paper_handlings.py --work /tmp/paperbench \
        --variants gated:auto,gated:cross-view,adaptive:cross-view

Frame 1 (left) of every scene of ``stereodeblur bench paper`` (rendered into the same work
folder layout, so a ``bench paper`` run's renders, motions and columns are reused), deblurred
with the estimated scene flow by the initial optical flow column, "ours (full)" (the
defaults) and each ``HANDLING:ALPHA`` variant of "ours (full)". Writes a Markdown table of
PSNR per scene and the means per scene group to ``--output``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.paper_columns import COLUMNS, Column
from stereodeblur.io.outputs import atomic_write_text
from stereodeblur.settings import DeblurSettings


def variant(text: str) -> Column:
    handling, alpha = text.split(":")
    value = alpha if alpha in ("auto", "cross-view") else float(alpha)
    key = f"ours-{handling}-{alpha}"
    return Column(key, f"ours, {handling}, {alpha}", "sceneflow", "homography", handling, value)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--work", default="/tmp/paperbench", help="bench paper's work folder")
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--scenes", default=None, help="comma-separated (default: all)")
    parser.add_argument("--variants", default="gated:auto", help="HANDLING:ALPHA,...")
    parser.add_argument("--output", default=None, help="Markdown (default: print only)")
    args = parser.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    folder = Path(args.work) / args.size
    names = args.scenes.split(",") if args.scenes else paper_bench.default_scenes()
    columns = [c for c in COLUMNS if c.key in ("initial-flow", "ours-full")]
    columns += [variant(v) for v in args.variants.split(",")]
    start = time.perf_counter()
    paper_bench.render_missing(folder / "scenes", names, size)
    rows = {}
    for name in names:
        row = paper_bench.evaluate_scene(
            folder / "scenes" / name, folder / "cache" / name, columns, DeblurSettings()
        )
        rows[name] = row.columns
        print(name, " ".join(f"{row.columns[c.key]['psnr']:.2f}" for c in columns), flush=True)
    head = " | ".join(c.title for c in columns)
    lines = [
        f"# bench paper's scenes, {args.size}: boundary handlings and alpha rules",
        "",
        f"Command: `python benchmarks/paper_handlings.py {' '.join(sys.argv[1:])}`; "
        f"{(time.perf_counter() - start) / 60:.1f} min (cached columns reused). PSNR dB "
        "(alpha) of frame 1, left view, estimated scene flow; ours (full) = the defaults.",
        "",
        f"| scene | {head} |",
        "|---|" + "---|" * len(columns),
    ]
    for name, values in rows.items():
        cells = [f"{values[c.key]['psnr']:.2f} ({values[c.key]['alpha']:.2g})" for c in columns]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"| mean | {head} |", "|---|" + "---|" * len(columns)]
    for label, chosen in paper_bench.scene_groups(rows):
        means = [np.mean([rows[n][c.key]["psnr"] for n in chosen]) for c in columns]
        lines.append(f"| {label} | " + " | ".join(f"{m:.2f}" for m in means) + " |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        atomic_write_text(Path(args.output), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
