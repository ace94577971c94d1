"""What re-estimating the scene flow on deblurred frames could gain (issue 13's optional
"re-estimated motion"): the scene flow estimated on the blurred frames (the default), on the
deblurred frames (one round), and on the sharp rendered frames (what no re-estimate can beat).

Run from the repository root after ``stereodeblur bench paper`` (it reuses the scenes and the
stored scene flows of the same work folder)::

    python benchmarks/reestimated_motion_bound.py --work /tmp/paperbench --size 640x480 \
        --jobs 2 --output benchmarks/results/reestimated_motion_bound_640x480.md

Frame 1 (left) of ``bench paper``'s object scenes, noiseless and noisy, the defaults. The
deblurred frames are frames 1 and its neighbour of both views, each deblurred with the
defaults (the neighbour with its own estimate); their scene flow deblurs frame 1 again. The
sharp frames are the renders at the centres of the exposures, estimated without the blur
balancing (they have no blur).
"""

from __future__ import annotations

import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from stereodeblur.evaluation import paper_bench
from stereodeblur.evaluation.metrics import border_for, endpoint_error, masked_mse, psnr
from stereodeblur.evaluation.motion_cache import cached_motion
from stereodeblur.io.scene import open_scene
from stereodeblur.pipeline import deblur_stereo_frame
from stereodeblur.pipeline.window import neighbour_of
from stereodeblur.sceneflow.estimate import estimate_scene_flow
from stereodeblur.settings import DeblurSettings
from stereodeblur.synth.objects import OBJECT_SCENES

sys.path.insert(0, str(Path(__file__).resolve().parent))

from hidden_fill_bound import finish, parse, scenes_folder, score_rows  # noqa: E402

ROWS = ("blurred frames (default)", "deblurred frames, one round", "sharp frames (bound)")
FRAME = 1
VIEWS = ("left", "right")


def estimate(scene, frames, exposure, settings):
    """The left view's scene flow of frame 1 towards its neighbour from ``frames``
    (left, right at frame 1, then at the neighbour)."""
    camera = scene.info.camera
    return estimate_scene_flow(
        *frames, camera, settings=settings.estimator, seed=settings.seed, exposure=exposure
    ).sceneflow


def evaluate(folder: Path, name: str) -> dict:
    """Each row's PSNR and gt/mixed MSE, the scene flow's flow AEP and seconds for ``name``."""
    settings = DeblurSettings()
    scene = open_scene(folder / name)
    neighbour = neighbour_of(FRAME, scene.num_frames)
    truth = scene.read_gt_sharp("left", FRAME)
    mixed = scene.read_gt_mixed("left", FRAME)
    flow = scene.read_gt_flow("left", FRAME)
    border = border_for(truth.shape[1])
    out, aep, seconds = {}, {}, {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cache = folder.parent / "cache" / name
        blurred = cached_motion(scene, "sceneflow", settings, cache)[0].sceneflow
        start = time.perf_counter()
        first = deblur_stereo_frame(scene, FRAME, settings=settings, sceneflow=blurred)
        second = deblur_stereo_frame(scene, neighbour, settings=settings)
        frames = [r.frames[v].image.clip(0, 1) for r in (first, second) for v in VIEWS]
        deblurred = estimate(scene, frames, scene.info.exposure, settings)
        rounds = time.perf_counter() - start  # the deblurred row's work before its own solve
        sharp_frames = [scene.read_gt_sharp(v, i) for i in (FRAME, neighbour) for v in VIEWS]
        sharp = estimate(scene, sharp_frames, None, settings)
        sceneflows = dict(zip(ROWS, (blurred, deblurred, sharp), strict=True))
        results = {ROWS[0]: first.frames["left"]}  # the default's frame 1, left view
        for row in ROWS[1:]:
            results[row] = deblur_stereo_frame(
                scene, FRAME, views=("left",), settings=settings, sceneflow=sceneflows[row]
            ).frames["left"]
        for row, result in results.items():
            out[row] = (
                psnr(result.image, truth, border=border),
                masked_mse(result.image, truth, mixed, border=border),
            )
            aep[row] = endpoint_error(sceneflows[row].flow(), flow)
            seconds[row] = sum(result.timings.values())
        seconds[ROWS[1]] += rounds
    return {"rows": out, "aep": aep, "seconds": seconds}


def report(results: dict, argv, minutes: float) -> list[str]:
    lines = [
        "# Re-estimated motion: the scene flow on blurred, deblurred and sharp frames",
        "",
        f"Command: `python benchmarks/reestimated_motion_bound.py {' '.join(argv)}`; "
        f"{minutes:.1f} min. Frame 1, left view, bench paper's object scenes, the defaults "
        "(`--observations other-view`, `--alpha held-out`). Per cell: PSNR dB / mean squared "
        "error in the gt/mixed pixels x 1000 (2.5 % border). The sharp frames are the renders, "
        "which no deblurred frame matches: the most a re-estimate can give.",
        "",
    ]
    for label, names in paper_bench.scene_groups(results):
        part = {n: results[n]["rows"] for n in names}
        lines += [f"**{label}**", "", "| scene | " + " | ".join(ROWS) + " |"]
        lines += ["|---|" + "---|" * len(ROWS), *score_rows(part, ROWS), ""]
    lines += [
        "Flow end-point error of each scene flow (px) and seconds of the row's left view (its "
        "stages' timings; the deblurred row with the deblurring of frames 1 and 2 and the "
        "re-estimate before it):",
        "",
    ]
    lines += ["| scene | " + " | ".join(ROWS) + " |", "|---|" + "---|" * len(ROWS)]
    for name, r in results.items():
        cells = [f"{r['aep'][k]:.3f} px, {r['seconds'][k]:.0f} s" for k in ROWS]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    args = parse(argv, __doc__.split("\n", 1)[0], jobs=True)
    base = args.scenes.split(",") if args.scenes else list(OBJECT_SCENES)
    names = [n + s for n in base for s in ("", "_noisy")]
    folder = scenes_folder(args)
    start = time.perf_counter()
    paper_bench.render_missing(folder, names, args.size)
    with ProcessPoolExecutor(args.jobs) as pool:
        done = pool.map(evaluate, [folder] * len(names), names)
        results = {}
        for name, r in zip(names, done, strict=True):
            results[name] = r
            print(name, " ".join(f"{r['rows'][k][0]:.2f}" for k in ROWS), flush=True)
    return finish(report(results, sys.argv[1:], (time.perf_counter() - start) / 60), args)


if __name__ == "__main__":
    sys.exit(main())
