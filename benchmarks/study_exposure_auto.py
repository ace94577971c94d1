"""Study: how the exposure estimate's windows are combined, a shrink of the estimate, and what
the exposure check should do when a given exposure and the frames disagree.

Run from the repository root on the calibration protocol's training scenes (rendered by
``calibrate_defaults.py``; any folder of scene folders)::

    python benchmarks/study_exposure_auto.py rules SCENES_DIR --cache DIR
    python benchmarks/study_exposure_auto.py policy SCENES_DIR --cache DIR

``rules``: each scene's window curves (frame 1, both views, DIS central flow, as
``--exposure auto`` computes them) once, then the share of scenes within 20 % of the true duty
cycle for caps of a window's vote, a kernel vote over the windows' minima, their median, and the
estimate scaled by 0.85-0.95. ``policy``: the default on frame 1 (left view) given the true
exposure, half and twice it, and with ``--exposure auto``; then, per tolerance F, the mean gain
over the blurred input if the frames' estimate replaced every given exposure more than a factor F
away from it.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np


def scene_dirs(root: Path) -> list[Path]:
    return sorted(p for p in root.iterdir() if (p / "camera.json").is_file())


def window_curves(root: Path, cache: Path):
    """The window curves of frame 1 of both views and the true duty cycle, cached."""
    from stereodeblur.blur import exposure as ex
    from stereodeblur.io.scene import open_scene
    from stereodeblur.sceneflow.initial import initial_optical_flow

    path = cache / f"{root.name}.npz"
    if not path.is_file():
        scene = open_scene(root)
        stride = ex.window_stride(scene.shape, ex.WINDOWS // 2)
        curves = []
        for view in ("left", "right"):
            f = [scene.read_frame(view, i) for i in range(3)]
            flows = {1: initial_optical_flow(f[1], f[2]), -1: initial_optical_flow(f[1], f[0])}
            curves.append(ex.duty_cycle_curves(f[1], ex.central_flow(flows), stride=stride))
        np.savez(path, curves=np.vstack(curves), truth=scene.info.exposure.duty_cycle)
    with np.load(path) as z:
        return z["curves"], float(z["truth"])


def rules(args) -> None:
    from stereodeblur.blur.exposure import DEFAULT_CANDIDATES as cand
    from stereodeblur.blur.exposure import duty_cycle_from_curves

    log_c = np.log(np.maximum(cand, 0.01))

    def vote(c, width):
        w = np.exp(-0.5 * ((log_c[None, :] - log_c[c.argmin(1)][:, None]) / width) ** 2)
        return cand[w.sum(0).argmax()]

    candidates = {f"cap {k}": (lambda c, k=k: duty_cycle_from_curves(c, cap=k).duty_cycle)
                  for k in (1, 3, 10, 30)}  # fmt: skip
    candidates |= {f"vote {w}": (lambda c, w=w: vote(c, w)) for w in (0.1, 0.2)}
    candidates["median"] = lambda c: float(np.median(cand[c.argmin(1)]))
    candidates |= {f"cap 10 x {s}": (lambda c, s=s: s * duty_cycle_from_curves(c).duty_cycle)
                   for s in (0.95, 0.9, 0.85)}  # fmt: skip
    errors = {k: [] for k in candidates}
    for root in scene_dirs(args.scenes):
        curves, truth = window_curves(root, args.cache)
        if len(curves):
            for name, rule in candidates.items():
                errors[name].append(rule(curves) / truth - 1)
    print("| rule | within 20 % | over +20 % | under -20 % |\n|---|---:|---:|---:|")
    for name, e in errors.items():
        e = np.array(e)
        print(f"| {name} | {np.sum(np.abs(e) <= 0.2)} / {e.size} | {np.sum(e > 0.2)} | "
              f"{np.sum(e < -0.2)} |")  # fmt: skip


def run(root: Path, mode: str, cache: Path) -> dict:
    """The default's PSNR on frame 1 (left) of ``root`` for ``mode``, cached."""
    from stereodeblur.evaluation.metrics import border_for, psnr
    from stereodeblur.io.scene import open_scene
    from stereodeblur.io.sources import open_source
    from stereodeblur.pipeline import deblur_stereo_frame
    from stereodeblur.settings import DeblurSettings

    path = cache / f"{root.name}.{mode}.json"
    if path.is_file():
        return json.loads(path.read_text())
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", 1)
    timing = scene.info.exposure
    if mode.startswith("x"):
        scene = open_source(
            root, exposure=min(float(mode[1:]) * timing.exposure, 1 / timing.frame_rate)
        )
    settings = DeblurSettings(exposure="auto" if mode == "auto" else "given")
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        frame = deblur_stereo_frame(scene, 1, views=("left",), settings=settings).frames["left"]
    border = border_for(truth.shape[1])
    data = {
        "psnr": psnr(frame.image, truth, border=border),
        "blurred": psnr(frame.blurred, truth, border=border),
        "duty": frame.exposure * timing.frame_rate,
        "seconds": time.perf_counter() - start,
    }
    path.write_text(json.dumps(data))
    return data


def policy(args) -> None:
    modes = ("x1", "x0.5", "x2", "auto")
    runs = {
        root.name: {m: run(root, m, args.cache) for m in modes} for root in scene_dirs(args.scenes)
    }
    print("| F | given: true / half / twice, mean gain (worst) [overridden] |\n|---|---|")
    for tolerance in (1.25, 1.4, 1.6, 2.0, None):
        cells = []
        for mode in modes[:3]:
            gains, overridden = [], 0
            for r in runs.values():
                given, auto = r[mode], r["auto"]
                apart = auto["duty"] == 0 or abs(np.log(given["duty"] / auto["duty"])) > np.log(
                    tolerance or np.inf
                )
                use = auto if apart and tolerance else given
                overridden += use is auto
                gains.append(use["psnr"] - use["blurred"])
            cells.append(f"{np.mean(gains):+.2f} ({min(gains):+.2f}) [{overridden}]")
        print(f"| {tolerance or 'never'} | {' / '.join(cells)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("study", choices=("rules", "policy"))
    parser.add_argument("scenes", type=Path)
    parser.add_argument("--cache", type=Path, required=True)
    args = parser.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    {"rules": rules, "policy": policy}[args.study](args)


if __name__ == "__main__":
    main()
