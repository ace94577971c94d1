"""How low the error in the mixed pixels can go (issue 13): the true motion, its
occlusion-aware operator and the hidden samples' true values, with today's solver.

Run from the repository root::

    python benchmarks/mixed_error_bound.py --work /tmp/paperbench --size 640x480 \
        --output benchmarks/results/mixed_error_bound_640x480.md

Frame 1 (left) of ``bench paper``'s object scenes (the same work folder layout), the default
settings but the motion: the true motion (``--motion-source gt``), so the occlusion-aware
homography operator (cubic taps), the default data weights, the other view and the
neighbouring frames observed (``--observations all``), 4 x 25 iterations, at each alpha of
:data:`ALPHAS`, no range guard. Rows: *true motion* (the pipeline's operator, data weights
and observations) and *oracle fill* (the samples of the view's own exposure that show a
surface the frame centre hides dropped from its operator, their true value, the mean of the
instantaneous renders there, subtracted from its blurred frame, and those pixels no longer
down-weighted; the further observations as before). Per scene the alpha with the least
gt/mixed error is kept: what this model and solver reach there with an exact motion.
"""

from __future__ import annotations

import copy
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from stereodeblur.blur.operator import SparseBlur
from stereodeblur.blur.visibility import hidden_fraction, sceneflow_visibility
from stereodeblur.deconv.irls import deblur_irls
from stereodeblur.deconv.trust import OUTSIDE_WEIGHT, leaves_view
from stereodeblur.deconv.weights import hidden_weights
from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.metrics import border_for, masked_mse, psnr
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import build_view_operator, data_terms, read_window, stereo_motion
from stereodeblur.pipeline.alpha import pixel_errors
from stereodeblur.pipeline.observations import view_observations
from stereodeblur.settings import OBSERVATION_ROBUST_SCALE, DeblurSettings
from stereodeblur.synth.objects import object_setup

sys.path.insert(0, str(Path(__file__).resolve().parent))

from hidden_fill_bound import (  # noqa: E402
    finish,
    hidden_samples,
    object_names,
    parse,
    scenes_folder,
)

ALPHAS = (1e-4, 3e-4, 1e-3)
ROWS = ("true motion", "oracle fill")
FRAME = 1
VIEWS = ("left", "right")


def rms(predicted, observed, border: int) -> float:
    """Root mean square of ``predicted - observed`` without ``border`` px on every side."""
    return float(np.sqrt(pixel_errors(predicted, observed, border=border).mean()))


def evaluate(
    root: Path, name: str, settings: DeblurSettings, *, setup=None, alphas=ALPHAS, by="mixed"
) -> dict:
    """``{row: (psnr, gt/mixed mse, alpha)}`` at the alpha of ``alphas`` with the least gt/mixed
    error (``by='mixed'``) or the highest PSNR (``'psnr'``); ``setup`` the scene's objects and
    camera (default: the object scene ``name``'s), whose instants give the hidden samples. Also
    ``'model residual'``: :func:`rms` of ``A I`` against ``B``, with the row *true motion*'s
    operator at the true sharp frame ``I``."""
    scene = open_scene(root)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = read_window(scene, FRAME, VIEWS, settings)
        motions = stereo_motion(scene, window, VIEWS, settings).views
        operators = {v: build_view_operator(window, motions[v], settings) for v in VIEWS}
        fixed = replace(settings, alpha="auto")
        terms = {v: data_terms(scene, window, v, operators[v], fixed) for v in VIEWS}
    weights = {v: terms[v].weights for v in VIEWS}
    observations = view_observations(window, "left", motions, operators, weights, settings)
    sf, exposure, n = motions["left"].sceneflow, window.exposure, settings.num_samples
    visible = sceneflow_visibility(sf, exposure, n)
    share = hidden_fraction(visible)
    assert np.array_equal(share, operators["left"].hidden), "not the pipeline's visibility"
    today = operators["left"].operator
    if setup is None:
        setup = object_setup(name, size=(sf.shape[1], sf.shape[0]))
    part, fill = hidden_samples(sf, exposure, n, visible, setup, "cubic")
    dropped = (today.matrix - part).tocsr()
    sums = np.asarray(dropped.sum(axis=1)).ravel()
    assert np.abs(sums - (1 - share.ravel())).max() < 1e-4, "hidden samples do not match"
    blurred = window.blurred("left").astype(np.float64)
    own = terms["left"].weights
    outside = leaves_view(motions["left"].flow_forward, motions["left"].flow_backward,
                          exposure.duty_cycle)  # fmt: skip
    unhidden = np.where(outside, OUTSIDE_WEIGHT, 1.0).astype(np.float32)
    assert np.allclose(own, unhidden * hidden_weights(share)), "not the pipeline's weights"
    problems = {
        "true motion": (today, blurred, own),
        "oracle fill": (
            SparseBlur(dropped.astype(np.float32), today.shape),
            blurred - fill,
            unhidden,
        ),
    }
    truth = scene.read_gt_sharp("left", FRAME).astype(np.float64)
    mixed = scene.read_gt_mixed("left", FRAME)
    border = border_for(truth.shape[1])
    out = {"model residual": rms(today.forward(truth), blurred, border)}
    for key, (op, data, w) in problems.items():
        best = None
        for alpha in alphas:
            result = deblur_irls(
                data,
                op,
                weights=w,
                alpha=alpha,
                num_irls=settings.num_irls,
                num_cg=settings.num_cg,
                update_weights=copy.deepcopy(terms["left"].update),
                anchor=terms["left"].anchor,
                observations=[o.observation for o in observations],
                robust_scale=OBSERVATION_ROBUST_SCALE if observations else None,
                initial=blurred,
            )
            image = np.clip(result.image, 0.0, 1.0)
            score = (
                psnr(image, truth, border=border),
                masked_mse(image, truth, mixed, border=border),
                alpha,
            )
            if best is None or (score[0] > best[0] if by == "psnr" else score[1] < best[1]):
                best = score
        out[key] = best
    return out


def main(argv=None) -> int:
    args = parse(argv, __doc__.split("\n", 1)[0])
    names = object_names(args)
    folder = scenes_folder(args)
    settings = DeblurSettings(motion_source="gt")
    start = time.perf_counter()
    paper_bench.render_missing(folder, names, args.size)
    results = {}
    for name in names:
        results[name] = evaluate(folder / name, name, settings)
        print(name, results[name], flush=True)
    minutes = (time.perf_counter() - start) / 60
    lines = [
        "# The error in the mixed pixels with the true motion and the hidden samples' true values",
        "",
        f"Command: `python benchmarks/mixed_error_bound.py {' '.join(sys.argv[1:])}`; "
        f"{minutes:.1f} min. Frame 1, left view, the default settings with the true motion "
        "(occlusion-aware operator, cubic taps, the other view and the neighbouring frames "
        f"observed), each row at the alpha of {', '.join(f'{a:g}' for a in ALPHAS)} with the "
        "least gt/mixed error. Per cell: PSNR dB / gt/mixed MSE x 1000 (2.5 % border) / alpha.",
        "",
        "| scene | " + " | ".join(ROWS) + " |",
        "|---|" + "---|" * len(ROWS),
    ]
    for name, r in results.items():
        cells = [f"{r[k][0]:.2f} / {1000 * r[k][1]:.2f} / {r[k][2]:g}" for k in ROWS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    for label, suffix in (("noiseless", False), ("noisy", True)):
        group = [r for name, r in results.items() if name.endswith("_noisy") == suffix]
        if group:
            cells = [
                f"{np.mean([r[k][0] for r in group]):.2f} / "
                f"{1000 * np.mean([r[k][1] for r in group]):.2f}"
                for k in ROWS
            ]
            lines.append(f"| **mean, {label}** | " + " | ".join(cells) + " |")
    return finish(lines, args)


if __name__ == "__main__":
    sys.exit(main())
