"""``stereodeblur demo``: render a small blurred stereo scene, deblur it, show the result."""

from __future__ import annotations

from pathlib import Path

import numpy as np

DEMO_SCENE = "yaw"
DEMO_FRAME = 1


def side_by_side(images: list[np.ndarray], *, gap: int = 4) -> np.ndarray:
    """Images of one size next to each other on a white background, RGB float32."""
    rgb = [np.repeat(i[..., None], 3, axis=2) if i.ndim == 2 else i for i in images]
    H, W = rgb[0].shape[:2]
    out = np.ones((H, len(rgb) * W + (len(rgb) - 1) * gap, 3), dtype=np.float32)
    for k, img in enumerate(rgb):
        out[:, k * (W + gap) : k * (W + gap) + W] = np.clip(img, 0, 1)
    return out


def run_demo(output: Path, *, size=(320, 240), progress=None) -> int:
    """Render, deblur and compare; writes ``output/demo.png`` and prints the PSNRs."""
    from .cli import _default_motion_source
    from .evaluation.metrics import psnr
    from .io.formats import linear_to_srgb, write_png
    from .io.scene import SceneWriter, open_scene
    from .pipeline import DeblurSettings, deblur_frame
    from .synth.planar import make_planar_scene, write_rendered_scene

    say = progress or (lambda message: None)
    say(f"rendering the '{DEMO_SCENE}' planar scene at {size[0]}x{size[1]}")
    rendered = make_planar_scene(DEMO_SCENE, size=size, num_frames=3)
    scene_dir = output / "scene"
    write_rendered_scene(rendered, scene_dir, overwrite=True)
    scene = open_scene(scene_dir)
    settings = DeblurSettings(motion_source=_default_motion_source())
    result = deblur_frame(scene, DEMO_FRAME, settings=settings, progress=say)
    SceneWriter(output / "deblurred", scene.info, overwrite=True).write_frame(
        "left", DEMO_FRAME, result.image
    )
    sharp = scene.read_gt_sharp("left", DEMO_FRAME)
    border = max(4, round(0.025 * size[0]))
    before = psnr(result.blurred, sharp, border=border)
    after = psnr(result.image, sharp, border=border)
    picture = output / "demo.png"
    # The scene holds linear values; the picture is sRGB-encoded for viewing.
    panel = side_by_side([result.blurred, result.image, sharp])
    write_png(picture, linear_to_srgb(panel), bit_depth=8)
    print(
        f"scene: {DEMO_SCENE}, {size[0]}x{size[1]}, motion from {settings.motion_source}, "
        f"{settings.kernels} kernels"
    )
    print(f"PSNR blurred   {before:6.2f} dB")
    print(f"PSNR deblurred {after:6.2f} dB  ({after - before:+.2f} dB)")
    print(f"picture (blurred | deblurred | sharp): {picture}")
    return 0
