"""
A point cloud of a deblurred frame
==================================

The scene flow gives every pixel a 3D point on its segment's plane, so a deblurred frame can
be seen from another viewpoint. This example renders a scene of moving spheres at 160x120
pixels, deblurs frame 1 of the left view, builds the coloured point cloud of that frame
(deblurred and blurred colours) and renders it from a camera moved to the left and turned
towards the scene. ``stereodeblur deblur --point-cloud`` writes the same clouds as PLY files,
and ``stereodeblur render-view`` renders them.
"""

import shutil
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from stereodeblur.io import linear_to_srgb, open_scene
from stereodeblur.pipeline import deblur_frame
from stereodeblur.pointcloud import frame_point_cloud, read_ply, render_view, write_ply
from stereodeblur.synth import make_object_scene, write_rendered_scene

# %%
# Deblur one frame
# ----------------
# The result keeps the motion it was deblurred with; its scene flow holds the planes.

folder = Path(tempfile.mkdtemp())
write_rendered_scene(make_object_scene("spheres", size=(160, 120)), folder / "spheres")
scene = open_scene(folder / "spheres")
result = deblur_frame(scene, 1, view="left")
sceneflow = result.motion.sceneflow

# %%
# The point cloud, written and read back as PLY
# ---------------------------------------------
# Points are in left-camera coordinates (x right, y down, z forward, metres); colours are
# stored as the scene stores its frames (here linear).

cloud = frame_point_cloud(sceneflow, result.image, blurred=result.blurred, color=scene.info.color)
path = write_ply(folder / "frame1.ply", cloud)
cloud = read_ply(path)
print(
    f"{len(cloud.points)} points, depth {cloud.points[:, 2].min():.2f} "
    f"to {cloud.points[:, 2].max():.2f} m"
)

# %%
# Seen from a new viewpoint
# -------------------------
# The new camera sits 0.4 m to the left of the left camera and turns 0.12 rad to the right
# (a rotation about the y axis); nothing is known behind the foreground, so those pixels stay
# black. Left half: deblurred colours, right half: blurred ones.

view = render_view(cloud, translation=(-0.4, 0.0, 0.0), rotation=(0.0, 0.12, 0.0), colors="both")
fig, axes = plt.subplots(2, 1, figsize=(6.4, 5), layout="constrained")
axes[0].imshow(linear_to_srgb(view.image))
axes[0].set_title("new viewpoint: deblurred | blurred", fontsize=10)
depth = axes[1].imshow(view.depth, cmap="viridis_r")
axes[1].set_title("depth seen from there (white: nothing seen)", fontsize=10)
fig.colorbar(depth, ax=axes[1], label="m", shrink=0.9)
for ax in axes:
    ax.set_axis_off()

shutil.rmtree(folder)
