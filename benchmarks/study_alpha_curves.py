"""What `--alpha held-out` sees on every alpha (issue 12, stops 50-51): its scores and the truth.

Run from the repository root after ``calibrate_defaults.py`` has computed the grid columns of
the same scenes, split, size and ``--work`` (their PSNRs score the choices)::

    python benchmarks/study_alpha_curves.py --split train --scenes 20 --size 320x240

For every scene and motion source, frame 1 of both views is deblurred with the default
settings and the calibration's stored motion, by the pipeline itself, but with its alpha choice
opened up: the candidates are the choice's floor and every alpha of
:data:`calibrate_defaults.ALPHAS` (those above the floor first, in the default's order), none
stops the search, the choice is the floor and nothing goes below it. Recorded per candidate
(each a solution of the view's own frame, as the choice makes them): the score the default
gives it (with the scene flow the sum of the held-out observations' errors, with the true motion
the other view's observation's), each held-out observation's error, and its PSNR against the
truth, its residual in its own blurred frame and its distance in the sharp domain from the
right view's own-frame solution at its floor (:func:`sharp_distances`); per grid alpha, its
solution's distance from the next one's; and the floor, the noise estimate and the PSNR of the
left view's solution at the floor with every observation. The default's own choice is
replayed from these records with the pipeline's functions (:func:`replay_default`) and checked
against the calibration's default column; the other rows are rules that the records allow to
compare. Every choice is scored with the PSNR of the calibration's grid column of its alpha (the
floor: the solution at the floor recorded here). Written:
``benchmarks/results/alpha_curves_SPLIT_WxH.md`` and ``.json``.
"""

from __future__ import annotations

import itertools
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

GRID = protocol.ALPHAS


def curves(task) -> tuple[str, dict]:
    """The records of one scene, per motion source (see the module's docstring)."""
    from stereodeblur.evaluation.metrics import border_for
    from stereodeblur.io.scene import open_scene

    kind, seed, size, work = task
    root = protocol.ensure_scene(kind, seed, size, work)
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    border = border_for(truth.shape[1])
    cache = work / "results" / root.name
    return root.name, {s: source_record(scene, s, truth, border, cache) for s in protocol.MOTIONS}


def opened_pipeline(out: dict, views: dict, current: dict, truth, border: int) -> dict:
    """The functions of :mod:`stereodeblur.pipeline.frame` that :func:`source_record` replaces
    to open up the alpha choice, by name: each records into ``out`` (the left view's candidates)
    and ``views`` (per view: its own operator and blurred frame, the other view, its candidates'
    images) while ``current["view"]``'s choice is made."""
    import stereodeblur.pipeline.alpha as rules
    import stereodeblur.pipeline.frame as frame
    from stereodeblur.evaluation.metrics import psnr

    def kept(image, errors):
        view = views[current["view"]]
        view["images"].append(image)
        if current["view"] == "left":
            out["errors"].append(errors)
            out["psnr"].append(psnr(image, truth, border=border))
            out["own"].append(
                rules.own_error(image, view["operator"], view["blurred"], border=border)
            )
        return sum(errors)

    def held_out_error(image, observations, *, border):
        return kept(image, [rules.observed_error(image, o, border=border) for o in observations])

    def observed_error(image, observation, *, border):
        return kept(image, [rules.observed_error(image, observation, border=border)])

    def prediction_error(image, other, *, border):
        return kept(image, [rules.prediction_error(image, other, border=border)])

    def choose(errors, rule, alphas):
        if current["view"] == "left":
            out["alphas"], out["score"] = [float(a) for a in alphas], list(errors)
        return 0

    def below_floor(floor, error, sigma):
        if current["view"] == "left":
            out["gate"] = {"floor": float(floor), "sigma": float(sigma)}
        return ()

    def candidates(rule, floor):
        above = [a for a in GRID if a > floor]
        return (floor, *above, *(a for a in reversed(GRID) if a < floor))

    solve = frame._alpha_choice_solve

    def opened(scene, window, view, blurred, operator, settings, other, *args):
        current["view"] = view
        views[view] = {
            "operator": operator.operator,
            "blurred": blurred,
            "other": other,
            "images": [],
        }
        return solve(scene, window, view, blurred, operator, settings, other, *args)

    return {
        "_alpha_choice_solve": opened,
        "held_out_error": held_out_error,
        "observed_error": observed_error,
        "prediction_error": prediction_error,
        "choose": choose,
        "below_floor": below_floor,
        "candidates": candidates,
        "searched": lambda rule, errors, alphas: False,
        "undominated": lambda alphas, own: list(range(len(alphas))),
    }


def source_record(scene, source: str, truth, border: int, cache: Path) -> dict:
    """One scene's and motion source's record (see the module's docstring)."""
    import stereodeblur.pipeline.alpha as rules
    import stereodeblur.pipeline.frame as frame
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.evaluation.motion_cache import cached_motion
    from stereodeblur.pipeline import deblur_stereo_frame

    out = {"alphas": [], "score": [], "errors": [], "psnr": [], "own": [], "gate": None}
    views = {}  # per view: its own operator and blurred frame, the other view, its candidates
    current = {"view": None}  # the view whose choice is being made
    patches = opened_pipeline(out, views, current, truth, border)
    saved = {name: getattr(frame, name) for name in patches}
    settings = protocol.Column("default", source).settings()
    motion, _, _ = cached_motion(scene, source, protocol.unmoved(source), cache)
    sceneflow = motion.sceneflow if source == "sceneflow" else None
    try:
        for name, function in patches.items():
            setattr(frame, name, function)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            both = ("left", "right")
            result = deblur_stereo_frame(
                scene, protocol.FRAME, views=both, settings=settings, sceneflow=sceneflow
            )
    finally:
        for name, function in saved.items():
            setattr(frame, name, function)
    count = len(out["alphas"])  # the gate's calls come after the candidates'
    for key in ("errors", "psnr", "own"):
        out[key] = out[key][:count]
    out["sharp"] = sharp_distances(views["left"], views["right"], count, border)
    images = [views["left"]["images"][out["alphas"].index(a)] for a in GRID]
    out["changes"] = [float(np.mean((b - a) ** 2)) for a, b in itertools.pairwise(images)]
    out["floor_psnr"] = psnr(result.frames["left"].result.image, truth, border=border)
    out["rule"] = "true motion" if rules.true_motion_choice(settings) else "estimated"
    return out


def sharp_distances(left: dict, right: dict, count: int, border: int) -> list[float]:
    """Per left candidate: the mean of the :data:`SHARP_KEEP` smallest squared differences
    from the right view's own-frame solution at its floor, carried to the left view through
    the left view's disparity, over the pixels whose two disparities agree within 1 px."""
    from stereodeblur.pipeline.alpha import inner, pixel_errors, warp_to_other

    left_disparity = right["other"].disparity  # what the right view's choice predicts: the left
    target = warp_to_other(right["images"][0], left_disparity, -1)
    carried = warp_to_other(left["other"].disparity, left_disparity, -1)
    agree = inner(np.abs(carried - left_disparity) < 1.0, border)
    out = []
    for image in left["images"][:count]:
        error = np.sort(pixel_errors(image, target, border=border)[agree])
        out.append(float(error[: max(1, int(SHARP_KEEP * error.size))].mean()))
    return out


SHARP_KEEP = 0.9
"""Share of the pixels :func:`sharp_distances` keeps (occlusions and the warp's errors out)."""


def replay_default(record: dict) -> float:
    """The alpha the default's choice takes on these records: the floor and the grid above it
    while :func:`~stereodeblur.pipeline.alpha.searched` lets it, then
    :func:`~stereodeblur.pipeline.alpha.choose`; at the floor, the noise gate
    (:func:`~stereodeblur.pipeline.alpha.below_floor`) on the other view's error (the last
    held-out observation), over the grid alphas only (the noise rule's own alpha, not on the
    grid, is not recorded); candidates a larger one fits better in the own frame are dropped
    (:func:`~stereodeblur.pipeline.alpha.undominated`)."""
    from stereodeblur.pipeline.alpha import below_floor, choose, searched, undominated

    alphas, floor, own = record["alphas"], record["alphas"][0], record["own"]
    order = [0] + [k for k, a in enumerate(alphas) if a > floor]
    errors, tried = [], []
    for k in order:
        errors.append(record["score"][k])
        tried.append(alphas[k])
        if searched("held-out", errors, tried):
            break
    solved = order[: len(errors)]
    kept = undominated([alphas[k] for k in solved], [own[k] for k in solved])
    best = kept[choose([errors[i] for i in kept], "held-out", [alphas[solved[i]] for i in kept])]
    chosen = solved[best]
    gate = record["gate"]
    if best == 0 and gate is not None:
        other = {a: e[-1] for a, e in zip(alphas, record["errors"], strict=True)}
        previous = other[floor]
        for alpha in below_floor(gate["floor"], previous, gate["sigma"]):
            k = alphas.index(alpha) if alpha in other else None
            if k is None or other[alpha] >= previous or own[k] >= own[chosen]:
                break
            previous, chosen = other[alpha], k
    return alphas[chosen]


def step_up(alpha: float, steps: int = 1) -> float:
    """The grid alpha ``steps`` above the grid alpha nearest ``alpha``, at most the largest."""
    return GRID[min(protocol.nearest_alpha(alpha) + steps, len(GRID) - 1)]


def normalised(record: dict) -> float:
    """The candidate (the floor and above) with the least sum of each held-out observation's
    error relative to its least over the candidates: every observation counts alike, not by
    the size of its error (a neighbour the motion explains badly outweighs the rest)."""
    alphas, floor = record["alphas"], record["alphas"][0]
    errors = np.array(record["errors"])
    relative = (errors / errors[[k for k, a in enumerate(alphas) if a >= floor]].min(0)).sum(1)
    return min((a for a in alphas if a >= floor), key=lambda a: relative[alphas.index(a)])


def single_best(record: dict) -> float:
    """The candidate whose own-frame solution is nearest the truth (an oracle)."""
    return record["alphas"][int(np.argmax(record["psnr"]))]


def sharpest_agreement(record: dict) -> float:
    """The candidate nearest the other view's own-frame solution at its floor, in the sharp
    domain (:func:`sharp_distances`)."""
    return record["alphas"][int(np.argmin(record["sharp"]))]


def discrepancy(record: dict) -> float:
    """The largest candidate whose residual in its own blurred frame is at most the other
    view's least held-out error (the model's and the noise's error, estimated by the other
    view; the smallest candidate if none)."""
    other = min(errors[-1] for errors in record["errors"])
    fitting = [a for a, own in zip(record["alphas"], record["own"], strict=True) if own <= other]
    return max(fitting) if fitting else min(record["alphas"])


def quasi_optimal(record: dict) -> float:
    """The smaller of the two neighbouring grid alphas whose solutions differ least (the
    quasi-optimality criterion, which needs no noise level)."""
    return GRID[int(np.argmin(record["changes"]))]


RULES = (
    ("the default (replayed)", replay_default),
    ("the default, one grid step up", lambda r: step_up(replay_default(r))),
    (
        "least score from the floor up, no tie rule",
        lambda r: min(
            (a for a in r["alphas"] if a >= r["alphas"][0]),
            key=lambda a: r["score"][r["alphas"].index(a)],
        ),
    ),
    ("least sum of relative errors from the floor up", normalised),
    ("sharp domain: nearest the other view's own-frame solution at its floor", sharpest_agreement),
    ("discrepancy: largest own residual within the other view's least error", discrepancy),
    ("quasi-optimality: least change to the next candidate", quasi_optimal),
    ("oracle: the own-frame solution nearest the truth", single_best),
    ("oracle: the same, one grid step up", lambda r: step_up(single_best(r))),
)
"""Rows of the report: label and the rule (a record's chosen alpha)."""


def grid_psnrs(work: Path, name: str, source: str) -> dict | None:
    """The calibration's cached PSNRs of the default column (``'default'``, its alpha
    ``'default alpha'``) and of the grid columns (by alpha); None if one is missing."""
    columns = [protocol.Column("default", source), *protocol.grid_columns(source)]
    found = protocol.cached_columns(work, name, columns)
    if found is None:
        return None
    default, *rest = found
    return {"default": default["psnr"], "default alpha": default["alpha"]} | {
        alpha: data["psnr"] for alpha, data in zip(GRID, rest, strict=True)
    }


def scored(record: dict, psnrs: dict, alpha: float) -> float:
    """PSNR of the solution with every observation at ``alpha``: the grid column's, the floor's
    recorded one."""
    return record["floor_psnr"] if alpha == record["alphas"][0] else psnrs[alpha]


def report(rows: dict, work: Path, args, minutes: float) -> list[str]:
    lines = [
        f"# `held-out`'s scores on every alpha: {args.split} split, {args.size}, "
        f"{len(rows)} scenes",
        "",
        f"Command: `python benchmarks/study_alpha_curves.py {' '.join(sys.argv[1:])}`; "
        f"{minutes:.1f} min (records cached under --work are reused); code "
        f"{protocol.code_version()}. Every choice scored with the PSNR of the solution with every "
        "observation at its alpha (the calibration's grid column; the floor's solved here). "
        "dB below the best grid alpha: mean, worst scene, scenes more than 1.5 dB below.",
        "",
        "| rule | true motion: mean | worst | > 1.5 dB | scene flow: mean | worst | > 1.5 dB |",
        "|---|---|---|---|---|---|---|",
    ]
    table = {
        source: [
            (name, entry[source], psnrs)
            for name, entry in rows.items()
            if (psnrs := grid_psnrs(work, name, source)) is not None
        ]
        for source in protocol.MOTIONS
    }
    for label, rule in RULES:
        cells = []
        for source in protocol.MOTIONS:
            gaps = [
                (max(psnrs[a] for a in GRID) - scored(record, psnrs, rule(record)), name)
                for name, record, psnrs in table[source]
            ]
            if not gaps:
                cells += ["–"] * 3
                continue
            values = np.array([g for g, _ in gaps])
            worst = max(gaps)
            cells += [
                f"{values.mean():.2f}",
                f"{worst[0]:.2f} ({worst[1]})",
                f"{(values > 1.5).sum()}",
            ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    matched = [
        np.isclose(replay_default(record), psnrs["default alpha"], rtol=1e-6)
        for source in protocol.MOTIONS
        for _, record, psnrs in table[source]
    ]
    lines.append("")
    for source in protocol.MOTIONS:
        steps = [
            protocol.nearest_alpha(max(GRID, key=lambda a: psnrs[a]))
            - protocol.nearest_alpha(single_best(record))
            for _, record, psnrs in table[source]
        ]
        if steps:
            lines.append(
                f"- {source}: the best alpha with every observation lies above the best own-frame "
                f"solution's on {sum(k > 0 for k in steps)} scenes, on it on "
                f"{sum(k == 0 for k in steps)}, below on {sum(k < 0 for k in steps)} "
                f"(grid steps: {', '.join(f'{k:+d}' for k in steps)})."
            )
    lines += [
        "",
        f"The replayed default took the calibration's alpha on {sum(matched)} of {len(matched)}.",
        "",
        "Per scene: the best alpha with every observation (grid), the best own-frame solution "
        "(oracle), the least score, the default's alpha replayed and in the calibration.",
        "",
        "| scene | motion | best (all observations) | best own frame | least score | "
        "default replayed | default (calibration) |",
        "|---|---|---|---|---|---|---|",
    ]
    for source in protocol.MOTIONS:
        for name, record, psnrs in table[source]:
            best = max(GRID, key=lambda a: psnrs[a])
            least = record["alphas"][int(np.argmin(record["score"]))]
            lines.append(
                f"| {name} | {source} | {best:g} | {single_best(record):g} | {least:g} | "
                f"{replay_default(record):.3g} | {psnrs['default alpha']:.3g} |"
            )
    return lines


def main(argv=None) -> int:
    return protocol.run_study("alpha_curves", curves, report, 20, __doc__.split("\n", 1)[0], argv)


if __name__ == "__main__":
    sys.exit(main())
