"""Choosing alpha per frame from the data (issue 12), train split only: the solutions.

Run from the repository root::

    nice -n 10 python benchmarks/study_alpha_choice.py --scenes 40 --jobs 2

Frame 1 of the left view of every scene of the calibration protocol's **train split**
(seeds 0-999; any other seed is refused) is deblurred from both motion sources (``gt``,
``sceneflow``) with the boundary handlings ``adaptive``, ``none`` and ``gated`` at every
alpha of :data:`GRID` and at ``'auto'``. Every solution is kept
(``--work``/SCENE/SOURCE_HANDLING.npz with the truth and the blurred frame), so that rules
choosing alpha from the solutions (e.g. the quasi-optimality criterion) are evaluated
afterwards without deblurring again (``benchmarks/study_alpha_choice_report.py``).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

GRID = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
SOURCES = ("gt", "sceneflow")
HANDLINGS = ("adaptive", "none", "gated")
KEEPS = (0.9, 1.0)
"""Shares of the best-predicted pixels the cross-view costs are kept for."""


def _disparity(motion) -> np.ndarray:
    """The view's disparity at the frame's centre from its motion (NaN without a scene flow)."""
    if motion.sceneflow is None:
        return np.full(motion.flow_forward.shape[:2], np.nan, np.float32)
    return motion.sceneflow.disparity().astype(np.float32)


def run_scene(task) -> str:
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import DeblurSettings
    from stereodeblur.pipeline.frame import deblur_view
    from stereodeblur.pipeline.motion import stereo_motion
    from stereodeblur.pipeline.window import read_window

    kind, seed, size, work, views, handlings = task
    if not 0 <= seed < 1000:
        raise SystemExit(f"seed {seed} is not in the train split (0-999)")
    root = protocol.ensure_scene(kind, seed, size, Path(work))
    scene = open_scene(root)
    out = Path(work) / "alpha_choice" / root.name
    out.mkdir(parents=True, exist_ok=True)
    for source in SOURCES:
        motion = window = None
        for handling, view in ((h, v) for v in views for h in handlings):
            suffix = "" if view == "left" else f"_{view}"
            path = out / f"{source}_{handling}{suffix}.npz"
            if path.is_file():
                continue
            base = DeblurSettings(motion_source=source, boundary_weights=handling)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                if window is None:
                    window = read_window(scene, protocol.FRAME, views, base)
                    motion = stereo_motion(scene, window, views, base)
                images, alphas, seconds = [], [], []
                for alpha in (*GRID, "auto") if view == "left" else GRID:
                    start = time.perf_counter()
                    settings = replace(base, alpha=alpha)
                    result = deblur_view(scene, window, motion.views[view], settings)
                    seconds.append(time.perf_counter() - start)
                    images.append(result.image.astype(np.float32))
                    alphas.append(result.alpha)
            tmp = path.with_suffix(".tmp.npz")
            np.savez_compressed(
                tmp,
                images=np.stack(images),
                alphas=np.array(alphas),
                seconds=np.array(seconds),
                truth=scene.read_gt_sharp(view, protocol.FRAME).astype(np.float32),
                blurred=window.blurred(view).astype(np.float32),
                disparity=_disparity(motion.views[view]),
                gt_disparity=scene.read_gt_disparity(view, protocol.FRAME).astype(np.float32),
            )
            tmp.replace(path)
            protocol._log(f"{root.name} {source} {handling} {view}: {sum(seconds):.1f} s")
        if views == ("left", "right"):
            cross_view_costs(scene, out, source, handlings)
    return root.name


def cross_view_costs(scene, out: Path, source: str, handlings=HANDLINGS) -> None:
    """How well each view's solutions predict the *other* view's blurred frame, per alpha:
    ``|| A_other W x(alpha) - b_other ||^2`` (trimmed), and their own, ``|| A x - b ||^2``;
    written to SOURCE_HANDLING_cross.json."""
    import json

    from stereodeblur.pipeline import DeblurSettings
    from stereodeblur.pipeline.alpha import trimmed_error, warp_to_other
    from stereodeblur.pipeline.motion import stereo_motion
    from stereodeblur.pipeline.operator import view_operator
    from stereodeblur.pipeline.window import read_window

    def costs(predictions, blurred) -> dict:
        return {
            f"{keep:g}": [trimmed_error(p, blurred, border=border, keep=keep) for p in predictions]
            for keep in KEEPS
        }

    todo = [h for h in handlings if not (out / f"{source}_{h}_cross.json").is_file()]
    if not todo:
        return
    views = ("left", "right")
    plain = DeblurSettings(motion_source=source, boundary_weights="none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        window = read_window(scene, protocol.FRAME, views, plain)
        motion = stereo_motion(scene, window, views, plain)
        operators = {
            v: view_operator(motion.views[v], window.exposure, plain).operator for v in views
        }
    disparity = {v: _disparity(motion.views[v]) for v in views}
    border = protocol.border_of(disparity["left"].shape[1])
    for handling in todo:
        data = {}
        for view, other, direction in (("left", "right", 1), ("right", "left", -1)):
            suffix = "" if view == "left" else "_right"
            images = np.load(out / f"{source}_{handling}{suffix}.npz")["images"][: len(GRID)]
            warped = [warp_to_other(image, disparity[other], direction) for image in images]
            predictions = [operators[other].forward(image) for image in warped]
            data[f"{view}_to_{other}"] = costs(predictions, window.blurred(other))
            own = [operators[view].forward(image.astype(np.float64)) for image in images]
            data[f"{view}_own"] = costs(own, window.blurred(view))
        path = out / f"{source}_{handling}_cross.json"
        atomic = path.with_suffix(".tmp")
        atomic.write_text(json.dumps(data, indent=1))
        atomic.replace(path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--scenes", type=int, default=40, help="train scenes (default 40)")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--work", default="/tmp/calib/work", help="scenes and solutions")
    parser.add_argument("--views", default="left", help="left or left,right (default left)")
    parser.add_argument(
        "--handlings", default=",".join(HANDLINGS), help="boundary handlings (default: all)"
    )
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    args = parser.parse_args(argv)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    work = str(Path(args.work) / args.size)
    tasks = [
        (kind, seed, size, work, tuple(args.views.split(",")), tuple(args.handlings.split(",")))
        for kind, seed in protocol.scene_list("train", args.scenes, protocol.KINDS)
    ]
    start = time.perf_counter()
    protocol.run_all(run_scene, tasks, args.jobs)
    print(f"{len(tasks)} scenes in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
