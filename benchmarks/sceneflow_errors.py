"""How far the calibration protocol's scene-flow estimates are from the truth, and what it costs.

Run from the repository root, after ``calibrate_defaults.py`` (its scenes, stored scene flows
and results JSON are read)::

    python benchmarks/sceneflow_errors.py --work /tmp/calib/work/320x240 \\
        --results benchmarks/results/calibrate_defaults_test_320x240_true_motion_fit.json

Per scene of the results: the stored estimate's mean and median end-point error against the
rendered flow (left view, frame 1; a few segments whose plane passes near the camera can have
flows of hundreds of pixels and dominate the mean), its share of pixels more than 3 px off,
its mean disparity error, and what the default loses with it against the true motion and
against the best alpha, and its margin over the monocular path. Sorted by the loss against the
true motion, as Markdown on stdout and in ``--output``. It says which scenes the estimator, not
the deblurring, fails on.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def errors(work: Path, name: str) -> dict:
    """End-point and disparity errors of the stored scene-flow estimate of scene ``name``."""
    from stereodeblur.io.scene import open_scene
    from stereodeblur.sceneflow.storage import load_sceneflow

    scene = open_scene(work / "scenes" / name)
    sceneflow = load_sceneflow(work / "results" / name / "sceneflow.npz")
    endpoint = np.linalg.norm(sceneflow.flow() - scene.read_gt_flow("left", 1), axis=-1)
    disparity = np.abs(sceneflow.disparity() - scene.read_gt_disparity("left", 1))
    return {
        "aep": float(np.nanmean(endpoint)),
        "median": float(np.nanmedian(endpoint)),
        "over_3px": float(np.nanmean(endpoint > 3.0)),
        "ade": float(np.nanmean(disparity)),
    }


def row(work: Path, record: dict) -> dict:
    """One scene's errors and the default's losses (dB) from its calibration ``record``."""
    psnr = {key: value["psnr"] for key, value in record["columns"].items()}
    best = max(v for k, v in psnr.items() if k.startswith("sceneflow/alpha="))
    default = psnr["sceneflow/default"]
    return {
        "scene": record["scene"],
        "description": record["description"],
        **errors(work, record["scene"]),
        "below_true": psnr["gt/default"] - default,
        "below_best": best - default,
        "over_monocular": default - psnr["initial-flow/monocular"],
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, required=True, help="the protocol's size folder")
    parser.add_argument("--results", type=Path, required=True, help="its results JSON")
    parser.add_argument("--output", type=Path, help="also write the report here")
    args = parser.parse_args(argv)
    try:
        records = json.loads(args.results.read_text())
    except (OSError, ValueError) as error:
        print(f"error: {args.results}: not a results JSON ({error})", file=sys.stderr)
        return 2
    from stereodeblur.evaluation.motion_cache import is_stored
    from stereodeblur.settings import DeblurSettings

    settings = DeblurSettings()
    missing = [
        r["scene"]
        for r in records
        if not is_stored(args.work / "results" / r["scene"], "sceneflow", settings)
    ]
    if missing:
        print(
            f"error: {args.work}: no scene flow of {', '.join(missing)} stored with today's "
            "estimator settings",
            file=sys.stderr,
        )
        return 2
    rows = sorted((row(args.work, r) for r in records), key=lambda r: -r["below_true"])
    bad = [r for r in rows if r["aep"] > 1.0]
    lines = [
        f"# Scene-flow estimates of {args.results.name}",
        "",
        "Command: `python benchmarks/sceneflow_errors.py "
        + " ".join(argv if argv is not None else sys.argv[1:])
        + "`.",
        "",
        f"{len(bad)} of {len(rows)} estimates are more than 1 px off on average; on them the "
        f"default is {np.mean([r['below_true'] for r in bad]):.2f} dB below the true motion on "
        f"average, on the others {np.mean([r['below_true'] for r in rows if r['aep'] <= 1.0]):.2f}"
        " dB.",
        "",
        "| scene | AEP (px) | median (px) | > 3 px | ADE (px) | true motion - default (dB) "
        "| best alpha - default (dB) | default - monocular (dB) | scene |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    lines += [
        f"| {r['scene']} | {r['aep']:.2f} | {r['median']:.2f} | {r['over_3px']:.1%} "
        f"| {r['ade']:.2f} | {r['below_true']:+.2f} | {r['below_best']:+.2f} "
        f"| {r['over_monocular']:+.2f} | {r['description']} |"
        for r in rows
    ]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.output:
        from stereodeblur.io.outputs import atomic_write_text

        atomic_write_text(args.output, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
