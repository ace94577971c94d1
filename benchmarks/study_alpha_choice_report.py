"""Rules that choose alpha from the solutions of ``study_alpha_choice.py`` (train split).

Run from the repository root after the study::

    python benchmarks/study_alpha_choice_report.py

For each motion source and boundary handling, the report gives how far each rule's choice
lies below the best grid alpha (mean, worst) and below the paper's settings (alpha 0.001,
no boundary handling). These are the checks of issue 12. The rules see only what a run
has: the solutions at every grid alpha, both views' disparities and blur operators, and
the blurred frames. PSNR uses gt/sharp only to score the choice.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402
from study_alpha_choice import GRID, HANDLINGS, SOURCES  # noqa: E402

from stereodeblur.pipeline.alpha import candidates, choose, searched, warp_to_other  # noqa: E402

PAPER_INDEX = GRID.index(1e-3)


def quasi_optimal(d: dict) -> int:
    """The larger alpha of the consecutive pair whose solutions differ least (RMS)."""
    images = d["images"][: len(GRID)]
    steps = np.sqrt(((images[1:] - images[:-1]) ** 2).reshape(len(GRID) - 1, -1).mean(axis=1))
    return int(np.argmin(steps)) + 1


def stereo_consistent(d: dict) -> int:
    """The alpha whose left and right solutions agree best through the right disparity
    (mean of the 90 % smallest squared differences)."""
    right = d["right"]
    left = np.stack([warp_to_other(x, right["disparity"], 1) for x in d["images"][: len(GRID)]])
    border = protocol.border_of(left.shape[2])
    inner = (slice(None), slice(border, -border), slice(border, -border))
    diff = ((left - right["images"])[inner] ** 2).mean(axis=-1).reshape(len(GRID), -1)
    diff = np.sort(diff, axis=1)[:, : int(0.9 * diff.shape[1])]
    return int(np.argmin(diff.mean(axis=1)))


def cross_view(d: dict, *, keep: str = "0.9", both: bool = False, step: int = 0) -> int:
    """The alpha whose solution best predicts the other view's blurred frame through the
    disparity and that view's blur operator (``both``: the two directions summed), ``step``
    grid steps up."""
    costs = np.array(d["cross"]["left_to_right"][keep])
    if both:
        costs = costs + np.array(d["cross"]["right_to_left"][keep])
    return min(int(np.argmin(costs)) + step, len(GRID) - 1)


def discrepancy(d: dict, *, keep: str = "0.9") -> int:
    """The largest alpha whose own residual is at most the cross-view prediction error
    (both views averaged): the discrepancy principle with the error level measured."""
    cross = {k: np.array(d["cross"][k][keep]) for k in d["cross"]}
    error = (cross["left_to_right"] + cross["right_to_left"]).min() / 2
    own = (cross["left_own"] + cross["right_own"]) / 2
    fits = np.nonzero(own <= error)[0]
    return int(fits.max()) if fits.size else 0


def held_out(d: dict, *, keep: str = "0.9") -> int:
    """``alpha='held-out'`` (:mod:`stereodeblur.pipeline.alpha`) on the right view's
    prediction errors (index ``len(GRID)`` is ``'auto'``). The study has the errors at the
    grid alphas only; the one at ``'auto'`` is interpolated in log alpha (the pipeline
    computes it)."""
    costs = np.log(d["cross"]["left_to_right"][keep])
    auto = float(d["alphas"][len(GRID)])
    indices = [len(GRID)] + [GRID.index(a) for a in candidates("held-out", auto)[1:]]
    at_auto = np.interp(np.log10(auto), np.log10(GRID), costs)
    errors, alphas = [], []
    for i in indices:
        errors.append(at_auto if i == len(GRID) else costs[i])
        alphas.append(auto if i == len(GRID) else GRID[i])
        if searched("held-out", errors, alphas):
            break
    return indices[choose(errors, "held-out", alphas)]


RULES = {
    "auto (today)": None,
    "oracle (best grid alpha; not a rule)": lambda d: int(np.argmax(d["psnr"][: len(GRID)])),
    "fixed 0.001": lambda d: PAPER_INDEX,
    "quasi-optimality": quasi_optimal,
    "stereo consistency of the solutions": stereo_consistent,
    "cross-view prediction, left to right, 90 %": cross_view,
    "cross-view prediction, left to right, all": lambda d: cross_view(d, keep="1"),
    "cross-view prediction, both ways, 90 %": lambda d: cross_view(d, both=True),
    "cross-view prediction, both ways, all": lambda d: cross_view(d, keep="1", both=True),
    "discrepancy at the cross-view error": discrepancy,
    "cross-view prediction, both ways, 90 %, one step up": lambda d: cross_view(
        d, both=True, step=1
    ),
    "alpha='cross-view': left to right, 90 %, one step up": lambda d: cross_view(d, step=1),
    "alpha='held-out': up from auto while the prediction improves, left to right, 90 %": held_out,
}


def load(work: Path, handlings=HANDLINGS, paper: Path | None = None) -> dict:
    """Per scene, per (source, handling): solutions, PSNR per alpha, right view, costs; per
    source the paper's PSNR (``paper``: the calibration protocol's results folder, whose
    ``paper`` column has the paper's iteration counts; else handling ``none`` at 0.001)."""
    from stereodeblur.evaluation.metrics import psnr

    scenes = {}
    for folder in sorted(p for p in work.iterdir() if p.is_dir()):
        runs = {}
        for source in SOURCES:
            for handling in handlings:
                stem = folder / f"{source}_{handling}"
                paths = [Path(f"{stem}.npz"), Path(f"{stem}_right.npz"), Path(f"{stem}_cross.json")]
                if not all(p.is_file() for p in paths):
                    continue
                data = dict(np.load(paths[0]))
                border = protocol.border_of(data["truth"].shape[1])
                data["psnr"] = np.array(
                    [psnr(image, data["truth"], border=border) for image in data["images"]]
                )
                data["right"] = dict(np.load(paths[1]))
                data["cross"] = json.loads(paths[2].read_text())
                runs[(source, handling)] = data
            if paper is not None:
                column = json.loads((paper / folder.name / f"{source}_paper.json").read_text())
                runs[(source, "paper")] = column["psnr"]
            elif (source, "none") in runs:
                runs[(source, "paper")] = runs[(source, "none")]["psnr"][PAPER_INDEX]
        if len(runs) == len(SOURCES) * (len(handlings) + 1):
            scenes[folder.name] = runs
    return scenes


def table(scenes: dict, handlings=HANDLINGS) -> str:
    lines = [
        "| rule | source | handling | mean below best | worst below best "
        "| worst below paper | scenes > 0.5 below paper | checks |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, rule in RULES.items():
        for source in SOURCES:
            for handling in handlings:
                below_best, below_paper = [], []
                for scene, runs in scenes.items():
                    d = runs[(source, handling)]
                    got = d["psnr"][-1] if rule is None else d["psnr"][rule(d)]
                    paper = runs[(source, "paper")]
                    below_best.append((d["psnr"][: len(GRID)].max() - got, scene))
                    below_paper.append((paper - got, scene))
                mean = float(np.mean([b for b, _ in below_best]))
                worst, under = max(below_best), max(below_paper)
                count = sum(b > protocol.BELOW_PAPER for b, _ in below_paper)
                checks = sum(
                    bool(passed)
                    for passed in (
                        mean <= protocol.WITHIN_BEST_MEAN,
                        worst[0] <= protocol.WITHIN_BEST_EACH,
                        under[0] <= protocol.BELOW_PAPER,
                    )
                )
                lines.append(
                    f"| {name} | {source} | {handling} | {mean:+.2f} | {worst[0]:+.2f} "
                    f"({worst[1]}) | {under[0]:+.2f} ({under[1]}) | {count} | {checks}/3 |"
                )
    return "\n".join(lines)


def curves(scenes: dict, handling: str = "none") -> str:
    """Per scene and source: PSNR per alpha and the both-ways cost."""
    head = ", ".join(f"{a:g}" for a in GRID)
    lines = [
        f"Alphas: {head}.",
        "",
        "| scene | source | PSNR per alpha (dB) | best alpha | both-ways cost / its minimum |",
        "|---|---|---|---|---|",
    ]
    for scene, runs in scenes.items():
        for source in SOURCES:
            d = runs[(source, handling)]
            costs = np.add(d["cross"]["left_to_right"]["0.9"], d["cross"]["right_to_left"]["0.9"])
            psnrs = " ".join(f"{p:.2f}" for p in d["psnr"][: len(GRID)])
            ratio = " ".join(f"{c / costs.min():.3f}" for c in costs)
            best = GRID[int(np.argmax(d["psnr"][: len(GRID)]))]
            lines.append(f"| {scene} | {source} | {psnrs} | {best:g} | {ratio} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--work", default="/tmp/calib/work/320x240/alpha_choice")
    parser.add_argument("--handlings", default=",".join(HANDLINGS), help="(default: all)")
    parser.add_argument(
        "--paper", default=None, help="calibration protocol results folder with the paper column"
    )
    parser.add_argument("--output", default=None, help="markdown file (default: print only)")
    args = parser.parse_args(argv)
    handlings = tuple(args.handlings.split(","))
    scenes = load(Path(args.work), handlings, Path(args.paper) if args.paper else None)
    curve_handling = "none" if "none" in handlings else handlings[0]
    text = "\n\n".join(
        [
            f"{len(scenes)} train scenes: {', '.join(scenes)}",
            table(scenes, handlings),
            f"Per scene, handling {curve_handling}:",
            curves(scenes, curve_handling),
        ]
    )
    if args.output:
        from stereodeblur.io.outputs import atomic_write_text

        atomic_write_text(Path(args.output), text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
