"""Scene-flow settings on the calibration scenes: the estimate's error per settings variant.

Run from the repository root::

    python benchmarks/study_sceneflow_settings.py --split train --scenes 40 --jobs 2 \\
        --variants "smoothness=1;smoothness=4;edge_floor=0.5"

For every scene of the split (``calibrate_defaults.py``'s family and street scenes, rendered
into ``--work`` if needed) the scene flow of frame 1 (left view, the blurred frames 1 and 2,
with the exposure, frame 0 on the other side) is estimated with the default
:class:`SceneFlowSettings` and with each variant (``field=value[,field=value]``, variants
separated by ``;``; ``true`` / ``false`` for a switch). Errors against the rendered flow:
the mean end-point error, the share of pixels more than 3 px off, and the
*textured* end-point error, each pixel weighted by the sharp frame's gradient magnitude
(Sobel, averaged over 5 x 5) with errors clipped at 20 px: what the deblurring pays for, where
an error on a flat wall costs nothing and one segment flying off does not swamp the mean. No
deblurring. Output: a Markdown table on stdout and in ``--output``, a ``.json`` beside.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

CLIP = 20.0
"""px: end-point errors are clipped here in the textured mean."""
BETTER = 0.3
"""px of textured end-point error a variant must gain (lose) on a scene to count as a win
(loss)."""


def parse_variants(text: str) -> dict[str, dict]:
    """``"a=1,b=0.5;c=3"`` -> ``{"a=1,b=0.5": {"a": 1, "b": 0.5}, "c=3": {"c": 3}}``."""
    from stereodeblur.sceneflow.settings import SceneFlowSettings

    known = SceneFlowSettings.__dataclass_fields__
    out = {}
    for item in filter(None, (part.strip() for part in text.split(";"))):
        overrides = {}
        for pair in item.split(","):
            name, _, value = pair.partition("=")
            name = name.strip()
            if name not in known or not value:
                raise SystemExit(f"--variants: {pair!r} is not field=value of SceneFlowSettings")
            if value.strip().lower() in ("true", "false"):
                overrides[name] = value.strip().lower() == "true"
                continue
            number = float(value)
            overrides[name] = int(number) if number.is_integer() and "." not in value else number
        SceneFlowSettings(**overrides)  # checks the values
        out[item] = overrides
    return out


def flow_errors(flow: np.ndarray, truth: np.ndarray, sharp: np.ndarray) -> dict:
    """Mean, textured mean and > 3 px share of the end-point error of ``flow``."""
    from scipy import ndimage

    from stereodeblur.evaluation.metrics import endpoint_error

    gray = sharp.mean(axis=-1) if sharp.ndim == 3 else sharp
    weight = ndimage.uniform_filter(np.hypot(ndimage.sobel(gray, 0), ndimage.sobel(gray, 1)), 5)
    endpoint = np.linalg.norm(flow - truth, axis=-1)
    known = np.isfinite(endpoint)
    weight = np.where(known, weight, 0.0)
    clipped = np.minimum(np.where(known, endpoint, 0.0), CLIP)
    return {
        "aep": endpoint_error(flow, truth),
        "textured": float((weight * clipped).sum() / max(weight.sum(), 1e-12)),
        "over_3px": float(np.nanmean(endpoint > 3.0)),
    }


def run_scene(task) -> dict:
    """Every variant's errors on one scene."""
    import warnings

    from stereodeblur.io.scene import open_scene
    from stereodeblur.sceneflow import estimate_scene_flow
    from stereodeblur.sceneflow.settings import SceneFlowSettings

    kind, seed, size, work, variants = task
    scene = open_scene(protocol.ensure_scene(kind, seed, size, Path(work)))
    frames = [scene.read_frame(v, i) for i in (1, 2) for v in ("left", "right")]
    other_side = None  # frame 0, read if a variant matches there
    if any(overrides.get("other_side") for overrides in variants.values()):
        other_side = tuple(scene.read_frame(v, 0) for v in ("left", "right"))
    truth = scene.read_gt_flow("left", 1)
    sharp = scene.read_gt_sharp("left", 1)
    out = {}
    for name, overrides in {"default": {}, **variants}.items():
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            estimate = estimate_scene_flow(
                *frames,
                scene.info.camera,
                settings=SceneFlowSettings(**overrides),
                exposure=scene.info.exposure,
                other_side=other_side,
            )
        errors = flow_errors(estimate.sceneflow.flow(), truth, sharp)
        out[name] = {**errors, "seconds": time.perf_counter() - start}
    return {"scene": scene.root.name, "variants": out}


def report(rows, variants, args, seconds: float) -> str:
    """Markdown: per variant the means and wins / losses, then every scene."""
    names = ["default", *variants]
    lines = [
        f"# Scene-flow settings, {args.split} split, {len(rows)} scenes, {args.size}",
        "",
        f"Command: `python benchmarks/study_sceneflow_settings.py --split {args.split} "
        f"--scenes {args.scenes} --skip {args.skip} --size {args.size} --jobs {args.jobs} "
        f'--variants "{args.variants}"`; {seconds / 60:.1f} min. '
        f"Code: {protocol.code_version()}.",
        "",
        f"End-point error (px) of frame 1's flow, left view. Textured: weighted by the sharp "
        f"frame's gradient magnitude, errors clipped at {CLIP:g} px. Wins / losses: scenes "
        f"where the textured error is more than {BETTER} px below / above the default's.",
        "",
        "| variant | mean | textured | > 3 px | wins / losses | worst loss |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for name in names:
        mine = np.array([r["variants"][name]["textured"] for r in rows])
        base = np.array([r["variants"]["default"]["textured"] for r in rows])
        worst = int(np.argmax(mine - base))
        loss = f"{mine[worst] - base[worst]:+.2f} ({rows[worst]['scene']})"
        lines.append(
            f"| {name} | {np.mean([r['variants'][name]['aep'] for r in rows]):.2f} "
            f"| {mine.mean():.3f} "
            f"| {np.mean([r['variants'][name]['over_3px'] for r in rows]):.3f} "
            f"| {int(np.sum(base - mine > BETTER))} / {int(np.sum(mine - base > BETTER))} "
            f"| {loss if name != 'default' else ''} |"
        )
    lines += ["", "Textured end-point error per scene (px):", ""]
    lines += ["| scene | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
    for r in rows:
        values = " | ".join(f"{r['variants'][n]['textured']:.2f}" for n in names)
        lines.append(f"| {r['scene']} | {values} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", choices=("train", "test"), default="train")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--scenes", type=int, default=40)
    parser.add_argument("--skip", type=int, default=0)
    parser.add_argument("--variants", required=True, help='"field=value[,field=value];..."')
    parser.add_argument("--work", default=str(Path(tempfile.gettempdir()) / "stereodeblur_calib"))
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--output", type=Path)
    args = parser.parse_args(argv)
    variants = parse_variants(args.variants)
    size = tuple(int(v) for v in args.size.lower().split("x"))
    work = Path(args.work) / args.size
    names = protocol.scene_list(args.split, args.scenes, protocol.KINDS, args.skip)
    for kind, seed in names:  # rendered here: parallel workers would render a scene twice
        protocol.ensure_scene(kind, seed, size, work)
    tasks = [(kind, seed, size, str(work), variants) for kind, seed in names]
    start = time.perf_counter()
    rows = protocol.run_all(run_scene, tasks, args.jobs)
    text = report(rows, variants, args, time.perf_counter() - start)
    print(text)
    if args.output is not None:
        args.output.write_text(text, encoding="utf-8")
        args.output.with_suffix(".json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
