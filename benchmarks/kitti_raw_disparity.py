"""Disparity outliers of the scene flow and of plain SGBM on KITTI raw drive 0023, against
its projected LiDAR depth (frames 0-5, each with the next; an outlier is over 3 px and 5 %).

The drive's seven frames, calibration and ``proj_depth/velodyne`` are in ``KITTI_tiny`` of
TRI-ML/packnet-sfm at commit c809c6c (non-commercial data: keep it out of the repository)::

    python benchmarks/kitti_raw_disparity.py \\
        /tmp/kitti_tiny/KITTI_tiny/2011_09_26/2011_09_26_drive_0023_sync
"""

import sys
from pathlib import Path

import numpy as np

from stereodeblur.io.kitti import open_kitti
from stereodeblur.pipeline.motion import stereo_motion
from stereodeblur.pipeline.window import read_window
from stereodeblur.sceneflow.initial import initial_disparity
from stereodeblur.settings import DeblurSettings


def rate(estimate, truth, known):
    err = np.abs(np.nan_to_num(estimate, nan=-1e9)[known] - truth[known])
    return float(np.mean((err > 3) & (err > 0.05 * truth[known])))


root = Path(sys.argv[1])
src = open_kitti(root, require_exposure=False)
fB = src.info.camera.K[0, 0] * src.info.camera.baseline
settings = DeblurSettings()
res = []
for i in range(0, 6, 1):
    z = np.load(root / "proj_depth/velodyne/image_02" / f"{i:010d}.npz")["velodyne_depth"]
    gt = np.where(z > 0, fB / np.maximum(z, 1e-6), np.nan)
    w = read_window(src, i, ("left",), settings)
    m = stereo_motion(src, w, ("left",), settings)
    d = m.views["left"].sceneflow.disparity()
    l0 = src.read_frame("left", i, linear=False)
    r0 = src.read_frame("right", i, linear=False)
    s = initial_disparity(l0, r0)
    k = np.isfinite(gt)

    res.append((rate(d, gt, k), rate(s, gt, k)))
    print(i, f"ours {100 * res[-1][0]:.2f} %  SGBM {100 * res[-1][1]:.2f} %", flush=True)
r = np.array(res)
print("mean", f"ours {100 * r[:, 0].mean():.2f} %  SGBM {100 * r[:, 1].mean():.2f} %")
