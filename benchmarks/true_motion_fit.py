"""How well the true motion (``--motion-source gt``) reproduces the true flow.

Run from the repository root, after ``calibrate_defaults.py`` has rendered its scenes::

    python benchmarks/true_motion_fit.py --work /tmp/calib/work/320x240

``--work`` is a folder of scenes or one with a ``scenes`` folder in it (``bench paper``'s
and ``bench planar``'s work folders too). The true motion is a scene flow fitted to the
rendered disparity and flow (:func:`stereodeblur.pipeline.motion.gt_motions`). Its flow
should equal the rendered flow up to the renderer's and the fit's rounding; where it does
not, the "true motion" columns of the benchmarks judge the blur model with a wrong motion.
Output: per scene of ``--work``
the mean end-point error of frame 1's fitted flow against the true flow (left view), the
share of pixels more than 1 px off, the mean error of the fitted disparity at t + 1 where
the point is seen then, and the number of segments, as a Markdown table on
stdout and in ``--output``.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np


def fit_error(root: Path) -> dict:
    """End-point error of frame 1's fitted true motion against the true flow."""
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import DeblurSettings
    from stereodeblur.pipeline.motion import gt_motions
    from stereodeblur.pipeline.window import read_window

    scene = open_scene(root)
    settings = DeblurSettings(motion_source="gt")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = read_window(scene, 1, ("left",), settings, motion=True)
        motion = gt_motions(scene, window, ("left",), settings)["left"]
    from scipy.ndimage import map_coordinates

    sceneflow, flow = motion.sceneflow, scene.read_gt_flow("left", 1)
    error = np.linalg.norm(sceneflow.flow() - flow, axis=-1)
    # Depth at t + 1 where the point is seen then: what the end flow cannot tell apart (a
    # small patch's tilt for a shift in depth).
    rows, cols = np.mgrid[0 : flow.shape[0], 0 : flow.shape[1]].astype(np.float64)
    coordinates = [rows + flow[..., 1], cols + flow[..., 0]]
    rendered = map_coordinates(scene.read_gt_disparity("left", 2), coordinates, order=1)
    seen = ~sceneflow.occlusion
    depth_error = np.abs(sceneflow.disparity_next() - rendered)[seen]
    return {
        "scene": root.name,
        "aep": float(np.nanmean(error)),
        "over_1px": float(np.nanmean(error > 1.0)),
        "disparity_next": float(np.nanmean(depth_error)),
        "segments": int(sceneflow.num_segments),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--work", required=True, help="a folder of scenes, or one with a scenes/ folder in it"
    )
    parser.add_argument("--output", default=None, help="markdown output")
    args = parser.parse_args(argv)
    folder = Path(args.work) / "scenes"
    folder = folder if folder.is_dir() else Path(args.work)
    roots = sorted(p for p in folder.iterdir() if (p / "camera.json").is_file())
    if not roots:
        print(f"error: no scenes in {folder}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    rows = [fit_error(root) for root in roots]
    aep = [r["aep"] for r in rows]
    lines = [
        f"# The true motion's fit against the true flow, {len(rows)} scenes",
        "",
        f"Command: `python benchmarks/true_motion_fit.py --work {args.work}`; "
        f"{time.perf_counter() - start:.0f} s.",
        "",
        f"Mean end-point error {np.mean(aep):.3f} px, worst {max(aep):.3f} px "
        f"({rows[int(np.argmax(aep))]['scene']}). Disparity at t + 1 where the point is seen "
        f"then, mean error: mean over the scenes {np.mean([r['disparity_next'] for r in rows]):.4f}"
        f" px, worst {max(r['disparity_next'] for r in rows):.4f} px.",
        "",
        "| scene | AEP (px) | > 1 px | disparity at t + 1, mean error (px) | segments |",
        "|---|---:|---:|---:|---:|",
    ]
    lines += [
        f"| {r['scene']} | {r['aep']:.3f} | {r['over_1px']:.1%} | {r['disparity_next']:.4f} "
        f"| {r['segments']} |"
        for r in rows
    ]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        from stereodeblur.io.outputs import atomic_write_text

        atomic_write_text(Path(args.output), text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
