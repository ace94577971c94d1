"""
Deblurring a rendered scene
===========================

A textured plane a few metres in front of a stereo camera turns about the camera's vertical
axis, as if the camera yawed, blurred by a 0.04 s exposure (the scene of ``stereodeblur demo``,
here at 160x120 pixels). The scene is
rendered with its ground truth, written in the scene folder format, read back, and frame 1 of
its left view is deblurred with the default settings: the scene flow is estimated from the
blurred stereo frames, the blur operator built from its homographies, and the sharp frame
solved by IRLS.
"""

import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from stereodeblur.demo import DEMO_FRAME, DEMO_SCENE
from stereodeblur.evaluation.metrics import border_for, psnr
from stereodeblur.io import linear_to_srgb, open_scene
from stereodeblur.pipeline import DeblurSettings, deblur_frame
from stereodeblur.synth import make_planar_scene, write_rendered_scene

# %%
# Render the scene and write it as a scene folder
# -----------------------------------------------
# Three frames of both views, each the mean of 48 instants of the exposure, with the sharp
# frames, disparities and flows as ground truth under ``gt/``.

size = (160, 120)
folder = Path(tempfile.mkdtemp()) / DEMO_SCENE
write_rendered_scene(make_planar_scene(DEMO_SCENE, size=size, num_frames=3), folder)
scene = open_scene(folder)
print(scene.describe())

# %%
# Deblur one frame
# ----------------
# ``deblur_frame`` reads the frames it needs, estimates the motion, builds the blur operator
# and solves for the sharp frame. ``DeblurSettings()`` holds the defaults of the command line.

result = deblur_frame(scene, DEMO_FRAME, view="left", settings=DeblurSettings())
sharp = scene.read_gt_sharp("left", DEMO_FRAME)
border = border_for(size[0])  # PSNR skips 2.5 % of the width at the borders
scores = {
    "blurred": psnr(result.blurred, sharp, border=border),
    "deblurred": psnr(result.image, sharp, border=border),
}
print(", ".join(f"PSNR {name} {value:.2f} dB" for name, value in scores.items()))
print("seconds per stage:", {k: round(v, 1) for k, v in result.timings.items()})

# %%
# Blurred | deblurred | sharp
# ---------------------------
# The frames hold linear intensities; they are sRGB-encoded for display.

panels = [
    (f"blurred, {scores['blurred']:.1f} dB", result.blurred),
    (f"deblurred, {scores['deblurred']:.1f} dB", result.image),
    ("sharp (ground truth)", sharp),
]
fig, axes = plt.subplots(1, 3, figsize=(9, 2.7), layout="constrained")
for ax, (title, image) in zip(axes, panels, strict=True):
    ax.imshow(linear_to_srgb(np.clip(image, 0, 1)))
    ax.set_title(title, fontsize=10)
    ax.set_axis_off()

# %%
# Where the error is
# ------------------
# The absolute error against the sharp frame, averaged over the colour channels, on one
# scale for both.

errors = [np.abs(image - sharp).mean(axis=2) for image in (result.blurred, result.image)]
top = float(max(e.max() for e in errors))
fig, axes = plt.subplots(1, 2, figsize=(7, 2.7), layout="constrained")
for ax, error, title in zip(axes, errors, ("blurred", "deblurred"), strict=True):
    shown = ax.imshow(error, cmap="magma", vmin=0, vmax=top)
    ax.set_title(f"|{title} - sharp|", fontsize=10)
    ax.set_axis_off()
fig.colorbar(shown, ax=axes, shrink=0.8)

shutil.rmtree(folder.parent)
