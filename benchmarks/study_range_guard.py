"""The range guard on the calibration scenes: where it acts and what it changes.

Run from the repository root::

    python benchmarks/study_range_guard.py --split train --scenes 40 --jobs 2
    python benchmarks/study_range_guard.py --split test --scenes 40 --jobs 2

For every scene of the split (``calibrate_defaults.py``'s family and street scenes, rendered
into ``--work`` if needed), three columns: the default with the true motion, the default with
the estimated scene flow, and the monocular path (initial optical flow, displacement kernels,
the same defaults). Each runs with the range guard (the default,
``DeblurSettings.range_guard``); where the guard acted, it runs once more without it, from the
same stored motion. Results are cached with ``calibrate_defaults.py``'s (the same files and
signatures). Output: a Markdown table (the scenes where the guard acted: its share of the
pixels, PSNR without and with it; per column the mean change and the worst) on stdout and in
``--output``, with a ``.json`` beside.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

COLUMNS = (("gt", "default"), ("sceneflow", "default"), ("initial-flow", "monocular"))
"""(motion source, column key) of the columns studied."""
OFF = {"range_guard": False}


def run_scene(task) -> dict:
    """The three columns on one scene, with the guard and, where it acted, without."""
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.io.scene import open_scene

    kind, seed, size, work = task
    work = Path(work)
    root = protocol.ensure_scene(kind, seed, size, work)
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    border = protocol.border_of(truth.shape[1])
    blurred = psnr(scene.read_frame("left", protocol.FRAME), truth, border=border)
    cache = work / "results" / root.name
    cache.mkdir(parents=True, exist_ok=True)
    motions, seconds, out = {}, {}, {}
    for source, key in COLUMNS:
        on = protocol.cached_column(
            scene, protocol.Column(key, source), truth, cache, motions, seconds
        )
        row = {"on": on["psnr"], "off": on["psnr"], "unexplained": on.get("unexplained", 0.0)}
        if row["unexplained"] > 0:
            off = protocol.Column(f"{key}-no-range-guard", source, dict(OFF))
            row["off"] = protocol.cached_column(scene, off, truth, cache, motions, seconds)["psnr"]
        out[f"{source}/{key}"] = row
    return {"scene": root.name, "blurred": blurred, "columns": out}


def report(rows, args, seconds: float) -> str:
    """The Markdown report of :func:`run_scene`'s rows."""
    lines = [
        f"# The range guard, {args.split} split, {len(rows)} scenes, {args.size}",
        "",
        f"Command: `python benchmarks/study_range_guard.py --split {args.split} --scenes "
        f"{args.scenes} --size {args.size} --jobs {args.jobs} --work {args.work}`; "
        f"{seconds / 60:.1f} min. "
        f"Code: {protocol.code_version()}.",
        "",
        "Where the guard acted (share of the pixels it deblurred with no motion; PSNR dB "
        "without / with it):",
        "",
        "| scene | blurred | " + " | ".join(f"{s}/{k}" for s, k in COLUMNS) + " |",
        "|---|---:|" + "---:|" * len(COLUMNS),
    ]
    for row in rows:
        cells = row["columns"]
        if not any(c["unexplained"] > 0 for c in cells.values()):
            continue
        text = []
        for source, key in COLUMNS:
            c = cells[f"{source}/{key}"]
            text.append(
                "-"
                if c["unexplained"] == 0
                else f"{c['unexplained']:.1%}: {c['off']:.2f} -> {c['on']:.2f}"
            )
        lines.append(f"| {row['scene']} | {row['blurred']:.2f} | " + " | ".join(text) + " |")
    lines += ["", "| column | acted on | mean change (dB) | worst change (dB) | best change (dB) |"]
    lines.append("|---|---:|---:|---:|---:|")
    for source, key in COLUMNS:
        name = f"{source}/{key}"
        changes = [r["columns"][name]["on"] - r["columns"][name]["off"] for r in rows]
        acted = sum(r["columns"][name]["unexplained"] > 0 for r in rows)
        lines.append(
            f"| {name} | {acted} of {len(rows)} | {sum(changes) / len(changes):+.3f} | "
            f"{min(changes):+.2f} | {max(changes):+.2f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", choices=("train", "test"), default="train")
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--scenes", type=int, default=40)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument(
        "--work",
        default=str(Path(tempfile.gettempdir()) / "stereodeblur_calibration"),
        help="calibrate_defaults.py's cache folder (the same default)",
    )
    parser.add_argument("--output", default=None, help="markdown output (and .json beside)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    work = Path(args.work) / args.size
    tasks = [
        (kind, seed, (width, height), str(work))
        for kind, seed in protocol.scene_list(args.split, args.scenes, protocol.KINDS)
    ]
    start = time.perf_counter()
    rows = protocol.run_all(run_scene, tasks, args.jobs)
    text = report(rows, args, time.perf_counter() - start)
    output = Path(args.output or f"benchmarks/results/range_guard_{args.split}_{args.size}.md")
    protocol.atomic_write_text(output, text)
    protocol.atomic_write_text(output.with_suffix(".json"), json.dumps(rows, indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
