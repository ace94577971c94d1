"""Calibrate the ``--alpha auto`` rule: best prior weight against the estimated noise level.

Run from the repository root::

    python benchmarks/calibrate_alpha.py --output sweep.jsonl     # sweep, evaluate, fit, print
    python benchmarks/calibrate_alpha.py --input benchmarks/results/calibrate_alpha.jsonl
    python benchmarks/calibrate_alpha.py --input sweep.jsonl --auto-only --output new.jsonl

The sweep is 1536 deblurs at 320 x 240 (one process per core, single-threaded numba): about
8 minutes on 16 cores, several hours on 2. ``--input`` reuses the rows of a previous
``--output`` (JSON lines, appended as they finish, so an interrupted run resumes) and runs
only what is missing; with ``--auto-only`` it reruns only ``alpha = auto`` (after a change of
the rule). ``benchmarks/results/calibrate_alpha.jsonl`` holds the sweep behind the constants
of :mod:`stereodeblur.deconv.noise`, ``benchmarks/results/calibrate_alpha.txt`` its table.

Test problems: eight natural images from ``skimage.data`` (half decoded to linear values as
the synthetic scenes are, half left sRGB-encoded), each framed two ways (the whole image
resized to the view; its centre at 1.6 px per texel, like the synthetic scenes' textures),
blurred by three exact homography operators of one slightly tilted plane 3 m away
(:func:`stereodeblur.blur.homography.homography_blur` on a hand-made :class:`SceneFlow`: a
sideways translation with yaw and pitch, a roll about the optical axis, an approach with
pitch; longest blur 10-21 px), plus Gaussian noise ``sigma`` in {0, 0.003, 0.01, 0.02},
clipped to [0, 1]: 192 cases. Every case is deblurred by
:func:`stereodeblur.deconv.deblur_irls` with the paper's solver settings (10 IRLS x 25 CG,
``w = 1``) for every ``alpha`` of a log grid from 1e-5 to 1e-2, and once with
``auto_alpha(blurred)``.

Printed: per case the noise estimate, the PSNR for each ``alpha``, the best ``alpha`` of the
issue's grid {3e-5, 1e-4, 3e-4, 1e-3, 3e-3}, the rule's ``alpha`` and its loss in dB against
that best (measured with a real deblur, not interpolated; negative where the rule beats the
grid); a summary per ``sigma`` and per framing, with the loss of the paper's fixed 0.001; the
fit of ``alpha = clip(c * sigma_hat^p, alpha_min, alpha_max)`` that minimises the mean loss
(PSNR interpolated linearly in ``log alpha``), and the loss of fits that leave one image
out, evaluated on that image.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

IMAGES = (
    ("astronaut", True),
    ("coffee", False),
    ("camera", True),
    ("chelsea", False),
    ("rocket", True),
    ("brick", False),
    ("grass", True),
    ("gravel", False),
)
"""``(skimage.data name, decode sRGB to linear)``."""

# Twists (vx, vy, vz, wx, wy, wz) per frame interval of a plane 3 m away; 20 fps, 0.04 s
# exposure (duty cycle 0.8), focal length 0.8 * width as in the synthetic scenes.
MOTIONS = {
    "lateral": (0.08, 0.03, 0.0, 0.005, 0.015, 0.0),
    "roll": (0.0, 0.0, 0.0, 0.0, 0.0, 0.08),
    "approach": (0.0, 0.0, -0.3, 0.01, 0.0, 0.0),
}
FRAMINGS = {"whole": None, "zoom": 1.6}
"""``whole``: the whole image resized to the view (aspect ratio not kept, about 0.6 px per
texel); ``zoom``: its central part at 1.6 px per texel, like the synthetic scenes' textures."""
SIGMAS = (0.0, 0.003, 0.01, 0.02)
ALPHAS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
TARGET_GRID = (3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
"""The grid of the issue's target: ``--alpha auto`` within 0.5 dB of its best."""


def load_image(name: str, linear: bool, size: tuple[int, int], framing: str) -> np.ndarray:
    from skimage import data, transform

    from stereodeblur.synth.textures import srgb_to_linear

    image = np.asarray(getattr(data, name)(), dtype=np.float64) / 255.0
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    image = image[..., :3]
    if linear:
        image = srgb_to_linear(image)
    height, width = size
    magnification = FRAMINGS[framing]
    if magnification is not None:
        rows, cols = image.shape[:2]
        keep = min(rows / height, cols / width) / magnification  # texels per pixel
        crop_rows, crop_cols = round(height * keep), round(width * keep)
        top, left = (rows - crop_rows) // 2, (cols - crop_cols) // 2
        image = image[top : top + crop_rows, left : left + crop_cols]
    return transform.resize(image, (height, width, 3), anti_aliasing=True).astype(np.float32)


@functools.cache
def operator(motion: str, size: tuple[int, int]):
    from stereodeblur.blur.homography import homography_blur
    from stereodeblur.geometry.camera import Exposure, StereoCamera
    from stereodeblur.sceneflow.model import SceneFlow

    height, width = size
    focal = 0.8 * width
    K = np.array([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1]])
    normal = np.array([0.02, -0.03, 1.0]) / 3.0  # tilted by about 2 degrees, 3 m away
    flow = SceneFlow(
        StereoCamera(K, 0.12),
        labels=np.zeros(size, np.int32),
        normals=normal[None],
        twists=np.array(MOTIONS[motion], dtype=np.float64)[None],
        occlusion=np.zeros(size, bool),
    )
    exposure = Exposure(frame_rate=20.0, exposure=0.04)
    extent = float(np.hypot(*np.moveaxis(flow.flow(), -1, 0)).max() * exposure.duty_cycle)
    return homography_blur(flow, exposure), extent


def problem(image_index: int, framing: str, motion: str, sigma_index: int, size):
    name, linear = IMAGES[image_index]
    sharp = load_image(name, linear, size, framing)
    blur, extent = operator(motion, size)
    seed = 1000 * image_index + 10 * list(MOTIONS).index(motion) + sigma_index
    rng = np.random.default_rng(seed)
    blurred = blur.forward(sharp) + rng.normal(0.0, SIGMAS[sigma_index], sharp.shape)
    return sharp, np.clip(blurred, 0, 1).astype(np.float32), blur, extent


def key(row: dict) -> tuple:
    """The case of a result row: ``(image, framing, motion, sigma index)``."""
    return (row["image"], row["framing"], row["motion"], row["sigma"])


def run_task(task) -> dict:
    """Deblur one case with one alpha (``alpha = None``: the package's ``auto_alpha``)."""
    image_index, framing, motion, sigma_index, alpha, size = task
    from stereodeblur.deconv import deblur_irls
    from stereodeblur.deconv.noise import auto_alpha, estimate_noise_sigma
    from stereodeblur.evaluation.metrics import psnr

    sharp, blurred, blur, extent = problem(image_index, framing, motion, sigma_index, size)
    used = auto_alpha(blurred) if alpha is None else alpha
    result = deblur_irls(blurred, blur, alpha=used)
    return {
        "image": image_index,
        "framing": framing,
        "motion": motion,
        "sigma": sigma_index,
        "alpha": alpha,
        "alpha_used": used,
        "psnr": psnr(result.image, sharp),
        "psnr_blurred": psnr(blurred, sharp),
        "sigma_hat": estimate_noise_sigma(blurred),
        "extent": extent,
    }


def sweep(size, workers: int, images, *, done: list[dict], output: str | None) -> list[dict]:
    """Run every (case, alpha) task not in ``done``; append each row to ``output`` (JSON lines)."""
    cases = list(itertools.product(images, FRAMINGS, MOTIONS, range(len(SIGMAS))))
    have = {key(r) + (r["alpha"],) for r in done}
    tasks = [
        (*case, alpha, size)
        for alpha in (None, *ALPHAS)
        for case in cases
        if (*case, alpha) not in have
    ]
    rows = list(done)
    if not tasks:
        return rows
    start = time.perf_counter()
    run_task(
        (images[0], "whole", "roll", 0, 1e-3, (16, 16))
    )  # compile the numba kernels once, here
    from stereodeblur.clip.worker import watch_parent

    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(
        workers, mp_context=context, initializer=watch_parent, initargs=(os.getpid(),)
    )  # workers end with this process
    with pool:
        futures = [pool.submit(run_task, task) for task in tasks]
        for future in as_completed(futures):
            rows.append(future.result())
            if output:
                with open(output, "a") as handle:
                    handle.write(json.dumps(rows[-1]) + "\n")
    print(f"# {len(tasks)} deblurs in {time.perf_counter() - start:.0f} s on {workers} workers")
    return rows


def interpolated(psnrs: np.ndarray, log_alpha: np.ndarray) -> np.ndarray:
    """PSNR at ``log_alpha`` (per case), piecewise linear in ``log10 alpha`` over ALPHAS."""
    grid = np.log10(ALPHAS)
    return np.array([np.interp(la, grid, row) for row, la in zip(psnrs, log_alpha, strict=True)])


def fit_rule(sigma_hat, psnrs, best, alpha_mins=(1e-5, 3e-5)):
    """Grid search of the rule minimising the mean interpolated loss against ``best``.

    Returns ``(loss, c, p, alpha_min, alpha_max)`` of ``alpha = clip(c sigma_hat^p, ...)``.
    """
    best_fit = None
    for alpha_min, alpha_max in itertools.product(alpha_mins, (3e-3, 1e-2)):
        for power in np.arange(0.5, 3.01, 0.125):
            for log_c in np.arange(-4.0, 4.01, 0.05):
                alpha = 10**log_c * np.maximum(sigma_hat, 1e-12) ** power
                alpha = np.clip(alpha, alpha_min, alpha_max)
                loss = float(np.mean(best - interpolated(psnrs, np.log10(alpha))))
                if best_fit is None or loss < best_fit[0]:
                    best_fit = (loss, 10**log_c, power, alpha_min, alpha_max)
    return best_fit


def report(rows: list[dict]) -> None:
    from stereodeblur.deconv import noise

    by = {key(r) + (r["alpha"],): r for r in rows}
    cases = sorted({key(r) for r in rows})
    cases = [c for c in cases if all((*c, a) in by for a in (None, *ALPHAS))]
    target = [ALPHAS.index(a) for a in TARGET_GRID]
    header = (
        f"{'image':>10} {'frame':>5} {'motion':>8} {'ext px':>6} {'sigma':>5} {'s_hat':>6} "
        f"{'blurred':>7} "
        + " ".join(f"{a:>7.0e}" for a in ALPHAS)
        + f" {'best a':>7} {'auto a':>7} {'auto':>6} {'loss':>5}"
    )
    print(header)
    psnrs, best, sigma_hat, losses, sigmas, images, framings = [], [], [], [], [], [], []
    for case in cases:
        image, framing, motion, sigma = case
        row = [by[(*case, a)]["psnr"] for a in ALPHAS]
        auto = by[(*case, None)]
        k = max(target, key=lambda i: row[i])
        loss = row[k] - auto["psnr"]
        psnrs.append(row)
        best.append(row[k])
        sigma_hat.append(auto["sigma_hat"])
        losses.append(loss)
        sigmas.append(SIGMAS[sigma])
        images.append(image)
        framings.append(framing)
        print(
            f"{IMAGES[image][0]:>10} {framing:>5} {motion:>8} {auto['extent']:6.1f} "
            f"{SIGMAS[sigma]:5.3f} "
            f"{auto['sigma_hat']:6.4f} {auto['psnr_blurred']:7.2f} "
            + " ".join(f"{v:7.2f}" for v in row)
            + f" {ALPHAS[k]:7.0e} {auto['alpha_used']:7.1e} {auto['psnr']:6.2f} {loss:5.2f}"
        )
    psnrs, best, sigma_hat = np.array(psnrs), np.array(best), np.array(sigma_hat)
    losses, sigmas, images = np.array(losses), np.array(sigmas), np.array(images)
    framings = np.array(framings)
    fixed = best - psnrs[:, ALPHAS.index(1e-3)]

    print("\nPer sigma (mean over images and motions; loss = best of the target grid - method):")
    print(
        f"{'sigma':>6} {'s_hat':>13} {'best alpha (geo. mean)':>22} {'auto loss':>9} "
        f"{'max':>5} {'a=1e-3 loss':>11}"
    )
    for s in SIGMAS:
        m = sigmas == s
        chosen = [ALPHAS[max(target, key=lambda i, r=r: r[i])] for r in psnrs[m]]
        print(
            f"{s:6.3f} {sigma_hat[m].min():6.4f}-{sigma_hat[m].max():6.4f} "
            f"{10 ** np.mean(np.log10(chosen)):22.1e} {losses[m].mean():9.2f} "
            f"{losses[m].max():5.2f} {fixed[m].mean():11.2f}"
        )
    for framing in FRAMINGS:
        m = framings == framing
        print(
            f"{framing:>6} {'':>13} {'':>22} {losses[m].mean():9.2f} "
            f"{losses[m].max():5.2f} {fixed[m].mean():11.2f}"
        )
    print(
        f"{'all':>6} {'':>13} {'':>22} {losses.mean():9.2f} {losses.max():5.2f} "
        f"{fixed.mean():11.2f}"
    )
    print(
        f"\nPackage rule: alpha = clip({noise.ALPHA_SCALE:g} * sigma_hat^{noise.ALPHA_POWER:g}, "
        f"{noise.ALPHA_MIN:g}, {noise.ALPHA_MAX:g}); measured mean loss {losses.mean():.2f} dB"
    )

    for alpha_mins in ((1e-5, 3e-5), (3e-5,)):
        loss, scale, power, alpha_min, alpha_max = fit_rule(sigma_hat, psnrs, best, alpha_mins)
        print(
            f"Fit on all cases: alpha = clip({scale:.3g} * sigma_hat^{power:g}, {alpha_min:g}, "
            f"{alpha_max:g}), interpolated mean loss {loss:.2f} dB"
        )
    held_out = []
    for image in np.unique(images) if len(np.unique(images)) > 1 else []:
        train, test = images != image, images == image
        _, c, p, low, high = fit_rule(sigma_hat[train], psnrs[train], best[train])
        alpha = np.clip(c * np.maximum(sigma_hat[test], 1e-12) ** p, low, high)
        held_out.extend(best[test] - interpolated(psnrs[test], np.log10(alpha)))
    if held_out:
        print(
            f"Leave-one-image-out fits (interpolated): mean loss {np.mean(held_out):.2f} dB, "
            f"max {np.max(held_out):.2f} dB"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument("--output", help="append the raw rows to this file (JSON lines)")
    parser.add_argument("--input", help="rows of a previous --output: rerun only missing tasks")
    parser.add_argument("--auto-only", action="store_true", help="rerun only alpha = auto")
    parser.add_argument("--images", type=int, help="use only the first N images (smoke test)")
    args = parser.parse_args()
    os.environ["NUMBA_NUM_THREADS"] = "1"  # one process per core instead (set before import)
    width, height = (int(v) for v in args.size.split("x"))
    done = []
    if args.input:
        with open(args.input) as handle:
            done = [json.loads(line) for line in handle if line.strip()]
        if args.auto_only:
            done = [r for r in done if r["alpha"] is not None]
    images = list(range(len(IMAGES) if args.images is None else args.images))
    rows = sweep((height, width), args.workers, images, done=done, output=args.output)
    report(rows)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
