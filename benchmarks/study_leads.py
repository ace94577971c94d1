"""Four leads measured and not adopted (kept in git; docs/defaults.md cites this commit).

Run from the repository root; scenes of the calibration protocol's training split, 320x240,
rendered into ``--work``; frame 1, left view, estimated motion; PSNR as everywhere::

    python benchmarks/study_leads.py confidence-smoothness --scenes 16   # and KITTI below
    python benchmarks/study_leads.py jacobi --scenes 1 --cg 12
    python benchmarks/study_leads.py warm-final --irls 2 --scenes 16
    python benchmarks/study_leads.py exposure --scenes 5 --factors 0.5,1,2

- ``confidence-smoothness``: the fusion's smoothness per edge scaled by
  ``floor + (1 - floor) / (1 + spread / scale)`` of the more ambiguous of its two segments
  (``spread``: mean minus least census cost of the segment's candidates, per pixel); with
  ``--kitti DIR`` it runs ``kitti_sceneflow.py`` on DIR (frames 2, 3, 7) instead.
- ``jacobi``: the IRLS's conjugate gradients preconditioned by the diagonal of the normal
  equations (every data term's ``(A o A)^T w^2``, the prior's, the anchor's).
- ``warm-final``: the final solve (every observation, the chosen alpha) started from the chosen
  alpha candidate's solution with ``--irls`` iterations instead of from the blurred frame.
- ``exposure``: the default with the exposure scaled by each factor (at most the frame
  interval): PSNR, the blurred frame's, the range guard's share.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from calibrate_defaults import KINDS, ensure_scene, scene_list

from stereodeblur import pipeline
from stereodeblur.deconv import irls
from stereodeblur.evaluation.metrics import border_for, psnr
from stereodeblur.geometry.camera import Exposure
from stereodeblur.io.scene import open_scene
from stereodeblur.settings import DeblurSettings


def confidence_smoothness(scale: float, floor: float) -> None:
    """Patch the fusion: each edge's smoothness scaled by its segments' data confidence."""
    from stereodeblur.sceneflow import selection

    costs, tables = selection.data_costs, selection.pairwise_tables
    last = {}

    def data_costs(*args, **kwargs):
        last["D"] = costs(*args, **kwargs)
        return last["D"]

    def pairwise_tables(camera, graph, cands, props, *, edge_weights, **kwargs):
        D = last["D"]
        finite = np.isfinite(D)
        count = finite.sum(axis=1)
        least = np.where(finite, D, np.inf).min(axis=1)
        mean = np.where(finite, D, 0).sum(axis=1) / np.maximum(count, 1)
        spread = np.where(count > 1, (mean - least) / np.maximum(graph.sizes, 1), 0.0)
        m = floor + (1 - floor) / (1 + spread / scale)
        m = np.maximum(m[graph.edges[:, 0]], m[graph.edges[:, 1]])
        return tables(camera, graph, cands, props, edge_weights=edge_weights * m, **kwargs)

    selection.data_costs, selection.pairwise_tables = data_costs, pairwise_tables


def jacobi() -> None:
    """Patch the IRLS: CG preconditioned by the diagonal of the normal equations."""
    made = {}
    plain = irls._NormalEquations

    class System(plain):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made["system"] = self

    def squared(operator):
        m = operator.matrix.copy()
        m.data = m.data.astype(np.float64) ** 2
        return m.T.tocsr()

    def diagonal(system):
        H, W, C = system.shape if len(system.shape) == 3 else (*system.shape, 1)
        d = np.zeros(H * W)
        for term in [system.own, *system.extras]:
            d += squared(term.operator) @ term.squared.reshape(-1).astype(np.float64)
        d = np.repeat(d.reshape(H, W, 1), C, axis=2)
        wx, wy = (w.reshape(H, W, C).astype(np.float64) for w in (system.wx, system.wy))
        d += wx + wy
        d[:, 1:] += wx[:, :-1]
        d[1:] += wy[:-1]
        if system.beta3 is not None:
            d += system.beta3.reshape(H, W, C)
        return d.reshape(system.b3.shape)

    def solve(apply, b, x, *, num_iterations, rtol, residual=None):
        inverse = (1.0 / np.maximum(diagonal(made["system"]), 1e-12)).astype(np.float32)
        partial = np.empty((b.shape[0], b.shape[2]))
        r = residual if residual is not None else b - apply(x, partial)
        z = inverse * r
        rz = np.einsum("ijc,ijc->c", r, z, dtype=np.float64)
        p, norms = z.copy(), [np.sqrt(np.einsum("ijc,ijc->c", r, r, dtype=np.float64))]
        for _ in range(num_iterations):
            q = apply(p, partial)
            curvature = partial.sum(axis=0)
            step = np.where(curvature > 0, rz / np.where(curvature > 0, curvature, 1), 0)
            x += step.astype(np.float32) * p
            r -= step.astype(np.float32) * q
            z = inverse * r
            rz, previous = np.einsum("ijc,ijc->c", r, z, dtype=np.float64), rz
            p = (
                z
                + np.where(previous > 0, rz / np.where(previous > 0, previous, 1), 0).astype(
                    np.float32
                )
                * p
            )
            norms.append(np.sqrt(np.einsum("ijc,ijc->c", r, r, dtype=np.float64)))
        return x, np.array(norms), num_iterations

    irls._NormalEquations, irls.solve = System, solve


def warm_final(iterations: int) -> None:
    """Patch the final solve: started from the chosen candidate, ``iterations`` IRLS."""
    from stereodeblur.pipeline import deconvolve, frame

    guarded, plain = frame.guarded_solve, deconvolve.solve
    chosen = {}

    def guarded_solve(blurred, operator, terms, settings, weights, observations, *rest):
        if not observations:
            result, unexplained = guarded(
                blurred, operator, terms, settings, weights, observations, *rest
            )
            chosen[terms.alpha] = None if unexplained is not None else result.image
            return result, unexplained
        start = chosen.get(terms.alpha)
        if start is None:
            return guarded(blurred, operator, terms, settings, weights, observations, *rest)
        result = irls.deblur_irls(
            blurred,
            operator.operator,
            weights=terms.weights if weights is None else weights,
            alpha=terms.alpha,
            alpha_scale=terms.alpha_scale,
            num_irls=iterations,
            num_cg=settings.num_cg,
            update_weights=terms.update,
            anchor=terms.anchor,
            observations=[o.observation for o in observations],
            robust_scale=deconvolve.OBSERVATION_ROBUST_SCALE,
            initial=start,
        )
        return result, None

    frame.guarded_solve = guarded_solve
    assert plain is deconvolve.solve


class Exposed:
    """``scene`` with its exposure scaled by ``factor`` (at most the frame interval)."""

    def __init__(self, scene, factor: float):
        self._scene = scene
        e = scene.info.exposure
        exposure = Exposure(e.frame_rate, min(e.exposure * factor, 1 / e.frame_rate))
        self.info = replace(scene.info, exposure=exposure)

    def __getattr__(self, name):
        return getattr(self._scene, name)


def deblurred(scene, settings):
    return pipeline.deblur_stereo_frame(scene, 1, views=("left",), settings=settings).frames["left"]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "study", choices=("confidence-smoothness", "jacobi", "warm-final", "exposure")
    )
    parser.add_argument("--scenes", type=int, default=16)
    parser.add_argument("--work", type=Path, default=Path("/tmp/study_leads"))
    parser.add_argument("--scale", type=float, default=0.1)
    parser.add_argument("--floor", type=float, default=0.25)
    parser.add_argument("--cg", type=int, default=25)
    parser.add_argument("--irls", type=int, default=2)
    parser.add_argument("--factors", default="0.5,1,2")
    parser.add_argument("--kitti", type=Path)
    parser.add_argument("--baseline", action="store_true", help="the default, unpatched")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    if args.study == "confidence-smoothness" and args.kitti and not args.baseline:
        code = (
            "import sys, runpy; sys.argv = sys.argv[1:]; sys.path.insert(0, 'benchmarks');"
            "import study_leads;"
            f"study_leads.confidence_smoothness({args.scale!r}, {args.floor!r});"
            "runpy.run_path('benchmarks/kitti_sceneflow.py', run_name='__main__')"
        )
        script = ["kitti_sceneflow.py", str(args.kitti), "--frames", "2,3,7"]
        subprocess.run([sys.executable, "-c", code, *script], check=True)
        return
    settings = DeblurSettings()
    if not args.baseline:
        if args.study == "confidence-smoothness":
            confidence_smoothness(args.scale, args.floor)
        elif args.study == "jacobi":
            jacobi()
        elif args.study == "warm-final":
            warm_final(args.irls)
    if args.study == "jacobi":
        settings = replace(settings, num_cg=args.cg)
    rows = {}
    for kind, seed in scene_list("train", args.scenes, KINDS):
        scene = open_scene(ensure_scene(kind, seed, (320, 240), args.work))
        truth = scene.read_gt_sharp("left", 1)
        border = border_for(truth.shape[1])
        if args.study != "exposure":
            rows[scene.name] = psnr(deblurred(scene, settings).image, truth, border=border)
            print(scene.name, f"{rows[scene.name]:.2f}", flush=True)
            continue
        blurred = scene.read_frame("left", 1)
        for factor in (float(f) for f in args.factors.split(",")):
            result = deblurred(Exposed(scene, factor), settings)
            x = np.clip(result.result.image, 0, 1).astype(np.float32)
            row = {
                "psnr": psnr(x, truth, border=border),
                "blurred": psnr(blurred, truth, border=border),
                "alpha": result.alpha,
                "range guard": 0.0 if result.unexplained is None else result.unexplained.mean(),
            }
            rows[f"{scene.name} x{factor:g}"] = row
            print(scene.name, factor, json.dumps(row), flush=True)
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
