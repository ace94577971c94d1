"""Study: the best the piecewise-rigid model can do on real KITTI 2015 pairs (an oracle).

Each segment's plane and rigid motion fitted to KITTI's ground truth (disparity at t and t + 1,
flow) on the estimate's own segments, on them cut at the truth's jumps, and on four times as
many segments, scored as ``kitti_sceneflow.py`` scores the estimate::

    python benchmarks/study_kitti_sceneflow_bound.py /data/kitti/training 2,3,7
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import kitti_sceneflow as ks

from stereodeblur.io.kitti import open_kitti
from stereodeblur.pipeline.motion import stereo_motion
from stereodeblur.pipeline.window import read_window
from stereodeblur.sceneflow import from_gt
from stereodeblur.sceneflow.superpixels import slic_segments
from stereodeblur.settings import DeblurSettings

from_gt._sample_smooth = lambda arr, x1, y1, max_bend=0.1: arr  # KITTI's disp_1 is on t's grid
root = Path(sys.argv[1])
for seq in sys.argv[2].split(","):
    seq = f"{int(seq):06d}"
    gt = ks.ground_truth(root, seq)
    src = open_kitti(root, kind="kitti-2015", sequence=seq, require_exposure=False)
    settings = DeblurSettings()
    window = read_window(src, 0, ("left",), settings)
    motion = stereo_motion(src, window, ("left",), settings)
    ours = motion.views["left"].sceneflow
    cam = window.camera
    d0, d1, fl = gt["D1", "all"], gt["D2", "all"], gt["Fl", "all"]
    d0 = np.where(d0 > 0, d0, np.nan)
    d1 = np.where(d1 > 0, d1, np.nan)
    flow = np.nan_to_num(fl.astype(np.float64))
    variants = {"ours": {"D1": ours.disparity(), "D2": ours.disparity_next(), "Fl": ours.flow()}}
    for name, labels in (
        ("oracle, our segments", ours.labels),
        (
            "oracle, our segments split at gt jumps",
            from_gt.split_at_discontinuities(ours.labels, np.nan_to_num(d0), flow),
        ),
        (
            "oracle, 4x segments",
            slic_segments(window.blurred("left"), 4 * (int(ours.labels.max()) + 1)),
        ),
    ):
        labels = np.unique(labels, return_inverse=True)[1].reshape(labels.shape)
        sf = from_gt.sceneflow_from_gt(cam, d0, d1, flow, labels)
        variants[name] = {"D1": sf.disparity(), "D2": sf.disparity_next(), "Fl": sf.flow()}
    shade = np.zeros(d0.shape, bool)
    for name, est in variants.items():
        s, _ = ks.scores(est, gt, shade)
        r = s["rates"]
        cells = " ".join(
            f"{m}-{g} {100 * r[m, g]:5.2f}"
            for m, g in (("D1", "noc"), ("D1", "all"), ("Fl", "noc"))
        )
        print(f"{seq} {name:42s} {cells} Fl-all {100 * r['Fl', 'all']:5.2f}", flush=True)
