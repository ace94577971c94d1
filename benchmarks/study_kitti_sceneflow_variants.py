"""Study: the scene flow's outliers on real KITTI pairs under estimator variants.

KITTI 2015 frames 000002, 000003, 000007 (D1-noc / D1-all / Fl-noc / Fl-all, KITTI's outliers)
and KITTI raw drive 0023 frames 0-5 (disparity outliers against the projected LiDAR depth of
packnet-sfm's KITTI_tiny), for each variant ``key:value,key:value`` of SceneFlowSettings::

    KITTI2015=/data/kitti/training KITTI_TINY=/data/KITTI_tiny \\
        python benchmarks/study_kitti_sceneflow_variants.py "" "smoothness:1.0"
"""

import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import kitti_sceneflow as ks  # noqa: E402

from stereodeblur.io.kitti import open_kitti  # noqa: E402
from stereodeblur.pipeline.motion import stereo_motion  # noqa: E402
from stereodeblur.pipeline.window import read_window  # noqa: E402
from stereodeblur.settings import DeblurSettings  # noqa: E402

ROOT = Path(os.environ["KITTI2015"])
TINY = Path(os.environ["KITTI_TINY"]) / "2011_09_26/2011_09_26_drive_0023_sync"
FB = 44.85728 + 339.5242  # KITTI raw 2011_09_26: f * baseline (px m) of cameras 2 and 3


def parse(spec: str) -> dict:
    out = {}
    for item in filter(None, spec.split(",")):
        key, value = item.split(":")
        out[key] = float(value) if "." in value or "e" in value else int(value)
    return out


def disparity(source, index, settings):
    window = read_window(source, index, ("left",), settings)
    return stereo_motion(source, window, ("left",), settings).views["left"].sceneflow


def main() -> None:
    gts = {s: ks.ground_truth(ROOT, s) for s in ("000002", "000003", "000007")}
    lidar = []
    for i in range(6):
        z = np.load(TINY / "proj_depth/velodyne/image_02" / f"{i:010d}.npz")["velodyne_depth"]
        lidar.append(np.where(z > 0, FB / np.maximum(z, 1e-6), np.nan))
    for spec in sys.argv[1:]:
        base = DeblurSettings()
        settings = replace(base, sceneflow=replace(base.sceneflow, **parse(spec)))
        start = time.time()
        rows = []
        for sequence, gt in gts.items():
            source = open_kitti(ROOT, kind="kitti-2015", sequence=sequence, require_exposure=False)
            sf = disparity(source, 0, settings)
            est = {"D1": sf.disparity(), "D2": sf.disparity_next(), "Fl": sf.flow()}
            rates = ks.scores(est, gt, np.zeros(gt["D1", "all"].shape, bool))[0]["rates"]
            rows.append([100 * rates[m, g] for m in ("D1", "Fl") for g in ("noc", "all")])
        source = open_kitti(TINY, require_exposure=False)
        d1 = []
        for i, gt in enumerate(lidar):
            error = np.abs(disparity(source, i, settings).disparity() - gt)[np.isfinite(gt)]
            d1.append(100 * np.mean((error > 3) & (error > 0.05 * gt[np.isfinite(gt)])))
        rows = np.array(rows)
        cells = "  ".join(
            f"{s[-1]}: " + "/".join(f"{v:5.2f}" for v in r) for s, r in zip(gts, rows, strict=True)
        )
        mean = "/".join(f"{v:5.2f}" for v in rows.mean(0))
        print(
            f"{spec or 'default':40s} {cells}  mean {mean} | raw 0023 D1 {np.mean(d1):5.2f} "
            f"({time.time() - start:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
