"""What a hidden-surface fill could gain at most (issue 13): the exposure's hidden samples
given their true values.

Run from the repository root::

    python benchmarks/hidden_fill_bound.py --work /tmp/paperbench --size 320x240 \
        --output benchmarks/results/hidden_fill_bound_320x240.md

Frame 1 (left) of ``bench paper``'s object scenes (the same work folder layout), the true
motion (``--motion-source gt``), the occlusion-aware homography operator
(:mod:`stereodeblur.blur.visibility`), bilinear taps, the paper's alpha, the default
iterations, one observation. A sample of the exposure that shows a surface the frame centre
hides (label ``HIDDEN``) takes the pixel's own segment today; its error is what the fill would
remove. Rows:

- *today*: that operator, hidden pixels down-weighted (``hidden_weights``), as the pipeline;
- *oracle fill*: the hidden samples dropped from the operator and their true value (the
  instantaneous render at the sample's instant) subtracted from the blurred frame, all
  weights 1 (but those of pixels whose path leaves the view, as everywhere);
- *oracle fill, down-weighted*: the same with the hidden pixels' weights of *today*;
- *renormalised*: the hidden samples dropped and each row rescaled to sum to one (a fill by
  the visible samples' mean, which needs no other observation), down-weighted.

Also the blur model's error ``A I - B`` at the true sharp frame, split into mixed pixels that
show a hidden surface and those that do not: what no fill can reach.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from stereodeblur.blur.homography import _inputs, homography_blur
from stereodeblur.blur.operator import SparseBlur
from stereodeblur.blur.trajectories import bilinear_taps, cubic_taps, homography_positions, is_cubic
from stereodeblur.blur.visibility import HIDDEN, hidden_fraction, sceneflow_visibility
from stereodeblur.cli.base import add_size, size_text
from stereodeblur.deconv.irls import deblur_irls
from stereodeblur.deconv.trust import OUTSIDE_WEIGHT, leaves_view
from stereodeblur.deconv.weights import hidden_weights
from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.metrics import border_for, masked_mse, psnr
from stereodeblur.io.outputs import atomic_write_text
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline.motion import stereo_motion
from stereodeblur.pipeline.window import read_window
from stereodeblur.settings import PAPER_ALPHA, DeblurSettings
from stereodeblur.synth.objects import OBJECT_SCENES, object_setup
from stereodeblur.synth.render import render_instant

ROWS = ("today", "oracle fill", "oracle fill, down-weighted", "renormalised")
FRAME = 1


def hidden_samples(sceneflow, exposure, num_samples, visible, setup, interpolation="bilinear"):
    """The operator's part made of hidden samples (``interpolation``'s taps at the own
    segment's positions, clamped as the operator clamps them) and the true mean of those
    samples, ``(H, W, 3)``, from the instantaneous renders."""
    homographies, labels, n = _inputs(sceneflow, exposure, num_samples, 0.0)
    height, width = sceneflow.shape
    pixel, sample = np.nonzero(np.moveaxis(visible == HIDDEN, 0, -1).reshape(-1, n))
    positions = homography_positions(homographies, labels).reshape(-1, n, 2)[pixel, sample]
    taps = cubic_taps if is_cubic(interpolation) else bilinear_taps
    index, weight, valid = taps(positions, (height, width), border="clamp")
    rows = np.broadcast_to(pixel[:, None], index.shape)
    size = height * width
    matrix = sp.coo_matrix(
        (weight[valid] / n, (rows[valid], index[valid])), shape=(size, size)
    ).tocsr()
    truth = np.zeros((height, width, 3))
    fractions = exposure.sample_fractions(n)
    for k in range(n):
        hidden = visible[k] == HIDDEN
        if hidden.any():
            at = FRAME + fractions[k]
            instant = render_instant(setup.objects, setup.camera, "left", (width, height), at)
            truth[hidden] += instant.image[hidden] / n
    return matrix, truth


def object_names(args) -> list[str]:
    """``args.scenes`` or every object scene of ``bench paper``, noiseless and noisy."""
    if args.scenes:
        return args.scenes.split(",")
    return [n + s for n in OBJECT_SCENES for s in ("", "_noisy")]


def evaluate(root: Path, name: str, settings: DeblurSettings) -> dict:
    """PSNR, gt/mixed MSE per row and the model's error split, for one scene."""
    scene = open_scene(root)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = read_window(scene, FRAME, ("left", "right"), settings)
        motion = stereo_motion(scene, window, ("left", "right"), settings).views["left"]
    sf, exposure, n = motion.sceneflow, window.exposure, settings.num_samples
    width, height = sf.shape[1], sf.shape[0]
    visible = sceneflow_visibility(sf, exposure, n)
    today = homography_blur(sf, exposure, num_samples=n, visible=visible).matrix
    setup = object_setup(name, size=(width, height))
    hidden_part, fill = hidden_samples(sf, exposure, n, visible, setup)
    dropped = (today - hidden_part).tocsr()
    sums = np.asarray(dropped.sum(axis=1)).ravel()
    share = hidden_fraction(visible)
    assert np.abs(sums - (1 - share.ravel())).max() < 1e-5, "hidden samples do not match"
    renormalised = sp.diags(1 / np.maximum(sums, 0.05)) @ dropped
    matrices = {"today": today, "dropped": dropped, "renorm": renormalised}
    shape = (height, width)
    ops = {k: SparseBlur(m.tocsr().astype(np.float32), shape) for k, m in matrices.items()}
    blurred = window.blurred("left").astype(np.float64)
    outside = leaves_view(motion.flow_forward, motion.flow_backward, exposure.duty_cycle)
    base = np.where(outside, OUTSIDE_WEIGHT, 1.0).astype(np.float32)
    down = base * hidden_weights(share)
    problems = {
        "today": (ops["today"], blurred, down),
        "oracle fill": (ops["dropped"], blurred - fill, base),
        "oracle fill, down-weighted": (ops["dropped"], blurred - fill, down),
        "renormalised": (ops["renorm"], blurred, down),
    }
    truth = scene.read_gt_sharp("left", FRAME).astype(np.float64)
    mixed = scene.read_gt_mixed("left", FRAME)
    border = border_for(width)
    out = {"hidden_share": float(np.mean(share > 0))}
    for key, (op, data, weights) in problems.items():
        result = deblur_irls(
            data, op, weights=weights, alpha=PAPER_ALPHA, num_irls=settings.num_irls,
            num_cg=settings.num_cg, initial=blurred,
        )  # fmt: skip
        out[key] = (
            psnr(result.image, truth, border=border),
            masked_mse(result.image, truth, mixed, border=border),
        )
    inner = np.zeros_like(mixed)
    inner[border:-border, border:-border] = True
    showing = share > 0
    for key, op, data in (("model today", ops["today"], blurred),
                          ("model oracle", ops["dropped"], blurred - fill)):  # fmt: skip
        error = ((op.forward(truth) - data) ** 2).mean(axis=-1)
        out[key] = tuple(float(error[inner & mixed & m].mean()) for m in (showing, ~showing))
    return out


def score_rows(results: dict, rows, first=None) -> list[str]:
    """Markdown rows ``PSNR / gt-mixed MSE x 1000`` of each scene of ``results`` (``{name:
    {row: (psnr, mse)}}``) in the order ``rows``, and their mean; ``first``: cells per name put
    before them (empty in the mean row)."""
    first = first or {}
    lines = []
    for name, r in results.items():
        cells = [*first.get(name, []), *(f"{r[k][0]:.2f} / {1000 * r[k][1]:.2f}" for k in rows)]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    means = [
        f"{np.mean([r[k][0] for r in results.values()]):.2f} / "
        f"{1000 * np.mean([r[k][1] for r in results.values()]):.2f}"
        for k in rows
    ]
    blanks = "| " * len(next(iter(first.values()), []))
    lines.append("| **mean** | " + blanks + " | ".join(means) + " |")
    return lines


def parse(argv=None, description: str = "", *, jobs: bool = False) -> argparse.Namespace:
    """The bound scripts' options: ``--work`` (bench paper's), ``--size``, ``--scenes``,
    ``--output``, and ``--jobs`` where ``jobs``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--work", default="/tmp/paperbench", help="bench paper's work folder")
    add_size(parser, (320, 240))
    parser.add_argument("--scenes", default=None, help="comma-separated (default: the objects)")
    parser.add_argument("--output", default=None, help="Markdown (default: print only)")
    if jobs:
        parser.add_argument("--jobs", type=int, default=1, help="scenes at once (processes)")
    return parser.parse_args(argv)


def scenes_folder(args) -> Path:
    """Where bench paper keeps the scenes of ``args.size`` under ``args.work``."""
    return Path(args.work) / size_text(args.size) / "scenes"


def finish(lines: list[str], args) -> int:
    """Print the report and write it to ``args.output`` if given."""
    print("\n".join(lines))
    if args.output:
        atomic_write_text(Path(args.output), "\n".join(lines) + "\n")
    return 0


def report(results: dict, argv, minutes: float) -> list[str]:
    lines = [
        "# What a hidden-surface fill could gain at most: bench paper's object scenes",
        "",
        f"Command: `python benchmarks/hidden_fill_bound.py {' '.join(argv)}`; {minutes:.1f} min. "
        "Frame 1, left view, true motion, occlusion-aware homography operator (bilinear), "
        "alpha 0.001, one observation. Per cell: PSNR dB / mean squared error in the gt/mixed "
        "pixels x 1000 (2.5 % border). The oracle rows use the true values of the hidden "
        "samples, which no deblurrer has: an upper bound of what filling them can gain.",
        "",
        "| scene | hidden px | " + " | ".join(ROWS) + " |",
        "|---|---|" + "---|" * len(ROWS),
    ]
    shares = {name: [f"{100 * r['hidden_share']:.1f} %"] for name, r in results.items()}
    lines += score_rows(results, ROWS, shares)
    lines += [
        "",
        "Blur model error `|A I - B|^2` x 1000 at the true sharp frame, in mixed pixels that show "
        "a hidden surface during the exposure / that do not:",
        "",
        "| scene | today | oracle fill |",
        "|---|---|---|",
    ]
    for name, r in results.items():
        pairs = (r["model today"], r["model oracle"])
        cells = [f"{1000 * a:.2f} / {1000 * b:.2f}" for a, b in pairs]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    args = parse(argv, __doc__.split("\n", 1)[0])
    names = object_names(args)
    folder = scenes_folder(args)
    settings = DeblurSettings(
        motion_source="gt", boundary_weights="none", observations="single",
        interpolation="bilinear", alpha=PAPER_ALPHA,
    )  # fmt: skip
    start = time.perf_counter()
    paper_bench.render_missing(folder, names, args.size)
    results = {}
    for name in names:
        results[name] = evaluate(folder / name, name, settings)
        print(name, " ".join(f"{results[name][k][0]:.2f}" for k in ROWS), flush=True)
    return finish(report(results, sys.argv[1:], (time.perf_counter() - start) / 60), args)


if __name__ == "__main__":
    sys.exit(main())
