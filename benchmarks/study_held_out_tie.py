"""How ``--alpha held-out`` breaks ties between near-equal predictors (issue 12, stop 37).

Run from the repository root after ``calibrate_defaults.py`` has computed the grid columns of
the same split and size (their PSNRs score the choices)::

    python benchmarks/study_held_out_tie.py --split train --scenes 40 --size 320x240

For every scene and motion source, frame 1 of the left view is deblurred with the default
settings, and the choice solves every candidate alpha (no early stop) and records its
prediction error (:func:`stereodeblur.pipeline.alpha.prediction_error`, or with the true motion
:func:`~stereodeblur.pipeline.alpha.observed_error`) and PSNR. Each tie share ``t`` then
replays the choice of :mod:`stereodeblur.pipeline.alpha` with a tie share ``t`` on these
errors (``t = 0``: the best predictor, the rule before stop 37), and (rows "less noise", stop
42) with ``t`` taken of the least error less the noise's expected part (:func:`noise_part`).
A choice is scored with the default's own PSNR where it is the recorded one, else with the
PSNR of the grid column ``alpha=A`` of ``calibrate_defaults.py``, else (an alpha off the grid,
the noise rule's) with the candidate's PSNR corrected by the default's difference to its own
candidate. The curves are cached under ``--work`` (``results/<scene>/<motion>_curve.json``;
delete them after a change to the pipeline).
Written: ``--output`` (markdown).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

from stereodeblur.io.outputs import atomic_write_text  # noqa: E402

TIES = (0.0, 0.005, 0.01, 0.02, 0.05)
VARIANTS = (
    *((f"{t:g}", t, False) for t in TIES),
    *((f"{t:g} less noise", t, True) for t in TIES[1:]),
)
"""``(label, tie share, of the error less the noise's part)``: the shares replayed."""


def record_curve(scene, source: str, cache: Path) -> dict:
    """The default's candidates of frame 1, left view, each ``(alpha, error, psnr)``, and the
    default's alpha and PSNR; cached in ``cache``."""
    import stereodeblur.pipeline.frame as frame
    from stereodeblur.deconv.noise import estimate_noise_sigma
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.evaluation.motion_cache import cached_motion

    path = cache / f"{source}_curve.json"
    if path.exists():
        return json.loads(path.read_text())
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    border = protocol.border_of(truth.shape[1])
    curve, last = [], {}
    solve, searched = frame.guarded_solve, frame.searched
    predicted, observed = frame.prediction_error, frame.observed_error

    def guarded(blurred, operator, terms, *args, **kwargs):
        result, unexplained = solve(blurred, operator, terms, *args, **kwargs)
        last.update(alpha=float(terms.alpha), psnr=psnr(result.image, truth, border=border))
        return result, unexplained

    def scored(score):
        def wrapped(image, other, *, border):
            error = score(image, other, border=border)
            curve.append((last["alpha"], error, last["psnr"]))
            return error

        return wrapped

    motion, _, _ = cached_motion(scene, source, protocol.unmoved(source), cache)
    try:
        frame.guarded_solve, frame.searched = guarded, lambda rule, errors: False
        frame.prediction_error, frame.observed_error = scored(predicted), scored(observed)
        result = protocol.run_column(scene, protocol.Column("default", source), motion, truth)
    finally:
        frame.guarded_solve, frame.searched = solve, searched
        frame.prediction_error, frame.observed_error = predicted, observed
    upwards = [curve[0]]
    for entry in curve[1:]:  # the candidates upwards; the gate's errors below the floor follow
        if entry[0] <= upwards[-1][0]:
            break
        upwards.append(entry)
    blurred = scene.read_frame("left", protocol.FRAME)
    out = {
        "curve": upwards,
        "alpha": result["alpha"],
        "psnr": result["psnr"],
        "sigma": estimate_noise_sigma(blurred),
        "channels": 1 if blurred.ndim == 2 else blurred.shape[2],
        "observed": source == "gt",
    }
    atomic_write_text(path, json.dumps(out))
    return out


def noise_part(record: dict) -> float:
    """The noise's expected share of ``record``'s prediction errors: ``sigma^2`` times the
    mean of the smallest :data:`~stereodeblur.settings.CROSS_VIEW_KEEP` of a chi-square over the
    channels (the trimmed error), or ``sigma^2`` for the untrimmed error of the true motion."""
    from scipy.stats import chi2

    from stereodeblur.settings import CROSS_VIEW_KEEP

    if record["observed"]:
        return record["sigma"] ** 2
    channels = record["channels"]  # E[X; X < q] = c F_{c+2}(q) for X ~ chi2(c)
    kept = chi2.cdf(chi2.ppf(CROSS_VIEW_KEEP, channels), channels + 2) / CROSS_VIEW_KEEP
    return record["sigma"] ** 2 * float(kept)


def replay(record: dict, tie: float, less_noise: bool = False) -> int:
    """Index of the candidate ``'held-out'`` chooses with ``HELD_OUT_TIE = tie``; where
    ``less_noise``, on the errors less :func:`noise_part` (at most the least error), so that
    the share is of the least error less the noise's part."""
    from stereodeblur.pipeline import alpha

    errors, alphas = [], []
    for candidate, error, _ in record["curve"]:
        errors.append(error)
        alphas.append(candidate)
        if alpha.searched("held-out", errors, alphas):
            break
    noise = min(noise_part(record), min(errors)) if less_noise else 0.0
    saved, alpha.HELD_OUT_TIE = alpha.HELD_OUT_TIE, tie
    try:
        return alpha.choose([e - noise for e in errors], "held-out", alphas)
    finally:
        alpha.HELD_OUT_TIE = saved


def score(record: dict, index: int, grid: dict) -> float:
    """PSNR of candidate ``index`` of ``record`` as the default would give it."""
    curve = record["curve"]
    alphas = [a for a, _, _ in curve]
    same = [k for k, a in enumerate(alphas) if np.isclose(a, record["alpha"], rtol=1e-6)]
    recorded = same[0] if same else 0  # below the floor: the gate went down from the floor
    if index == recorded:
        return record["psnr"]
    on_grid = [a for a in grid if np.isclose(a, alphas[index], rtol=1e-6)]
    if on_grid:
        return grid[on_grid[0]]
    return curve[index][2] + record["psnr"] - curve[recorded][2]


def grid_psnr(scene, source: str, cache: Path) -> tuple[dict, float]:
    """The grid columns' PSNR by alpha and the paper column's, from ``calibrate_defaults.py``'s
    cache (computed there if missing or stale)."""
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    motions, seconds = {}, {}

    def column(key: str, overrides: dict) -> float:
        column = protocol.Column(key, source, overrides)
        return protocol.cached_column(scene, column, truth, cache, motions, seconds)["psnr"]

    grid = {a: column(protocol.alpha_key(a), {"alpha": a}) for a in protocol.ALPHAS}
    return grid, column("paper", dict(protocol.PAPER))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--split", choices=("train", "test"), default="train")
    parser.add_argument("--scenes", type=int, default=40)
    parser.add_argument("--skip", type=int, default=0)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--work", type=Path, default=Path("/tmp/calib/work"))
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args(argv)
    from stereodeblur.io.scene import open_scene

    work = args.work / args.size
    rows = {v[0]: {s: [] for s in protocol.MOTIONS} for v in VARIANTS}
    changes = []
    for kind, seed in protocol.scene_list(args.split, args.scenes, protocol.KINDS, args.skip):
        name = f"{kind}_{seed:04d}"
        scene = open_scene(work / "scenes" / name)
        for source in protocol.MOTIONS:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                record = record_curve(scene, source, work / "results" / name)
            grid, paper = grid_psnr(scene, source, work / "results" / name)
            best = max(grid.values())
            picks = {label: replay(record, tie, less) for label, tie, less in VARIANTS}
            for label, index in picks.items():
                value = score(record, index, grid)
                rows[label][source].append((best - value, paper - value, name))
            if len({record["curve"][i][0] for i in picks.values()}) > 1:
                changes.append((name, source, record, picks, grid, best))
            print(f"{name} {source}", flush=True)
    lines = [
        f"# `held-out`'s tie share: {args.split} split, {args.size}, {args.scenes} scenes",
        "",
        f"Command: `python benchmarks/study_held_out_tie.py --split {args.split} --scenes "
        f"{args.scenes} --skip {args.skip} --size {args.size}`.",
        "",
        "| tie | motion | mean gap to the best grid alpha | worst | scenes > 1.5 dB | "
        "worst below the paper |",
        "|---|---|---|---|---|---|",
    ]
    for label, _, _ in VARIANTS:
        for source in protocol.MOTIONS:
            gaps = rows[label][source]
            worst = max(gaps)
            below = max(gaps, key=lambda g: g[1])
            lines.append(
                f"| {label} | {source} | {np.mean([g[0] for g in gaps]):+.2f} | "
                f"{worst[0]:+.2f} ({worst[2]}) | {sum(g[0] > 1.5 for g in gaps)} | "
                f"{below[1]:+.2f} ({below[2]}) |"
            )
    lines += ["", "## Scenes whose choice depends on the tie share (alpha: PSNR dB)", ""]
    lines += ["| scene | motion | sigma | best grid | " + " | ".join(v[0] for v in VARIANTS) + " |"]
    lines += ["|---|---|---|---|" + "---|" * len(VARIANTS)]
    for name, source, record, picks, grid, best in changes:
        cells = [
            f"{record['curve'][i][0]:.2g}: {score(record, i, grid):.2f}" for i in picks.values()
        ]
        lines.append(
            f"| {name} | {source} | {record['sigma']:.4f} | {best:.2f} | "
            + " | ".join(cells)
            + " |"
        )
    text = "\n".join(lines) + "\n"
    if args.output:
        atomic_write_text(args.output, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
