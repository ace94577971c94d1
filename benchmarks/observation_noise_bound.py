"""How much a second observation can gain by averaging noise (issue 13): the other view
against a second noise draw of the view itself.

Run from the repository root::

    python benchmarks/observation_noise_bound.py --work /tmp/paperbench --size 320x240 \
        --output benchmarks/results/observation_noise_bound_320x240.md

Frame 1 (left) of ``bench paper``'s noisy object scenes (the same work folder layout), the
defaults (``--alpha held-out``, gated boundaries), the true motion and the estimated scene
flow. Rows: the view's own frame only (``--observations single``); + the other view (the
default); + a second draw of the view's own frame (the noiseless render with new noise of the
same deviation, seed 7: the same operator, the same model error, independent noise), the most
a second observation of the same exposure can add by averaging noise; + both.
"""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from stereodeblur.deconv.irls import Observation
from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.metrics import border_for, masked_mse, psnr
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import (
    build_view_operator,
    data_terms,
    deblur_view,
    read_window,
    stereo_motion,
)
from stereodeblur.pipeline.alpha import other_view
from stereodeblur.pipeline.observations import NamedObservation, view_observations
from stereodeblur.settings import DeblurSettings
from stereodeblur.synth.objects import NOISE_SIGMA, OBJECT_SCENES

sys.path.insert(0, str(Path(__file__).resolve().parent))

from hidden_fill_bound import finish, parse, scenes_folder, score_rows  # noqa: E402

ROWS = ("own frame only", "+ other view (default)", "+ second draw", "+ both")
FRAME = 1
VIEWS = ("left", "right")


def evaluate(folder: Path, name: str, source: str) -> dict:
    """PSNR and gt/mixed MSE of each row for scene ``name`` (noisy) and motion ``source``."""
    scene = open_scene(folder / f"{name}_noisy")
    settings = DeblurSettings(motion_source=source)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = read_window(scene, FRAME, VIEWS, settings)
        motions = stereo_motion(scene, window, VIEWS, settings).views
        operators = {v: build_view_operator(window, motions[v], settings) for v in VIEWS}
        weights = {
            v: data_terms(scene, window, v, operators[v], replace(settings, alpha="auto")).weights
            for v in VIEWS
        }
    clean = open_scene(folder / name).read_frame("left", FRAME)
    rng = np.random.default_rng(7)
    draw = np.clip(clean + NOISE_SIGMA * rng.standard_normal(clean.shape), 0, 1)
    second = NamedObservation(
        "second draw",
        Observation(operators["left"].operator, draw.astype(np.float32), weights["left"]),
    )
    other = view_observations(window, "left", motions, operators, weights, settings)
    rows = dict(zip(ROWS, ((), tuple(other), (second,), (*other, second)), strict=True))
    truth = scene.read_gt_sharp("left", FRAME)
    mixed = scene.read_gt_mixed("left", FRAME)
    border = border_for(truth.shape[1])
    held_out = other_view(operators["right"], motions["right"], window.blurred("right"), "right")
    out = {}
    for key, observations in rows.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = deblur_view(
                scene, window, motions["left"], settings, operator=operators["left"],
                other=held_out, observations=observations,
            )  # fmt: skip
        out[key] = (
            psnr(result.image, truth, border=border),
            masked_mse(result.image, truth, mixed, border=border),
        )
    return out


def report(results: dict, argv, minutes: float) -> list[str]:
    lines = [
        "# What a second observation can gain by averaging noise: bench paper's noisy objects",
        "",
        f"Command: `python benchmarks/observation_noise_bound.py {' '.join(argv)}`; "
        f"{minutes:.1f} min. Frame 1, left view, the defaults. Per cell: PSNR dB / mean squared "
        "error in the gt/mixed pixels x 1000 (2.5 % border). The second draw is the view's own "
        "frame with independent noise (sigma 0.01): what averaging noise over two observations "
        "of the same exposure can give at most.",
        "",
    ]
    for source in ("gt", "sceneflow"):
        part = {f"{name}_noisy": r for (name, s), r in results.items() if s == source}
        lines += [f"**{source}**", "", "| scene | " + " | ".join(ROWS) + " |"]
        lines.append("|---|" + "---|" * len(ROWS))
        lines += [*score_rows(part, ROWS), ""]
    return lines


def main(argv=None) -> int:
    args = parse(argv, __doc__.split("\n", 1)[0])
    names = args.scenes.split(",") if args.scenes else list(OBJECT_SCENES)
    folder = scenes_folder(args)
    start = time.perf_counter()
    paper_bench.render_missing(folder, [n + s for n in names for s in ("", "_noisy")], args.size)
    results = {}
    for name in names:
        for source in ("gt", "sceneflow"):
            results[name, source] = r = evaluate(folder, name, source)
            print(name, source, " ".join(f"{r[k][0]:.2f}" for k in ROWS), flush=True)
    return finish(report(results, sys.argv[1:], (time.perf_counter() - start) / 60), args)


if __name__ == "__main__":
    sys.exit(main())
