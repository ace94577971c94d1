"""Would an extended sharp domain remove the loss near the image edges? (issue 12, stop 38)

Run from the repository root after ``calibrate_defaults.py`` has rendered the scenes::

    python benchmarks/study_extended_domain.py --split train --scenes 10 --size 320x240

Today's operator samples the sharp frame on the blurred frame's grid and replicates its edge
pixels for the samples of an exposure that leave it. The alternative solves for a sharp image
``margin`` px larger on every side: the true motion's scene flow is carried to the padded
canvas (principal point moved by ``margin``, labels and flows repeated at the edges), the
canvas's operator is built as usual, the data weight is 0 on the padding (only the prior
fills it), and the result is cropped. Both are solved with the same fixed alphas, 4 x 25
IRLS, data weight 1 and no further observations, so that only the border rule differs. PSNR is
reported over the scored frame and in bands by distance to the image edge.
Written: ``--output`` (markdown).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

from stereodeblur.io.outputs import atomic_write_text  # noqa: E402

ALPHAS = (1e-4, 1e-3)
BANDS = ((24, 40), (40, None))  # px from the edge; the first band starts at the scored border


def padded(array: np.ndarray, margin: int) -> np.ndarray:
    """``array`` with ``margin`` px of its edge values repeated on every side."""
    pad = ((margin, margin), (margin, margin)) + ((0, 0),) * (array.ndim - 2)
    return np.pad(array, pad, mode="edge")


def padded_motion(motion, margin: int):
    """The :class:`~stereodeblur.pipeline.FrameMotion` ``motion`` on a canvas ``margin`` px
    larger on every side."""
    from stereodeblur.geometry.camera import StereoCamera

    sf = motion.sceneflow
    K = sf.camera.K.copy()
    K[:2, 2] += margin
    sceneflow = replace(
        sf,
        camera=StereoCamera(K, sf.camera.baseline),
        labels=padded(sf.labels, margin),
        occlusion=padded(sf.occlusion, margin),
    )
    return replace(
        motion,
        sceneflow=sceneflow,
        flow_forward=padded(motion.flow_forward, margin),
        flow_backward=padded(motion.flow_backward, margin),
        boundary_flow=None,
    )


def band_psnrs(image, truth, border: int) -> list[float]:
    """PSNR over the scored frame, then in each band of :data:`BANDS` (the first from
    ``border``)."""
    from stereodeblur.evaluation.metrics import masked_mse

    H, W = truth.shape[:2]
    rows, cols = np.mgrid[0:H, 0:W]
    distance = np.minimum.reduce([rows, cols, H - 1 - rows, W - 1 - cols])
    out = []
    for low, high in ((border, None), (border, BANDS[0][0]), *BANDS):
        inside = (distance >= low) & (distance < (high or H + W))
        out.append(float(10 * np.log10(1.0 / masked_mse(image, truth, inside))))
    return out


def study_scene(scene_dir: Path, results: Path) -> list[tuple]:
    """Rows ``(alpha, rule, psnrs)`` of one scene: the blurred input, then per alpha today's
    operator and the extended domain."""
    from stereodeblur.deconv.irls import deblur_irls
    from stereodeblur.evaluation.motion_cache import cached_motion
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline.operator import build_operator
    from stereodeblur.settings import DeblurSettings

    scene = open_scene(scene_dir)
    truth = scene.read_gt_sharp("left", protocol.FRAME).astype(np.float64)
    blurred = scene.read_frame("left", protocol.FRAME).astype(np.float32)
    border = protocol.border_of(truth.shape[1])
    motion, _, _ = cached_motion(scene, "gt", protocol.unmoved("gt"), results)
    settings = DeblurSettings(motion_source="gt", boundary_weights="none", observations="single")
    flow = np.hypot(
        *np.moveaxis(np.concatenate([motion.flow_forward, motion.flow_backward]), -1, 0)
    )
    margin = int(np.ceil(flow.max())) + 4  # every sample of the exposure on the canvas
    exposure = scene.info.exposure
    plain = build_operator(motion, exposure, settings)
    extended = build_operator(padded_motion(motion, margin), exposure, settings)
    weights = np.zeros(extended.shape, np.float32)
    weights[margin:-margin, margin:-margin] = 1.0
    rows = [(None, "blurred input", band_psnrs(blurred, truth, border), margin)]
    for alpha in ALPHAS:
        solve = {"alpha": alpha, "num_irls": settings.num_irls, "num_cg": settings.num_cg}
        image = deblur_irls(blurred, plain, **solve).image
        rows.append((alpha, "edges replicated", band_psnrs(image, truth, border), margin))
        image = deblur_irls(padded(blurred, margin), extended, weights=weights, **solve).image
        image = image[margin:-margin, margin:-margin]
        rows.append((alpha, "extended domain", band_psnrs(image, truth, border), margin))
    return rows


def report(table: dict, args, minutes: float, border: int) -> str:
    bands = [
        f"{border}-{BANDS[0][0]} px",
        *(f"{lo}-{hi} px" if hi else f">= {lo} px" for lo, hi in BANDS),
    ]
    lines = [
        f"# Extended sharp domain: {args.split} split, {args.size}, {len(table)} scenes",
        "",
        f"Command: `python benchmarks/study_extended_domain.py --split {args.split} --scenes "
        f"{args.scenes} --skip {args.skip} --size {args.size}`; {minutes:.1f} min (one core). The "
        "true motion, data weight 1, single observation, fixed alphas, 4 x 25 IRLS; PSNR (dB) over "
        "the scored frame and by distance to the image edge.",
        "",
        "| scene | margin px | alpha | border rule | frame | " + " | ".join(bands) + " |",
        "|---|---|---|---|---|" + "---|" * len(bands),
    ]
    gains = {alpha: [] for alpha in ALPHAS}
    for name, rows in table.items():
        for alpha, rule, psnrs, margin in rows:
            cells = " | ".join(f"{p:.2f}" for p in psnrs)
            lines.append(f"| {name} | {margin} | {alpha or '-'} | {rule} | {cells} |")
        by = {(a, r): p for a, r, p, _ in rows}
        for alpha in ALPHAS:
            gains[alpha].append(
                np.subtract(by[alpha, "extended domain"], by[alpha, "edges replicated"])
            )
    lines += [
        "",
        "Extended domain minus edges replicated (dB), mean / least / most over the scenes:",
        "",
    ]
    lines += ["| alpha | frame | " + " | ".join(bands) + " |", "|---|---|" + "---|" * len(bands)]
    for alpha, rows in gains.items():
        rows = np.array(rows)
        cells = " | ".join(
            f"{rows[:, k].mean():+.2f} / {rows[:, k].min():+.2f} / {rows[:, k].max():+.2f}"
            for k in range(rows.shape[1])
        )
        lines.append(f"| {alpha:g} | {cells} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("train", "test"), default="train")
    parser.add_argument("--scenes", type=int, default=10)
    parser.add_argument("--skip", type=int, default=0)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--work", type=Path, default=Path("/tmp/calib/work"))
    parser.add_argument("--output", type=Path)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    work = args.work / args.size
    start = time.perf_counter()
    table = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, seed in protocol.scene_list(args.split, args.scenes, protocol.KINDS, args.skip):
            scene_dir = protocol.ensure_scene(kind, seed, (width, height), work)
            table[scene_dir.name] = study_scene(scene_dir, work / "results" / scene_dir.name)
            print(scene_dir.name, flush=True)
    minutes = (time.perf_counter() - start) / 60
    text = report(table, args, minutes, protocol.border_of(width))
    output = args.output or Path(__file__).parent / "results" / (
        f"extended_domain_{args.split}_{args.size}.md"
    )
    atomic_write_text(output, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
