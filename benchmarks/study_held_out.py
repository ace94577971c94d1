"""A candidate for `--alpha held-out` on every grid alpha of the train split (issue 12, stop 28).

Run from the repository root after ``calibrate_defaults.py`` has computed the grid columns of
the same split and size (their PSNRs score the choices)::

    python benchmarks/study_held_out.py --split train --scenes 40 --jobs 2

For every scene and motion source, frame 1 of the left view is deblurred from its own frame at
every alpha of :data:`calibrate_defaults.ALPHAS` (the default settings otherwise). Each
solution predicts the right view's blurred frame in two ways: as ``held-out`` does (the 90 %
best-predicted pixels through a bilinear warp,
:func:`stereodeblur.pipeline.alpha.prediction_error`), and through the right view's observation
of the left one (the data term of ``--observations other-view``: a cubic warp by the disparity,
the right view's operator), every pixel it sees counted (:func:`observed_errors`, which also
gives the error over the pixels of data weight >= 0.5 and over those whose motion is trusted).
With the floor (the ``'auto'`` alpha, snapped to the grid) and the noise estimate this gives
each rule's grid alpha: upwards from the floor while the error falls, and for the candidate,
where the floor predicts best within ``ratio`` times the two views' noise ``2 sigma^2``,
downwards to the noise rule's alpha while it falls (the noise gate, :func:`choice`); the rows
"`held-out` upwards" keep ``held-out``'s choice and gate it with the error over the pixels of
data weight >= 0.5 (the default since stop 29). Each
choice is scored with the PSNR of the grid column ``alpha=A`` of ``calibrate_defaults.py`` (the
alpha solved with the default's observations), as that script's checks score the default.
Written: ``benchmarks/results/held_out_SPLIT_WxH.md`` (and the errors, ``.json``); the errors
are cached under ``--work``. Stop 28's candidate was not adopted: results/README.md, "`held-out`
with the other view's observation and a noise gate".
"""

from __future__ import annotations

import copy
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

GRID = protocol.ALPHAS
RATIOS = (None, 2.0, 4.0, 8.0, 16.0, 24.0)
"""Noise-gate ratios compared (None: no gate)."""
VIEWS = ("left", "right")


def observed_errors(image: np.ndarray, observation, trust, *, border: int) -> dict:
    """Mean squared error per pixel (over channels) of ``observation``'s blurred frame predicted
    from ``image``, ``border`` px excluded, over the pixels it sees (``'observed'``: weight >
    0), those it sees with weight >= 0.5 (``'full'``: not the exposures that leave the view),
    and of those the ones whose motion is trusted (``'trusted'``: ``trust`` >= 0.5)."""
    from stereodeblur.pipeline.alpha import inner, pixel_errors

    error = pixel_errors(observation.operator.forward(image), observation.blurred, border=border)
    weights = inner(observation.weights, border)
    trusted = np.ones_like(weights, bool) if trust is None else inner(trust, border) >= 0.5
    masks = {"observed": weights > 0, "full": weights >= 0.5}
    masks["trusted"] = masks["full"] & trusted
    return {k: float(error[m].mean()) if m.any() else float("inf") for k, m in masks.items()}


def grid_errors(task) -> tuple[str, dict]:
    """The prediction errors of each grid alpha's own-frame solution, the floor and the noise,
    per motion source, for one scene."""
    from stereodeblur.deconv.noise import estimate_noise_sigma
    from stereodeblur.evaluation.metrics import border_for
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import (
        build_view_operator,
        data_terms,
        deblur_view,
        read_window,
        stereo_motion,
    )
    from stereodeblur.pipeline.alpha import other_view, prediction_error
    from stereodeblur.pipeline.observations import other_view_observation

    kind, seed, size, work = task
    root = protocol.ensure_scene(kind, seed, size, work)
    scene = open_scene(root)
    out = {}
    for source in protocol.MOTIONS:
        column = protocol.Column("default", source)
        settings = column.settings()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # the calibration columns' scene flow; the true motion is fitted by stereo_motion
            given = None
            if source == "sceneflow":
                cache = Path(work) / "results" / root.name
                given = protocol.motion_for(scene, column, {}, {}, cache).sceneflow
            window = read_window(scene, protocol.FRAME, VIEWS, settings)
            motions = stereo_motion(scene, window, VIEWS, settings, sceneflow=given).views
            operators = {v: build_view_operator(window, motions[v], settings) for v in VIEWS}
            auto = replace(settings, alpha="auto")
            terms = {v: data_terms(scene, window, v, operators[v], auto) for v in VIEWS}
            right = window.blurred("right")
            held_out = other_view(operators["right"], motions["right"], right, "right")
            observation = other_view_observation(
                motions["left"].sceneflow, operators["right"], right, terms["right"].weights
            )
            border, trust = border_for(right.shape[1]), terms["right"].trust
            errors, observed = [], {"observed": [], "full": [], "trusted": []}
            for alpha in GRID:
                fixed = replace(settings, alpha=alpha, observations="single")
                left = replace(
                    terms["left"], alpha=alpha, update=copy.deepcopy(terms["left"].update)
                )
                image = deblur_view(
                    scene, window, motions["left"], fixed, operator=operators["left"], terms=left
                ).image
                errors.append(prediction_error(image, held_out, border=border))
                for key, value in observed_errors(image, observation, trust, border=border).items():
                    observed[key].append(value)
        out[source] = {
            "held_out": errors,
            **observed,
            "floor": terms["left"].alpha,
            "sigma": estimate_noise_sigma(window.blurred("left")),
        }
    return root.name, out


def choice(
    entry: dict, key: str, ratio: float | None, gate: str | None = None, start: str = "floor"
) -> int:
    """The grid index chosen with the errors ``entry[key]``: upwards from the snapped floor
    (``start='noise'``: from the noise rule's alpha, as ``held-out`` does with the true motion
    since stop 33) while the error falls (``held-out``); then, with a noise gate of ``ratio``,
    downwards to the noise rule's alpha while the error ``entry[gate]`` (default: the same)
    falls if the floor predicts best and its ``gate`` error is within ``ratio * 2 sigma^2``."""
    from stereodeblur.deconv.noise import alpha_from_sigma

    errors, noise = entry[key], protocol.nearest_alpha(alpha_from_sigma(entry["sigma"]))
    floor = noise if start == "noise" else protocol.nearest_alpha(entry["floor"])
    best = floor
    while best + 1 < len(GRID) and errors[best + 1] < errors[best]:
        best += 1
    below = entry[gate or key]
    gated = ratio is not None and best == floor and below[best] < ratio * 2 * entry["sigma"] ** 2
    while gated and best > noise and below[best - 1] < below[best]:
        best -= 1
    return best


RULES = (
    ("`held-out` (the default: 90 % best pixels, bilinear warp)", "held_out", None),
    *(
        (f"the other view's observation, noise gate {r:g} x 2 sigma^2", "observed", r)
        if r is not None
        else ("the other view's observation, every pixel it sees, no gate", "observed", None)
        for r in RATIOS
    ),
    *(
        (f"the same, pixels of weight >= 0.5{'' if r is None else f', gate {r:g}'}", "full", r)
        for r in (None, 8.0)
    ),
    *(
        (f"the same, and trust >= 0.5{'' if r is None else f', gate {r:g}'}", "trusted", r)
        for r in (None, 8.0)
    ),
    *(
        (f"`held-out` upwards, the gate {r:g} on the weight >= 0.5 error", "held_out", r, "full")
        for r in (4.0, 8.0, 16.0)
    ),
    (
        "from the noise rule's alpha up, the weight >= 0.5 error (stop 33: the true motion's)",
        "full",
        None,
        None,
        "noise",
    ),
)
"""Rows of the report: label, errors, gate ratio (and the gate's errors, if others)."""


def grid_psnrs(work: Path, name: str, source: str) -> np.ndarray | None:
    """The cached PSNRs of ``calibrate_defaults.py``'s grid columns, None if one is missing."""
    found = protocol.cached_columns(work, name, protocol.grid_columns(source))
    return None if found is None else np.array([data["psnr"] for data in found])


def report(rows: dict, work: Path, args, minutes: float) -> list[str]:
    lines = [
        f"# `held-out`'s choice on the grid: {args.split} split, {args.size}, {len(rows)} scenes",
        "",
        f"Command: `python benchmarks/study_held_out.py {' '.join(sys.argv[1:])}`; "
        f"{minutes:.1f} min (errors cached under --work are reused). Each rule's grid alpha "
        "scored with the PSNR of `calibrate_defaults.py`'s grid column; the floor snapped to the "
        "grid. dB below the best grid alpha: mean, worst scene, scenes more than 1.5 dB below.",
        "",
        "| rule | true motion: mean | worst | > 1.5 dB | scene flow: mean | worst | > 1.5 dB |",
        "|---|---|---|---|---|---|---|",
    ]
    scored = [
        (name, source, entry[source], psnrs)
        for name, entry in rows.items()
        for source in protocol.MOTIONS
        if (psnrs := grid_psnrs(work, name, source)) is not None
    ]
    for label, key, ratio, *gate in RULES:
        cells = []
        for source in protocol.MOTIONS:
            gaps = [
                (psnrs.max() - psnrs[choice(errors, key, ratio, *gate)], name)
                for name, s, errors, psnrs in scored
                if s == source
            ]
            values = np.array([g for g, _ in gaps])
            worst = max(gaps)
            cells += [f"{values.mean():.2f}", f"{worst[0]:.2f} ({worst[1]})"]
            cells.append(f"{(values > 1.5).sum()}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    return protocol.run_study("held_out", grid_errors, report, 40, __doc__.split("\n", 1)[0], argv)


if __name__ == "__main__":
    sys.exit(main())
