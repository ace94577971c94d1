"""
Blur kernels from homographies and from 2D flow
===============================================

The paper's Fig. 3: a textured plane 3 m in front of the camera turns about the vertical axis
through its centre by 0.3 rad per frame interval. Row ``x`` of a blur matrix is the kernel of
pixel ``x``: the weights of the sharp pixels it averages. The homography-induced kernels
follow the exact trajectories of the rigid motion (Eq. 3-4); the flow-induced ones assume a
straight path at constant speed. Near the rotation axis the two agree; towards the sides the
trajectories bend and accelerate, and the straight-line model misses them.
"""

import matplotlib.pyplot as plt
import numpy as np

from stereodeblur.evaluation.kernels_figure import kernel_grid, render_kernel_figure

# %%
# Kernels at a 5 x 4 grid of pixels
# ---------------------------------
# ``kernel_grid`` builds both blur operators of the turning plane at 320x240 pixels (70
# instants per exposure) and cuts the rows of the grid's pixels out as square patches.

kernels = kernel_grid(size=(320, 240), yaw=0.3, depth=3.0, grid=(5, 4))
print("patch size:", kernels.homography.shape[2:], "pixels")

# %%
# The figure of ``stereodeblur kernels``: homography kernels, flow kernels (each patch scaled
# to its own maximum) and their signed difference (red: the homography kernel is larger,
# blue: the flow kernel is larger).

fig, ax = plt.subplots(figsize=(10, 3), layout="constrained")
ax.imshow(render_kernel_figure(kernels), interpolation="nearest")
ax.set_axis_off()

# %%
# How far apart the two models are
# --------------------------------
# The L1 norm of the difference of each pair of kernels (0: equal, 2: disjoint), against the
# pixel's horizontal distance from the rotation axis.

columns = kernels.pixels[..., 0]
difference = kernels.difference_norm()
fig, ax = plt.subplots(figsize=(5, 3), layout="constrained")
ax.plot(columns.ravel() - (320 - 1) / 2, difference.ravel(), "o")
ax.set_xlabel("x - image centre (px)")
ax.set_ylabel("|homography - flow| (L1)")
ax.set_ylim(0, 2)
ax.grid(alpha=0.3)
print(np.round(difference, 2))
