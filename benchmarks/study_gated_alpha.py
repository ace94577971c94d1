"""The alpha grid with the gated boundary handling (issue 12), train split only.

Run from the repository root after ``benchmarks/study_boundary.py`` (its motion cache and
columns are reused)::

    nice -n 10 python benchmarks/study_gated_alpha.py --scenes 64 --jobs 2

Frame 1 of the left view of every scene of the calibration protocol's **train split only**
(seeds 0-999; the script refuses any other seed) is deblurred with the candidate boundary
handling ``gated`` at every alpha of :data:`GRID` and at ``alpha='auto'``:

- ``sceneflow``: the outside weight ``O`` and the dense-flow rows ``R`` only at band pixels
  where the dense flow's trust beats the scene flow's by more than 0.25
  (``study_boundary``'s column ``gate:better>0.25``);
- ``gt``: the outside weight ``O`` and the occlusion-aware operator ``V``, no anchor
  (``study_boundary``'s column ``OV``).

The parts are switched by ``study_boundary``'s monkeypatches (``src/`` is not edited). With
``alpha='auto'`` the pipeline raises the noise-driven alpha by the share of untrusted pixels
(``alpha_from_trust``): with ``gt`` (no dense rows) that is the trust of the motion in its own
boundary band, which the removed anchor does not touch; with ``sceneflow`` and dense rows it is
the scene flow's trust *in the band the dense rows take*, and the gate shrinks that band to
the gated pixels, so the patched ``'auto'`` counts fewer untrusted pixels than the rule does
without the gate. The column ``auto-band`` runs the alpha the rule gives with the scene
flow's trust over its whole band (``max(alpha_from_sigma, alpha_from_trust)`` from the
study's features), as a fixed alpha.

Per-scene results are cached as json under ``--work``; ``--report-only`` reads them (with
``--note`` a sentence on how the grid was measured). The report
(``benchmarks/study_gated_alpha_report.py``) writes ``--output`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402
import study_boundary as boundary  # noqa: E402

GRID = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
SOURCES = ("gt", "sceneflow")
GATED = {"gt": "OV", "sceneflow": "gate:better>0.25"}
"""The study_boundary column of the candidate handling per motion source."""
SIGNATURE = "gated alpha study 1"


def column_names(source: str) -> list[str]:
    names = [f"{a:g}" for a in GRID] + ["auto"]
    return names + (["auto-band"] if source == "sceneflow" else [])


def band_alpha(features: dict) -> float:
    """``'auto'`` with the scene flow's trust over its whole boundary band."""
    from stereodeblur.deconv.noise import alpha_from_sigma
    from stereodeblur.deconv.trust import PAPER_ALPHA, UNTRUSTED_SHARE

    trust = PAPER_ALPHA * min(1.0, features["untrusted_share"] / UNTRUSTED_SHARE)
    return max(alpha_from_sigma(features["noise_sigma"]), trust)


def deblur(scene, source: str, motion, truth, alpha, masks) -> dict:
    """PSNR of the gated handling of ``source`` at ``alpha`` (a float or ``'auto'``)."""
    import warnings

    import stereodeblur.pipeline.weights as weights
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.pipeline import deblur_frame
    from stereodeblur.settings import DeblurSettings

    settings = DeblurSettings(motion_source=source, alpha=alpha, boundary_weights="adaptive")
    column = GATED[source]
    resolve, used_alphas = weights.resolve_alpha, []

    def recorded(*args, **kwargs):  # the alpha the run takes (chosen by 'auto')
        used_alphas.append(resolve(*args, **kwargs))
        return used_alphas[-1]

    weights.resolve_alpha = recorded
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if column.startswith("gate:"):
            with boundary.only_parts("OR", motion) as used, boundary.gated_rows(masks[column[5:]]):
                result = deblur_frame(
                    scene, boundary.FRAME, view="left", settings=settings, motion=used
                )
        else:
            with boundary.only_parts(column, motion) as used:
                result = deblur_frame(
                    scene, boundary.FRAME, view="left", settings=settings, motion=used
                )
    weights.resolve_alpha = resolve
    border = protocol.border_of(truth.shape[1])
    out = {"psnr": psnr(result.image, truth, border=border), "seconds": time.perf_counter() - start}
    if used_alphas:
        out["alpha"] = float(used_alphas[-1])
    return out


def run_scene(task) -> dict:
    """Every column of one scene, reusing this study's and study_boundary's caches."""
    from stereodeblur.io.scene import open_scene

    kind, seed, size, scenes_from, work, boundary_work = task
    if not 0 <= seed < 1000:
        raise SystemExit(f"seed {seed} is not in the train split (0-999)")
    root = protocol.ensure_scene(kind, seed, size, Path(scenes_from))
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", boundary.FRAME)
    blurred = scene.read_frame("left", boundary.FRAME)
    motion_cache = Path(boundary_work) / root.name
    motion_cache.mkdir(parents=True, exist_ok=True)
    previous = motion_cache / "results.json"
    earlier = json.loads(previous.read_text()) if previous.is_file() else {}
    cache = Path(work) / root.name
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / "results.json"
    data = json.loads(path.read_text()) if path.is_file() else {}
    if data.get("signature") != SIGNATURE:
        data = {"signature": SIGNATURE, "scene": root.name, "kind": kind, "seed": seed}
    for source in SOURCES:
        motion = boundary.scene_motion(scene, source, blurred, motion_cache)
        columns = data.setdefault("columns", {}).setdefault(source, {})
        old = earlier.get("columns", {}).get(source, {})
        if "paper" not in columns and "none" in old:
            columns["paper"] = dict(old["none"], source="boundary study cache")
        if "0.001" not in columns and GATED[source] in old:
            columns["0.001"] = dict(old[GATED[source]], source="boundary study cache")
        masks = None
        for column in column_names(source):
            if column in columns:
                continue
            if masks is None:  # the gate's masks (and the features of this motion)
                features, masks = boundary.scene_features(scene, motion, blurred)
                data.setdefault("features", {})[source] = features
            alpha = {"auto": "auto"}.get(column)
            if column == "auto-band":
                alpha = band_alpha(data["features"][source])
            elif alpha is None:
                alpha = float(column)
            columns[column] = deblur(scene, source, motion, truth, alpha, masks)
            if column == "auto-band":
                columns[column]["alpha"] = alpha
            boundary._log(f"{root.name} {source} {column}: {columns[column]['psnr']:.2f} dB")
            tmp = path.with_suffix(".tmp")
            tmp.write_text(json.dumps(data, indent=1))
            tmp.replace(path)
        if "features" not in data or source not in data["features"]:
            data.setdefault("features", {})[source] = earlier.get("features", {}).get(source)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)
    return data


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--scenes", type=int, default=64, help="train scenes (default 64)")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--scenes-from", default="/tmp/calib/work", help="protocol's --work")
    parser.add_argument("--boundary-work", default="/tmp/boundary_study", help="its --work")
    parser.add_argument("--work", default="/tmp/gated_alpha", help="per-scene cache")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--report-only", action="store_true", help="cached scenes, no runs")
    parser.add_argument("--output", default=None, help="markdown output (and .json beside)")
    parser.add_argument("--note", default="", help="a sentence for the report (e.g. run time)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    args.size_pair = (width, height)
    if args.output is None:
        args.output = f"benchmarks/results/gated_alpha_train_{args.size}.md"
    return args


def _cached(work: Path, kind: str, seed: int) -> dict | None:
    path = work / f"{kind}_{seed:04d}" / "results.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    done = data.get("columns", {})
    if all(set(column_names(s)) | {"paper"} <= set(done.get(s, {})) for s in SOURCES):
        return data
    return None


def main(argv=None) -> int:
    from stereodeblur.io.outputs import atomic_write_text

    args = parse(argv)
    tasks = [
        (
            kind,
            seed,
            args.size_pair,
            str(Path(args.scenes_from) / args.size),
            str(Path(args.work) / args.size),
            str(Path(args.boundary_work) / args.size),
        )
        for kind, seed in protocol.scene_list("train", args.scenes, protocol.KINDS)
    ]
    start = time.perf_counter()
    if args.report_only:
        rows = [_cached(Path(t[4]), t[0], t[1]) for t in tasks]
        rows = [r for r in rows if r is not None]
    else:
        rows = protocol.run_all(run_scene, tasks, args.jobs)
    seconds = time.perf_counter() - start
    import study_gated_alpha_report as reporting  # noqa: PLC0415 (written after the runs began)

    shown = [a for i, a in enumerate(sys.argv[1:]) if "--note" not in sys.argv[i : i + 2]]
    text, summary = reporting.report(rows, seconds, " ".join(shown), note=args.note)
    output = Path(args.output)
    atomic_write_text(output, text)
    atomic_write_text(output.with_suffix(".json"), json.dumps(summary, indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
