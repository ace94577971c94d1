"""The IRLS and CG iteration counts as a defaults question (issue 12), train split only.

Run from the repository root::

    nice -n 10 python benchmarks/study_iterations.py --scenes 40 --jobs 2

Frame 1 of the left view of every scene of the calibration protocol's **train split only**
(seeds 0-999; other seeds are refused) is deblurred with the default settings at every
``(num_irls, num_cg)`` of ``--pairs`` (default :data:`PAIRS`), with the true (``gt``) and
the estimated (``sceneflow``) motion, and the monocular path at those of
``--monocular-pairs``. Fewer iterations stop the solver early, which also regularises: on
``bench paper``'s objects 6 x 10 beat the paper's 10 x 25 (issue 13's note). The report
writes, per motion source, each pair's mean and worst PSNR difference to the paper's
10 x 25 and its time. Columns are cached under ``--work`` as the protocol's are.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

from stereodeblur.settings import PAPER_CG, PAPER_IRLS  # noqa: E402

PAIRS = (
    (PAPER_IRLS, PAPER_CG),
    (10, 10),
    (8, 15),
    (8, 25),
    (6, 25),
    (5, 25),
    (4, 25),
    (3, 25),
    (6, 10),
    (4, 10),
)
"""``(num_irls, num_cg)``; the first is the paper's (the default until stop 22)."""
MONOCULAR_PAIRS = (PAIRS[0], (6, 25), (5, 25), (6, 10))
"""The monocular path's pairs; the first is the paper's."""


def pair_key(pair) -> str:
    return f"iters={pair[0]}x{pair[1]}"


def columns(pairs=PAIRS, monocular_pairs=MONOCULAR_PAIRS) -> list[protocol.Column]:
    out = [
        protocol.Column(pair_key(p), source, {"num_irls": p[0], "num_cg": p[1]})
        for source in protocol.MOTIONS
        for p in pairs
    ]
    return out + [
        protocol.Column("mono-" + pair_key(p), "initial-flow", {"num_irls": p[0], "num_cg": p[1]})
        for p in monocular_pairs
    ]


def run_scene(task) -> dict:
    """Every column on one training scene, reusing cached results."""
    from stereodeblur.io.scene import open_scene

    kind, seed, size, work, pairs, monocular_pairs = task
    if seed >= 1000:
        raise SystemExit(f"seed {seed} is in the test split: this study tunes on train only")
    work = Path(work)
    root = protocol.ensure_scene(kind, seed, size, work)
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    cache = work / "results" / root.name
    cache.mkdir(parents=True, exist_ok=True)
    motions, seconds = {}, {}
    out = {
        f"{c.motion_source}/{c.key}": protocol.cached_column(
            scene, c, truth, cache, motions, seconds
        )
        for c in columns(pairs, monocular_pairs)
    }
    spec = json.loads((root / "gt" / "family.json").read_text(encoding="utf-8"))
    return {"scene": root.name, "noise": spec["noise"], "columns": out}


def report(rows, command: str, minutes: float, pairs, monocular_pairs) -> str:
    lines = [
        f"# IRLS x CG iterations, train split, {len(rows)} scenes",
        "",
        f"Command: `{command}`; {minutes:.1f} min wall time (cached columns reused); code "
        f"{protocol.code_version()}. Train split only (seeds 0-999).",
        "",
        "PSNR difference to the paper's 10 x 25 (dB), per motion source: mean over all "
        "scenes, over the noiseless and the noisy ones, worst scene; median seconds per solve.",
        "",
        "| motion | iterations | mean | noiseless | noisy | worst | best | seconds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    noiseless = np.array([r["noise"] == 0 for r in rows])
    sources = [(s, pairs, "") for s in protocol.MOTIONS]
    sources.append(("initial-flow", monocular_pairs, "mono-"))
    for source, grid, prefix in sources:
        base = np.array(
            [r["columns"][f"{source}/{prefix}{pair_key(grid[0])}"]["psnr"] for r in rows]
        )
        for pair in grid:
            key = f"{source}/{prefix}{pair_key(pair)}"
            value = np.array([r["columns"][key]["psnr"] for r in rows])
            seconds = np.median([r["columns"][key]["seconds"] for r in rows])
            d = value - base
            worst = int(np.argmin(d))
            means = f"{d.mean():+.2f} | {d[noiseless].mean():+.2f} | {d[~noiseless].mean():+.2f}"
            lines.append(
                f"| {source} | {pair[0]} x {pair[1]} | {means} | "
                f"{d[worst]:+.2f} ({rows[worst]['scene']}) | "
                f"{d.max():+.2f} | {seconds:.2f} |"
            )
    lines += ["", "## Per scene (PSNR, dB)", ""]
    keys = [f"{s}/{pair_key(p)}" for s in protocol.MOTIONS for p in pairs]
    keys += [f"initial-flow/mono-{pair_key(p)}" for p in monocular_pairs]
    lines.append("| scene | noise | " + " | ".join(keys) + " |")
    lines.append("|---|---|" + "---|" * len(keys))
    for r in rows:
        cells = " | ".join(f"{r['columns'][k]['psnr']:.2f}" for k in keys)
        lines.append(f"| {r['scene']} | {r['noise']:.3f} | {cells} |")
    return "\n".join(lines) + "\n"


def _pairs(text: str) -> tuple[tuple[int, int], ...]:
    return tuple(tuple(int(v) for v in item.split("x")) for item in text.split(","))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=40)
    parser.add_argument("--size", default="320x240")
    parser.add_argument(
        "--work", type=Path, default=Path(tempfile.gettempdir()) / "stereodeblur_calibration"
    )
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--pairs", default=None, help="IRLSxCG,... (default: PAIRS)")
    parser.add_argument(
        "--monocular-pairs", default=None, help="IRLSxCG,... (default: MONOCULAR_PAIRS)"
    )
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args(argv)
    pairs = _pairs(args.pairs) if args.pairs else PAIRS
    monocular_pairs = _pairs(args.monocular_pairs) if args.monocular_pairs else MONOCULAR_PAIRS
    if pairs[0] != PAIRS[0] or monocular_pairs[0] != PAIRS[0]:
        parser.error(f"the first pair must be the paper's {pair_key(PAIRS[0])}")
    output = args.output or Path(f"benchmarks/results/iterations_train_{args.size}.md")
    size = tuple(int(v) for v in args.size.split("x"))
    work = args.work / args.size
    tasks = [
        (kind, seed, size, str(work), pairs, monocular_pairs)
        for kind, seed in protocol.scene_list("train", args.scenes, protocol.KINDS)
    ]
    start = time.perf_counter()
    rows = protocol.run_all(run_scene, tasks, args.jobs)
    command = "python benchmarks/study_iterations.py " + " ".join(sys.argv[1:])
    text = report(rows, command, (time.perf_counter() - start) / 60, pairs, monocular_pairs)
    protocol.atomic_write_text(output, text)
    protocol.atomic_write_text(output.with_suffix(".json"), json.dumps(rows, indent=1))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
