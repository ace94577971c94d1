"""Semi-real driving clips from real KITTI 2015 scenes, and how the deblurring does on them.

Run from the repository root, on a KITTI 2015 ``training`` folder (as for
``kitti_sceneflow.py``; KITTI's data is non-commercial: keep it and the clips out of the
repository)::

    python benchmarks/kitti_semireal.py /tmp/kitti/training --frames 2,3,7 \\
        --work /tmp/kitti/semireal --output benchmarks/results/kitti_semireal.md

Per sequence ``NNNNNN``, a clip of three frames whose middle one is centred on the real
photographs ``NNNNNN_10`` of both views (:mod:`stereodeblur.synth.photo`):

- **depth**: KITTI's disparity ground truth (``disp_occ_0``, LiDAR with fitted car models),
  filled where missing as KITTI's devkit does (background interpolation); the right view's
  disparity is the left one's seen from the right (nearest surface), filled likewise;
- **motion**: the camera's, fitted to the flow ground truth (``flow_occ``) with RANSAC
  (OpenCV's PnP on the 3D points at frame 10 and where the flow sees them at 11); the
  pixels the camera's motion misses by more than 3 px and 5 % form the moving objects
  (connected regions of at least ``MIN_OBJECT`` px), each with its own rigid motion fitted
  the same way;
- **blur**: frame rate 10 Hz; the exposure that makes the longest blur of the middle frame's
  left view ``--blur`` px (at most the frame interval); the instants of each exposure
  rendered with occlusions and averaged; grey, linear, 16 bit; a copy with Gaussian noise of
  deviation ``--noise`` (seeded).

The middle frame's left view is then deblurred (estimated motion) by three columns of
``stereodeblur bench paper``: the default ("ours (full)"), the monocular path with the same
machinery ("monocular (same defaults)": dense optical flow, displacement kernels, the same
solver, alpha rule and its strongest boundary handling) and the paper's settings ("paper
(full)"); and, as a bound, the default given the true motion ("ours, true motion": the
piecewise-planar model fitted to the clip's true disparity and flow). PSNR against the
photograph without a border of 2.5 % of the width.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from kitti_sceneflow import commit  # this folder's: the scripts run from it

FRAME_RATE = 10.0
MIN_OBJECT = 300  # px: smaller regions the camera's motion misses stay with the camera
MIN_DISPARITY = 0.5  # px: farther filled depth is clamped here
METHODS = ("ours-full", "monocular", "paper-full", "ours-true-motion")
NAMES = {
    "ours-full": "default",
    "monocular": "monocular",
    "paper-full": "paper",
    "ours-true-motion": "true motion",
}


def fit_motion(points: np.ndarray, seen: np.ndarray, K: np.ndarray):
    """Twist (per frame) of the rigid motion taking ``points`` (n, 3) to where they are
    seen at the next frame (pixels (n, 2)), by RANSAC PnP; and its inliers."""
    import cv2

    from stereodeblur.geometry.rigid import se3_log

    ok, rvec, tvec, inliers = cv2.solvePnPRansac(
        points.astype(np.float64), seen.astype(np.float64), K, None,
        iterationsCount=500, reprojectionError=1.0, confidence=0.999, flags=cv2.SOLVEPNP_SQPNP,
    )  # fmt: skip
    if not ok or inliers is None or len(inliers) < 6:
        return None, None
    inliers = inliers.ravel()
    rvec, tvec = cv2.solvePnPRefineLM(points[inliers], seen[inliers], K, None, rvec, tvec)
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = cv2.Rodrigues(rvec)[0], tvec.ravel()
    return se3_log(M), inliers


def right_view(disparity: np.ndarray, labels: np.ndarray):
    """The left view's dense disparity and labels seen from the right camera (the nearest
    surface wins), holes filled with the background beside them."""
    from stereodeblur.evaluation.kitti_scores import interpolate_background

    H, W = disparity.shape
    y, x = np.mgrid[0:H, 0:W]
    xr = np.rint(x - disparity).astype(int)
    inside = (xr >= 0) & (xr < W)
    order = np.argsort(disparity[inside], kind="stable")  # nearest written last, wins
    rows, cols = y[inside][order], xr[inside][order]
    right_d = np.full((H, W), np.nan)
    right_l = np.zeros((H, W), dtype=np.int64)
    right_d[rows, cols] = disparity[inside][order]
    right_l[rows, cols] = labels[inside][order]
    return interpolate_background(right_d), right_l


def photo_scene(root: Path, sequence: str):
    """The :class:`PhotoScene` of ``sequence``, and a description of its motions."""
    import cv2

    from stereodeblur.evaluation.kitti_scores import (
        interpolate_background,
        is_outlier,
        read_kitti_disparity,
        read_kitti_flow,
    )
    from stereodeblur.io.kitti import open_kitti
    from stereodeblur.sceneflow.initial import to_gray
    from stereodeblur.synth.photo import PhotoScene

    source = open_kitti(root, kind="kitti-2015", sequence=sequence, require_exposure=False)
    camera = source.info.camera
    K = camera.K
    images = {v: to_gray(source.read_frame(v, 0)) for v in ("left", "right")}
    name = f"{sequence}_10.png"
    d1 = read_kitti_disparity(root / "disp_occ_0" / name)
    d2 = read_kitti_disparity(root / "disp_occ_1" / name)
    flow = read_kitti_flow(root / "flow_occ" / name)
    H, W = d1.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    known = np.isfinite(d1) & np.isfinite(d2) & np.isfinite(flow).all(axis=-1) & (d1 > 0)
    points = camera.backproject(x[known], y[known], camera.disparity_to_depth(d1[known]))
    seen = np.stack([x[known], y[known]], axis=-1) + flow[known]
    ego, _ = fit_motion(points, seen, K)
    twists = [ego]
    # The camera's motion where it fails: moving objects.
    from stereodeblur.geometry.rigid import se3_exp

    M = se3_exp(ego)
    predicted = camera.project(points @ M[:3, :3].T + M[:3, 3])
    error = np.linalg.norm(predicted - seen, axis=1)
    missed = np.zeros((H, W), dtype=np.uint8)
    missed[known] = is_outlier(error, np.linalg.norm(flow[known], axis=1)).astype(np.uint8)
    missed = cv2.morphologyEx(missed, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
    count, regions, stats, _ = cv2.connectedComponentsWithStats(missed, connectivity=8)
    labels = np.zeros((H, W), dtype=np.int64)
    index = np.full((H, W), -1)
    index[known] = np.arange(known.sum())
    for k in range(1, count):
        if stats[k, cv2.CC_STAT_AREA] < MIN_OBJECT:
            continue
        mine = index[(regions == k) & known]
        twist, inliers = fit_motion(points[mine], seen[mine], K)
        if twist is None:
            continue
        labels[regions == k] = len(twists)
        twists.append(twist)
    disparity = np.maximum(interpolate_background(d1), MIN_DISPARITY)
    right_d, right_l = right_view(disparity, labels)
    photo = PhotoScene(
        images=images,
        disparity={"left": disparity, "right": np.maximum(right_d, MIN_DISPARITY)},
        labels={"left": labels, "right": right_l},
        twists=np.asarray(twists),
        camera=camera,
    )
    return photo, {"objects": len(twists) - 1, "moving px": int((labels > 0).sum())}


def build(root: Path, sequence: str, work: Path, blur: float, noise: float) -> dict:
    """Write the clean and the noisy clip of ``sequence`` under ``work``; their facts."""
    from stereodeblur.evaluation.metrics import border_for
    from stereodeblur.geometry.camera import Exposure
    from stereodeblur.io.scene import open_scene
    from stereodeblur.synth.photo import longest_blur, render_clip, write_clip

    clean, noisy = work / f"{sequence}", work / f"{sequence}_noisy"
    facts_path = work / f"{sequence}.json"
    if facts_path.is_file() and clean.is_dir() and noisy.is_dir():
        return json.loads(facts_path.read_text())
    start = time.perf_counter()
    photo, facts = photo_scene(root, sequence)
    border = border_for(photo.shape[1])
    per_frame = longest_blur(photo, 1.0, border=border)
    duty = min(1.0, blur / per_frame)
    exposure = Exposure(FRAME_RATE, duty / FRAME_RATE)
    clip = render_clip(photo, exposure, border=border)
    write_clip(clip, photo.camera, clean, overwrite=True)
    rng = np.random.default_rng(int(sequence))
    frames = {
        v: tuple(np.clip(f + rng.normal(0.0, noise, f.shape), 0, 1) for f in clip.frames[v])
        for v in clip.frames
    }
    write_clip(replace(clip, frames=frames), photo.camera, noisy, overwrite=True)
    open_scene(clean), open_scene(noisy)  # both read back as scenes
    facts |= {
        "size": f"{photo.shape[1]}x{photo.shape[0]}",
        "longest blur (px)": round(clip.longest_blur, 1),
        "exposure (s)": round(exposure.exposure, 5),
        "samples": clip.num_samples,
        "render (s)": round(time.perf_counter() - start, 1),
    }
    facts_path.write_text(json.dumps(facts))
    return facts


def deblur(scene_dir: Path, method: str, cache: Path) -> dict:
    """PSNR of the blurred and the deblurred middle frame (left view) by ``method``."""
    from stereodeblur.evaluation.metrics import border_for, psnr
    from stereodeblur.evaluation.paper_columns import COLUMNS, TRUE_MOTION
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import deblur_frame
    from stereodeblur.settings import DeblurSettings

    if cache.is_file():
        return json.loads(cache.read_text())
    column = next(c for c in (*COLUMNS, TRUE_MOTION) if c.key == method)
    scene = open_scene(scene_dir)
    start = time.perf_counter()
    result = deblur_frame(scene, 1, view="left", settings=column.settings(DeblurSettings()))
    seconds = time.perf_counter() - start
    sharp = scene.read_gt_sharp("left", 1)
    border = border_for(scene.shape[1])
    out = {
        "blurred": psnr(result.blurred, sharp, border=border),
        "psnr": psnr(result.image, sharp, border=border),
        "seconds": seconds,
    }
    cache.write_text(json.dumps(out))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("root", type=Path, help="a KITTI 2015 training folder")
    parser.add_argument("--frames", default="2,3,7", help="sequences, e.g. 2,3,7 (default)")
    parser.add_argument("--work", type=Path, required=True, help="clips and results go here")
    parser.add_argument("--output", type=Path, help="also write the report here")
    parser.add_argument("--blur", type=float, default=25.0, help="longest blur, px (25)")
    parser.add_argument("--noise", type=float, default=0.01, help="noise deviation (0.01)")
    args = parser.parse_args(argv)
    sequences = [f"{int(s):06d}" for s in args.frames.split(",")]
    args.work.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = []
    for sequence in sequences:
        facts = build(args.root, sequence, args.work, args.blur, args.noise)
        for variant in ("", "_noisy"):
            scene_dir = args.work / f"{sequence}{variant}"
            row = {"frame": sequence + variant, **facts}
            for method in METHODS:
                result = deblur(scene_dir, method, args.work / f"{sequence}{variant}.{method}.json")
                row["blurred"] = result["blurred"]
                row[method] = result["psnr"]
                row[method + " s"] = result["seconds"]
            rows.append(row)
            print(
                f"{row['frame']}: blurred {row['blurred']:.2f} dB, "
                + ", ".join(f"{NAMES[m]} {row[m]:.2f}" for m in METHODS),
                flush=True,
            )
    minutes = (time.perf_counter() - start) / 60
    lines = [
        "# Semi-real driving clips from real KITTI 2015 scenes",
        "",
        f"Command: `python benchmarks/kitti_semireal.py {args.root} --frames {args.frames} "
        f"--work {args.work} --blur {args.blur:g} --noise {args.noise:g}`; commit {commit()}, "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC, {minutes:.1f} min (clips and results cached "
        "in --work are reused).",
        "",
        "Frame 1 (the photograph), left view, estimated motion; PSNR (dB) against the "
        "photograph without a border of 2.5 % of the width. Default: `ours (full)`; monocular: "
        "`monocular (same defaults)`; paper: `paper (full)` (`stereodeblur bench paper`'s "
        "columns); true motion: the default given the true motion (a bound).",
        "",
        "| frame | size | moving objects | longest blur (px) | exposure (s) | blurred | default "
        "| monocular | paper | default - monocular | default - paper | true motion "
        "| default time (s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['frame']} | {r['size']} | {r['objects']} | {r['longest blur (px)']:.1f} "
            f"| {r['exposure (s)']:.4f} | {r['blurred']:.2f} | {r['ours-full']:.2f} "
            f"| {r['monocular']:.2f} | {r['paper-full']:.2f} "
            f"| {r['ours-full'] - r['monocular']:+.2f} | {r['ours-full'] - r['paper-full']:+.2f} "
            f"| {r['ours-true-motion']:.2f} | {r['ours-full s']:.0f} |"
        )
    mean = {k: float(np.mean([r[k] for r in rows])) for k in ("blurred", *METHODS)}
    lines.append(
        f"| **mean** | | | | | {mean['blurred']:.2f} | {mean['ours-full']:.2f} "
        f"| {mean['monocular']:.2f} | {mean['paper-full']:.2f} "
        f"| {mean['ours-full'] - mean['monocular']:+.2f} "
        f"| {mean['ours-full'] - mean['paper-full']:+.2f} | {mean['ours-true-motion']:.2f} | |"
    )
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
