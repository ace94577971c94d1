"""How far the alpha rule and the motion could take the default on the semi-real KITTI clips.

A study (issue 65's line "+0.5 dB over the monocular path"): on the clips that
``kitti_semireal.py`` renders into ``--work``, frame 1 of the left view is deblurred by the
default ("ours (full)"), the monocular path with the same machinery and the default given the
true motion, each at its own alpha rule and at every alpha of ``--alphas`` (a fixed alpha: the
whole grid). The best alpha of each column per clip is an oracle: what a perfect alpha rule
could give. Run from the repository root after ``kitti_semireal.py``::

    python benchmarks/study_semireal_bound.py --work /tmp/kitti/semireal
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

ALPHAS = (2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3)
CLIPS = ("000002", "000002_noisy", "000003", "000003_noisy", "000007", "000007_noisy")


def run(work: Path, clip: str, key: str, alpha, cache: Path) -> float:
    """PSNR of ``key``'s column at ``alpha`` (None: its own rule) on ``clip``, cached."""
    from stereodeblur.evaluation.motion_cache import cached_motion
    from stereodeblur.evaluation.paper_bench import FRAME, run_column
    from stereodeblur.evaluation.paper_columns import COLUMNS, TRUE_MOTION
    from stereodeblur.io.scene import open_scene
    from stereodeblur.settings import DeblurSettings

    path = cache / f"{clip}.{key}.{'rule' if alpha is None else f'{alpha:g}'}.json"
    if path.is_file():
        return json.loads(path.read_text())["psnr"]
    column = next(c for c in (*COLUMNS, TRUE_MOTION) if c.key == key)
    if alpha is not None:
        column = replace(column, alpha=alpha)
    scene = open_scene(work / clip)
    settings = DeblurSettings()
    motion, _, _ = cached_motion(scene, column.motion_source, settings, cache / f"{clip}.motion")
    truth = {
        "sharp": scene.read_gt_sharp("left", FRAME),
        "flow": scene.read_gt_flow("left", FRAME),
        "disparity": scene.read_gt_disparity("left", FRAME),
        "mixed": scene.read_gt_mixed("left", FRAME),
    }
    result, _ = run_column(scene, column, settings, motion, truth)
    cache.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"psnr": result.psnr, "alpha": result.alpha}))
    print(f"{clip} {key} alpha {alpha}: {result.psnr:.2f} dB", file=sys.stderr, flush=True)
    return result.psnr


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, required=True, help="kitti_semireal.py's --work")
    args = parser.parse_args(argv)
    cache = args.work / "bound"
    keys = ("ours-full", "monocular", "ours-true-motion")
    rows = {}
    for clip in CLIPS:
        rows[clip] = {
            key: {a: run(args.work, clip, key, a, cache) for a in (None, *ALPHAS)} for key in keys
        }
    head = (
        "| clip | "
        + " | ".join(f"{k} rule | {k} best alpha" for k in keys)
        + " | best ours - monocular rule |"
    )
    print(head)
    print("|---" * (2 * len(keys) + 2) + "|")
    sums = [0.0] * (2 * len(keys) + 1)
    for clip, row in rows.items():
        cells = []
        for key in keys:
            best = max(ALPHAS, key=lambda a, r=row[key]: r[a])
            cells += [row[key][None], row[key][best]]
        best_ours = max(cells[1], cells[5])
        cells.append(best_ours - row["monocular"][None])
        sums = [s + c for s, c in zip(sums, cells, strict=True)]
        text = " | ".join(f"{c:.2f}" for c in cells)
        print(f"| {clip} | {text} |")
    print("| **mean** | " + " | ".join(f"{s / len(rows):.2f}" for s in sums) + " |")
    for clip, row in rows.items():
        print(clip, {k: {str(a): round(v, 2) for a, v in row[k].items()} for k in keys})
    return 0


if __name__ == "__main__":
    sys.exit(main())
