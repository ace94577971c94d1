"""
Scene flow and motion segments
==============================

The blur of every pixel comes from a piecewise-rigid scene flow: superpixels, each a 3D
plane with a rigid 3D motion, estimated from two blurred stereo frames. This example renders
a scene of moving boxes at 240x180 pixels, estimates its scene flow and compares its disparity
and optical flow with the ground truth. Flow is drawn with the Middlebury colour wheel (hue:
direction, saturation: length; the wheel is shown as a legend), disparity with the turbo map
(red near, blue far).
"""

import matplotlib.pyplot as plt
import numpy as np

from stereodeblur.io import linear_to_srgb
from stereodeblur.sceneflow import estimate_scene_flow
from stereodeblur.synth import make_object_scene
from stereodeblur.viz import (
    disparity_to_color,
    flow_to_color,
    mask_to_image,
    segment_overlay,
)

# %%
# Render two stereo frames and estimate the scene flow
# ----------------------------------------------------
# ``estimate_scene_flow`` takes frames t and t + 1 of both views and the stereo camera; it
# returns the scene flow of the left view at t and the initial correspondences it started
# from (semi-global matching disparity, DIS optical flow).

rendered = make_object_scene("boxes", size=(240, 180), num_frames=2)
left, right = rendered.frames["left"], rendered.frames["right"]
estimate = estimate_scene_flow(
    left[0], right[0], left[1], right[1], rendered.camera, exposure=rendered.exposure
)
sceneflow = estimate.sceneflow
print(f"{sceneflow.num_segments} segments, occluded share {sceneflow.occlusion.mean():.3f}")

# %%
# Motion segments
# ---------------
# Each superpixel (yellow boundaries) carries a plane and a rigid motion (a twist). The fusion
# lets neighbouring superpixels choose the same plane and motion, and the refinement fits that
# plane and motion to all of them together: each colour below is one such group, the
# background or a face of a box.

planes_and_motions = np.round(np.hstack([sceneflow.normals, sceneflow.twists]), 6)
_, group_of_segment = np.unique(planes_and_motions, axis=0, return_inverse=True)
groups = group_of_segment.reshape(-1)[sceneflow.labels]
print(f"{groups.max() + 1} planes with their rigid motions")

frame = linear_to_srgb(left[0])
fig, axes = plt.subplots(1, 3, figsize=(10, 2.8), layout="constrained")
axes[0].imshow(segment_overlay(frame, sceneflow.labels))
axes[0].set_title("superpixels", fontsize=10)
axes[1].imshow(groups, cmap="tab20", interpolation="nearest")
axes[1].set_title("planes with their motions", fontsize=10)
axes[2].imshow(mask_to_image(sceneflow.occlusion, frame))
axes[2].set_title("occluded at t + 1 (red)", fontsize=10)
for ax in axes:
    ax.set_axis_off()

# %%
# Disparity and flow against the ground truth
# -------------------------------------------
# The scene flow's disparity and flow are projections of its planes and motions; the true
# ones come with the rendered scene. Both rows use one colour scale.

true_disparity = rendered.disparity["left"][0]
true_flow = rendered.flow[0]
max_disparity = float(np.nanmax(true_disparity))
max_flow = float(np.nanmax(np.hypot(true_flow[..., 0], true_flow[..., 1])))
rows = [
    ("estimated", sceneflow.disparity(), sceneflow.flow()),
    ("true", true_disparity, true_flow),
]
fig, axes = plt.subplots(2, 2, figsize=(6.4, 4.6), layout="constrained")
for (name, disparity, flow), (ax_d, ax_f) in zip(rows, axes, strict=True):
    ax_d.imshow(disparity_to_color(disparity, max_disparity=max_disparity))
    ax_d.set_title(f"{name} disparity", fontsize=10)
    ax_f.imshow(flow_to_color(flow, max_flow=max_flow))
    ax_f.set_title(f"{name} flow", fontsize=10)
for ax in axes.flat:
    ax.set_axis_off()

# %%
# The flow colour wheel
# ---------------------
# The legend of the flow pictures: the colour of a flow vector ``(u, v)`` at the position
# ``(u, v)`` from the centre, up to ``max_flow`` pixels (x right, y down).

radius = np.linspace(-max_flow, max_flow, 121)
u, v = np.meshgrid(radius, radius)
wheel = flow_to_color(np.stack([u, v], axis=-1), max_flow=max_flow)
wheel[np.hypot(u, v) > max_flow] = 255
fig, ax = plt.subplots(figsize=(2.6, 2.6), layout="constrained")
ax.imshow(wheel, extent=(-max_flow, max_flow, max_flow, -max_flow))
ax.set_xlabel("u (px)")
ax.set_ylabel("v (px)")

# %%
# The estimate's mean endpoint error (AEP) and mean absolute disparity error (ADE) against
# the ground truth, over every pixel:

from stereodeblur.evaluation.metrics import disparity_error, endpoint_error  # noqa: E402

print(
    f"flow AEP {endpoint_error(sceneflow.flow(), true_flow):.3f} px, "
    f"disparity ADE {disparity_error(sceneflow.disparity(), true_disparity):.3f} px"
)
