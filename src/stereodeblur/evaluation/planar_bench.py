"""``stereodeblur bench planar``: the paper's Table 2 on physically rendered planes.

For every planar scene and size: PSNR and SSIM of the blurred input, of the
frame deblurred with ground-truth 2D displacement kernels and with homography
kernels from the true motion and from the estimated scene flow (the default
pipeline), plus the trajectory curvature (largest distance in
px between a pixel's true path during the exposure and the straight line the
displacement model assumes). Metrics skip a border of 2.5 % of the width, where
content enters the view from outside.
"""

from __future__ import annotations

import json
import os
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import InputError
from ..progress import ProgressCallback, report

FRAME = 1
SIZES = ((320, 240), (640, 480))


@dataclass(frozen=True)
class PlanarRow:
    """One scene at one size."""

    scene: str
    size: str
    curvature_px: float
    psnr_blurred: float
    ssim_blurred: float
    psnr_displacement: float
    ssim_displacement: float
    psnr_homography: float
    ssim_homography: float
    psnr_sceneflow: float
    ssim_sceneflow: float
    seconds: float


def evaluate_scene(
    root: Path, name: str, size: str, *, progress: ProgressCallback | None = None
) -> PlanarRow:
    """Deblur frame 1 of a rendered planar scene with both kernel types and the scene flow."""
    from ..io.scene import open_scene
    from ..pipeline import DeblurSettings, deblur_frame
    from ..synth.planar import curvature_px, planar_setup
    from .metrics import border_for, psnr, ssim

    t0 = time.perf_counter()
    scene = open_scene(root)
    sharp = scene.read_gt_sharp("left", FRAME)
    border = border_for(sharp.shape[1])
    results = {}
    for key, kernels, source in (
        ("displacement", "displacement", "gt"),
        ("homography", "homography", "gt"),
        ("sceneflow", "homography", "sceneflow"),
    ):
        settings = DeblurSettings(kernels=kernels, motion_source=source)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # scene-flow warnings are not the benchmark's
            results[key] = deblur_frame(scene, FRAME, settings=settings, progress=progress).image
    blurred = scene.read_frame("left", FRAME)
    w, h = (int(v) for v in size.split("x"))
    curvature = curvature_px(planar_setup(name, size=(w, h)), FRAME).max_px
    return PlanarRow(
        scene=name,
        size=size,
        curvature_px=float(curvature),
        psnr_blurred=psnr(blurred, sharp, border=border),
        ssim_blurred=ssim(blurred, sharp, border=border),
        psnr_displacement=psnr(results["displacement"], sharp, border=border),
        ssim_displacement=ssim(results["displacement"], sharp, border=border),
        psnr_homography=psnr(results["homography"], sharp, border=border),
        ssim_homography=ssim(results["homography"], sharp, border=border),
        psnr_sceneflow=psnr(results["sceneflow"], sharp, border=border),
        ssim_sceneflow=ssim(results["sceneflow"], sharp, border=border),
        seconds=time.perf_counter() - t0,
    )


def format_table(rows: list[PlanarRow]) -> str:
    """Markdown table in the layout of the paper's Table 2."""
    lines = [
        "| scene | size | curvature (px) | blurred PSNR / SSIM | gt 2D displacement PSNR / SSIM "
        "| 3D homographies PSNR / SSIM | homography - displacement (dB) "
        "| scene flow PSNR / SSIM | scene flow - gt (dB) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.scene} | {r.size} | {r.curvature_px:.2f} | {r.psnr_blurred:.2f} / "
            f"{r.ssim_blurred:.3f} | {r.psnr_displacement:.2f} / {r.ssim_displacement:.3f} | "
            f"**{r.psnr_homography:.2f}** / {r.ssim_homography:.3f} | "
            f"{r.psnr_homography - r.psnr_displacement:+.2f} | "
            f"{r.psnr_sceneflow:.2f} / {r.ssim_sceneflow:.3f} | "
            f"{r.psnr_sceneflow - r.psnr_homography:+.2f} |"
        )
    return "\n".join(lines)


def summary(rows: list[PlanarRow]) -> str:
    """The checks the issue asks for, as sentences."""
    import numpy as np

    gain = np.array([r.psnr_homography - r.psnr_blurred for r in rows])
    diff = np.array([r.psnr_homography - r.psnr_displacement for r in rows])
    curved = np.array([r.curvature_px > 2 for r in rows])
    estimated = np.array([r.psnr_sceneflow - r.psnr_homography for r in rows])
    return "\n".join(
        [
            f"homography >= displacement - 0.05 dB on {np.sum(diff >= -0.05)}/{len(rows)} rows",
            f"homography >= displacement + 0.5 dB where curvature > 2 px: "
            f"{np.sum(diff[curved] >= 0.5)}/{curved.sum()} rows",
            f"every homography result above its input: {bool(np.all(gain > 0))}; "
            f"mean gain {gain.mean():+.2f} dB",
            f"estimated scene flow within 1 dB of the true motion on "
            f"{np.sum(estimated >= -1.0)}/{len(rows)} rows (worst {estimated.min():+.2f} dB)",
        ]
    )


@dataclass(frozen=True)
class PlanarBench:
    """A run of :func:`run_planar_bench`: its rows, the Markdown table and checks, the files."""

    rows: tuple[PlanarRow, ...]
    table: str
    summary: str
    markdown: Path
    json: Path


def run_planar_bench(
    work: str | os.PathLike,
    *,
    sizes: Sequence[tuple[int, int]] = SIZES,
    scenes: Sequence[str] | None = None,
    progress: ProgressCallback | None = None,
) -> PlanarBench:
    """Render the missing planar scenes under ``work``, evaluate them, write the table.

    Parameters
    ----------
    work : path
        Folder for the rendered scenes (``WORK/WxH/NAME``) and the results
        (``WORK/planar.md``, ``WORK/planar.json``).
    sizes : sequence of (width, height)
    scenes : sequence of str, optional
        Planar motion names (default: all, :data:`~stereodeblur.synth.planar.PLANAR_MOTIONS`).
    progress : callable, optional
        Receives :class:`~stereodeblur.progress.Progress` reports.
    """
    from ..io.outputs import atomic_write_text
    from ..synth.planar import PLANAR_MOTIONS, write_planar_set

    work = Path(work)
    names = list(scenes) if scenes else list(PLANAR_MOTIONS)
    unknown = [n for n in names if n not in PLANAR_MOTIONS]
    if unknown:
        raise InputError(
            f"unknown planar scene {unknown[0]!r}: expected one of {', '.join(PLANAR_MOTIONS)}",
            parameter="scenes",
        )
    rows = []
    for width, height in sizes:
        size = f"{width}x{height}"
        base = work / size
        missing = [n for n in names if not (base / n / "camera.json").is_file()]
        if missing:
            report(progress, f"rendering {len(missing)} planar scene(s) at {size}")
            write_planar_set(base, size=(width, height), names=missing, progress=progress)
        for k, name in enumerate(names):
            report(progress, f"{size} {name}", k, len(names))
            rows.append(evaluate_scene(base / name, name, size))
    table, checks = format_table(rows), summary(rows)
    work.mkdir(parents=True, exist_ok=True)
    markdown = atomic_write_text(work / "planar.md", table + "\n\n" + checks + "\n")
    data = atomic_write_text(work / "planar.json", json.dumps([asdict(r) for r in rows], indent=1))
    return PlanarBench(tuple(rows), table, checks, markdown, data)
