"""The exposure estimate with the true flow, and with each window's noise modelled on its own
sampling (a study: it changes no default).

    python benchmarks/study_exposure_bound.py SCENES_DIR [SCENES_DIR ...]

Per scene (frame 1): the estimate as ``deblur --exposure auto`` makes it (both views, DIS flows
to both neighbours), from the left view with DIS or the true flow to the next frame only, and
two variants of the window likelihood: ``geom``, the noise periodogram simulated on each
window's own streamlines (8 white-noise images through the same pre-filter and spline
sampling, bins smoothed over 3) instead of one template for every direction; ``geom+info``,
which also drops windows whose best texture model beats noise alone by less than 5 nats.
"""

from __future__ import annotations

import argparse
import inspect
from pathlib import Path

import numpy as np

import stereodeblur.blur.exposure as ex
import stereodeblur.pipeline.exposure as pe
from stereodeblur.io import open_scene
from stereodeblur.pipeline.motion import view_dense_flow
from stereodeblur.pipeline.window import read_window, views_read
from stereodeblur.settings import DeblurSettings

FRAME = 1
BASE = ex.duty_cycle_curves
SOURCE = inspect.getsource(ex.duty_cycle_curves)


def _variant(threshold: float | None):
    """``duty_cycle_curves`` with each window's own noise spectrum (and an information test)."""
    src = SOURCE.replace(
        "        prof = ndimage.map_coordinates(coef, coords, order=3, prefilter=False)\n",
        "        prof = ndimage.map_coordinates(coef, coords, order=3, prefilter=False)\n"
        "        nrng = np.random.default_rng(7)\n"
        "        sim = []\n"
        "        for _ in range(8):\n"
        "            nimg = nrng.standard_normal(gray.shape)\n"
        "            nimg = ndimage.gaussian_filter(nimg, sig) if sig > 0 else nimg\n"
        "            ncoef = ndimage.spline_filter(nimg, order=3)\n"
        "            sim.append(ndimage.map_coordinates(ncoef, coords, order=3, prefilter=False))\n"
        "        sim = np.stack(sim).reshape(8, int(sel.sum()), lines, -1)\n",
    )
    src = src.replace(
        "            nll, dev = _window_curve(p_hat, tex[lidx], sigma_n**2 * nt, nu)\n",
        "            own = _periodogram(sim[:, i][:, ok].reshape(-1, sim.shape[-1])).mean(axis=0)\n"
        "            own = sigma_n**2 * ndimage.uniform_filter1d(own, 3, mode='nearest')\n"
        "            nll, dev = _window_curve(p_hat, tex[lidx], own, nu)\n"
        "            if nu * np.sum(np.log(own) + p_hat / own) - nll.min() < THRESHOLD:\n"
        "                continue\n",
    )
    names = dict(vars(ex), THRESHOLD=-np.inf if threshold is None else threshold)
    exec(src, names)
    return names["duty_cycle_curves"]


def _left_forward(window, flow) -> float:
    stride = ex.window_stride(window.shape, ex.WINDOWS)
    flows = ex.central_flow({window.neighbour - window.index: flow})
    found = ex.duty_cycle_from_curves(
        ex.duty_cycle_curves(window.blurred("left"), flows, stride=stride)
    )
    return found.duty_cycle if found.windows else 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path)
    args = parser.parse_args()
    columns = ["auto", "dis-left", "true-flow-left", "geom", "geom+info"]
    for folder in args.folders:
        within = dict.fromkeys(columns, 0)
        sharp = dict.fromkeys(columns, 0)
        roots = sorted(p for p in folder.iterdir() if (p / "camera.json").is_file())
        for root in roots:
            scene = open_scene(root)
            settings = DeblurSettings()
            views = views_read(settings, ("left",))
            window = read_window(scene, FRAME, views, settings)
            rate = window.exposure.frame_rate
            truth = window.exposure.exposure * rate
            dense = {v: view_dense_flow(window, v) for v in views}
            found = {}
            for name, curves in (
                ("auto", BASE),
                ("geom", _variant(None)),
                ("geom+info", _variant(5.0)),
            ):
                ex.duty_cycle_curves = pe.duty_cycle_curves = curves
                found[name] = pe.estimate_exposure(window, dense).exposure.exposure * rate
            ex.duty_cycle_curves = pe.duty_cycle_curves = BASE
            found["dis-left"] = _left_forward(window, dense["left"][0])
            found["true-flow-left"] = _left_forward(window, scene.read_gt_flow("left", FRAME))
            for name in columns:
                within[name] += abs(found[name] / truth - 1) <= 0.2
                sharp[name] += found[name] == 0
            print(
                root.name,
                f"truth {truth:.2f}",
                *(f"{n} {found[n] / truth - 1:+.0%}" for n in columns),
                flush=True,
            )
        print(
            folder,
            "within 20 % (read as sharp):",
            *(f"{n} {within[n]}/{len(roots)} ({sharp[n]})" for n in columns),
        )


if __name__ == "__main__":
    main()
