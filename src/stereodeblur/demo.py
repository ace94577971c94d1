"""The demo: render a small blurred stereo scene, deblur one frame, compare with the truth."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .progress import ProgressCallback, report

if TYPE_CHECKING:
    from .settings import DeblurSettings

DEMO_SCENE = "yaw"
DEMO_FRAME = 1
DEMO_SIZE = (320, 240)


@dataclass(frozen=True)
class DemoResult:
    """What :func:`run_demo` did: the scene, the settings, the PSNRs and the picture written."""

    scene: str
    size: tuple[int, int]
    settings: DeblurSettings
    psnr_blurred: float
    psnr_deblurred: float
    picture: Path


def side_by_side(images: list[np.ndarray], *, gap: int = 4) -> np.ndarray:
    """Images of one size next to each other on a white background, RGB float32."""
    rgb = [np.repeat(i[..., None], 3, axis=2) if i.ndim == 2 else i for i in images]
    H, W = rgb[0].shape[:2]
    out = np.ones((H, len(rgb) * W + (len(rgb) - 1) * gap, 3), dtype=np.float32)
    for k, img in enumerate(rgb):
        out[:, k * (W + gap) : k * (W + gap) + W] = np.clip(img, 0, 1)
    return out


def run_demo(
    output: str | os.PathLike,
    *,
    size: tuple[int, int] = DEMO_SIZE,
    settings: DeblurSettings | None = None,
    progress: ProgressCallback | None = None,
) -> DemoResult:
    """Render the demo scene, deblur frame 1 of its left view, write the comparison picture.

    Parameters
    ----------
    output : path
        Folder for ``scene/`` (the rendered scene), ``deblurred/`` and ``demo.png``
        (blurred | deblurred | sharp, sRGB).
    size : (width, height)
    settings : DeblurSettings, optional
        Default: ``DeblurSettings()``.
    progress : callable, optional
        Receives :class:`~stereodeblur.progress.Progress` reports.
    """
    from .evaluation.metrics import border_for, psnr
    from .io.formats import linear_to_srgb, write_png
    from .io.scene import SceneWriter, open_scene
    from .pipeline import DeblurSettings, deblur_frame
    from .synth.planar import make_planar_scene, write_rendered_scene

    output = Path(output)
    settings = DeblurSettings() if settings is None else settings
    report(progress, f"rendering the '{DEMO_SCENE}' planar scene at {size[0]}x{size[1]}")
    rendered = make_planar_scene(DEMO_SCENE, size=size, num_frames=3)
    scene_dir = output / "scene"
    write_rendered_scene(rendered, scene_dir, overwrite=True)
    scene = open_scene(scene_dir)
    result = deblur_frame(scene, DEMO_FRAME, settings=settings, progress=progress)
    SceneWriter(output / "deblurred", scene.info, overwrite=True).write_frame(
        "left", DEMO_FRAME, result.image
    )
    sharp = scene.read_gt_sharp("left", DEMO_FRAME)
    border = border_for(size[0])
    picture = output / "demo.png"
    # The scene holds linear values; the picture is sRGB-encoded for viewing.
    panel = side_by_side([result.blurred, result.image, sharp])
    write_png(picture, linear_to_srgb(panel), bit_depth=8)
    return DemoResult(
        scene=DEMO_SCENE,
        size=tuple(size),
        settings=settings,
        psnr_blurred=psnr(result.blurred, sharp, border=border),
        psnr_deblurred=psnr(result.image, sharp, border=border),
        picture=picture,
    )
