"""Where the model's error on noiseless frames comes from (issue 12, stop 52).

Run from the repository root::

    python benchmarks/study_model_error.py --split train --scenes 16 --size 320x240 --jobs 2

On a noiseless frame the error that the prior weight must absorb is the model's. For every
noiseless scene among the split's first ``--scenes`` (rendered into ``--work`` as
``calibrate_defaults.py`` renders them), the true sharp frame 1 (left) is blurred with the true
motion and compared with the rendered blurred frame: the RMS of the difference over the pixels
at least the PSNR's border from the image edge, more than :data:`MIXED_MARGIN` px from
``gt/mixed`` and whose exposure stays inside the image (:func:`kept_pixels`,
:func:`misfit`). Operator variants (:data:`OPERATORS`): the pipeline's own (the scene flow
fitted to the ground truth, Keys' cubic kernel, ``num_samples`` instants), four times the
instants, bilinear taps, a cubic B-spline on the same trajectories (scipy, the image
prefiltered), and the straight trajectories of the dense true flow instead of the fitted planes
(Keys' kernel). Render variants (the scene rendered again into ``WORK/model_error/``): nine
times the instants (one ray per pixel and instant, as the family renders), and nine times the
instants with 9 x 9 instead of 3 x 3 rays per pixel side for the sharp frame and the instants'
offsets. For the family's render and the 9 x 9 one, the pipeline's result with the true motion
at every grid alpha (PSNR). Written: ``benchmarks/results/model_error_SPLIT_WxH.md`` and ``.json``.
"""

from __future__ import annotations

import json
import sys
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

from stereodeblur.synth.scenespec import SUPERSAMPLING  # noqa: E402

MIXED_MARGIN = 3
"""Pixels within this distance of ``gt/mixed`` are left out (the exposure mixes surfaces)."""
SAMPLES_FACTOR = 4
"""The operator variant's instants per the pipeline's."""
RENDERS = (("9x instants", 3, 9), ("9x instants, 9x9 rays", 9, 9))
"""Render variants: label, rays per pixel side, instants per the family's."""
OPERATORS = (
    "pipeline",
    f"{SAMPLES_FACTOR}x instants",
    "bilinear",
    "cubic B-spline",
    "dense true flow",
)
"""Operator variants, in the report's order."""


def model_error(task) -> tuple[str, dict | None]:
    """One scene's record (see the module's docstring), None for a noisy scene."""
    from stereodeblur.io.scene import open_scene

    kind, seed, size, work = task
    root = protocol.ensure_scene(kind, seed, size, work)
    spec = json.loads((root / "gt" / "family.json").read_text(encoding="utf-8"))
    if spec["noise"] > 0:
        return root.name, None
    scene = open_scene(root)
    errors, counted = operator_errors(scene)
    record = {
        "blur_px": spec["blur_px"],
        "description": spec["description"],
        "counted": counted,
        "operators": errors,
        "renders": {},
        "psnr": {"family render": grid_psnrs(scene, work / "results" / root.name)},
    }
    for label, rays, factor in RENDERS:
        path = rerender(kind, seed, size, work, rays, factor)
        other = open_scene(path)
        record["renders"][label] = operator_errors(other, variants=("pipeline",))[0]["pipeline"]
        if rays != SUPERSAMPLING:
            record["psnr"][label] = grid_psnrs(other, path.parent / "results" / path.name)
    return root.name, record


def rerender(kind: str, seed: int, size, work: Path, rays: int, factor: int) -> Path:
    """The scene rendered again with ``rays`` per pixel side and ``factor`` times the instants,
    into ``work / 'model_error'`` (once)."""
    from stereodeblur.synth.family import family_scene, write_family_scene
    from stereodeblur.synth.street import street_scene

    spec = (family_scene if kind == "family" else street_scene)(seed, size=size)
    root = work / "model_error" / f"{spec.name}_rays{rays}_x{factor}"
    if not root.is_dir():
        root.parent.mkdir(parents=True, exist_ok=True)
        spec = replace(spec, supersampling=rays)
        write_family_scene(spec, root, num_samples=spec.num_samples * factor)
    return root


def kept_pixels(scene, border: int, positions) -> np.ndarray:
    """Pixels :func:`misfit` counts: off the border, away from ``gt/mixed`` and with every
    instant's position in ``positions`` (``(px, py)`` per instant) inside the image (what
    comes in from outside, no operator can know)."""
    from scipy import ndimage

    mixed = np.asarray(scene.read_gt_mixed("left", protocol.FRAME)).astype(bool)
    mixed = mixed.any(axis=-1) if mixed.ndim == 3 else mixed
    keep = ~ndimage.binary_dilation(mixed, iterations=MIXED_MARGIN)
    keep[:border], keep[-border:], keep[:, :border], keep[:, -border:] = False, False, False, False
    height, width = keep.shape
    for px, py in positions:
        keep &= (px >= 0) & (px <= width - 1) & (py >= 0) & (py <= height - 1)
    return keep


def misfit(predicted, blurred, keep) -> float:
    """RMS of ``predicted - blurred`` over the ``keep`` pixels (channels averaged)."""
    from stereodeblur.pipeline.alpha import pixel_errors

    return float(np.sqrt(pixel_errors(predicted, blurred, border=0)[keep].mean()))


def channels(image: np.ndarray) -> list[np.ndarray]:
    """The planes of ``image`` (one for a grey image)."""
    return [image[..., c] for c in range(image.shape[-1])] if image.ndim == 3 else [image]


def keys_sample(plane: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """``plane`` at ``(px, py)`` by Keys' cubic convolution, as the blur operator gathers
    (:func:`~stereodeblur.blur.trajectories.cubic_taps`, clamped to the image)."""
    from stereodeblur.blur.trajectories import cubic_taps

    index, weight, _ = cubic_taps(np.stack([px, py], axis=-1), plane.shape, border="clamp")
    return (plane.ravel()[index] * weight).sum(axis=-1)


def gathered(planes, positions, sample) -> np.ndarray:
    """Mean over the instants of ``sample(plane, px, py)`` at ``positions`` (``(px, py)`` per
    instant) for every plane of ``planes``, stacked on the last axis (one plane: 2D)."""
    total, count = np.zeros(planes[0].shape + (len(planes),)), 0
    for px, py in positions:
        count += 1
        for c, plane in enumerate(planes):
            total[..., c] += sample(plane, px, py)
    mean = total / count
    return mean[..., 0] if len(planes) == 1 else mean


def homography_positions(sceneflow, exposure, num_samples: int, chunk: int = 10):
    """``(px, py)`` of every pixel at each instant under its segment's homographies."""
    from stereodeblur.blur.trajectories import homography_positions as positions

    homographies = np.asarray(sceneflow.homographies(exposure.sample_fractions(num_samples)))
    labels = np.asarray(sceneflow.labels, dtype=np.int32)
    for start in range(0, num_samples, chunk):
        part = positions(np.ascontiguousarray(homographies[:, start : start + chunk]), labels)
        for k in range(part.shape[2]):
            yield part[:, :, k, 0], part[:, :, k, 1]


def flow_positions(scene, exposure, num_samples: int):
    """``(px, py)`` of every pixel at each instant along the dense true flow: ``x - s f(x)``
    with the flow to the next frame for ``s >= 0``, to the previous one for ``s < 0``."""
    from stereodeblur.pipeline.motion import invert_flow

    forward = scene.read_gt_flow("left", protocol.FRAME).astype(np.float64)
    backward = invert_flow(scene.read_gt_flow("left", protocol.FRAME - 1)).astype(np.float64)
    y, x = np.mgrid[0 : forward.shape[0], 0 : forward.shape[1]].astype(np.float64)
    for s in exposure.sample_fractions(num_samples):
        flow = forward if s >= 0 else backward
        yield x - abs(s) * flow[..., 0], y - abs(s) * flow[..., 1]


def operator_errors(scene, variants=OPERATORS) -> tuple[dict, float]:
    """:func:`misfit` of the true sharp frame under each operator variant in ``variants``, and
    the share of the frame it counts."""
    from scipy import ndimage

    from stereodeblur.evaluation.metrics import border_for
    from stereodeblur.pipeline import frame_motion
    from stereodeblur.pipeline.operator import build_operator

    settings = protocol.unmoved("gt")
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    blurred = scene.read_frame("left", protocol.FRAME)
    motion = frame_motion(scene, protocol.FRAME, "left", settings)
    exposure, num = scene.info.exposure, settings.num_samples
    positions = list(homography_positions(motion.sceneflow, exposure, num))
    keep = kept_pixels(scene, border_for(truth.shape[1]), positions)

    def operator(**changes):
        built = build_operator(motion, exposure, replace(settings, **changes))
        return built.forward(truth)

    def bspline(coefficients, px, py):
        return ndimage.map_coordinates(
            coefficients, [py, px], order=3, mode="nearest", prefilter=False
        )

    predictions = {
        "pipeline": lambda: operator(),
        f"{SAMPLES_FACTOR}x instants": lambda: operator(num_samples=SAMPLES_FACTOR * num),
        "bilinear": lambda: operator(interpolation="bilinear"),
        "cubic B-spline": lambda: gathered(
            [ndimage.spline_filter(c, order=3, mode="nearest") for c in channels(truth)],
            positions,
            bspline,
        ),
        "dense true flow": lambda: gathered(
            channels(truth), flow_positions(scene, exposure, num), keys_sample
        ),
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        errors = {name: misfit(predictions[name](), blurred, keep) for name in variants}
    return errors, float(keep.mean())


def grid_psnrs(scene, cache: Path) -> list[float]:
    """PSNR of the left view's frame 1 deblurred with the true motion and the default settings
    at every grid alpha: the calibration's columns, read from or stored in ``cache``."""
    cache.mkdir(parents=True, exist_ok=True)
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    motions, seconds = {}, {}
    return [
        protocol.cached_column(scene, column, truth, cache, motions, seconds)["psnr"]
        for column in protocol.grid_columns("gt")
    ]


def report(rows: dict, work: Path, args, minutes: float) -> list[str]:
    records = {name: r for name, r in rows.items() if r is not None}
    renders = [label for label, _, _ in RENDERS]
    lines = [
        f"# The model's error on noiseless frames: {args.split} split, {args.size}, "
        f"{len(records)} noiseless scenes of {len(rows)}",
        "",
        f"Command: `python benchmarks/study_model_error.py {' '.join(sys.argv[1:])}`; "
        f"{minutes:.1f} min (records cached under --work are reused); code "
        f"{protocol.code_version()}. RMS of the true sharp frame blurred with the true motion "
        "minus the rendered blurred frame (left view, frame 1), away from the border, more "
        f"than {MIXED_MARGIN} px from gt/mixed and where the exposure stays inside the image; "
        "the share of the frame counted; columns: the operator's variants on the "
        "family's render (3 x 3 rays per pixel side, one per instant), then the pipeline's "
        "operator on the scene rendered again.",
        "",
        "| scene | blur (px) | counted | "
        + " | ".join(OPERATORS)
        + " | "
        + " | ".join(renders)
        + " |",
        "|---|---|---|" + "---|" * (len(OPERATORS) + len(renders)),
    ]
    for name, r in records.items():
        cells = [f"{r['operators'][k]:.5f}" for k in OPERATORS]
        cells += [f"{r['renders'][k]:.5f}" for k in renders]
        counted = f"{r['counted']:.0%}"
        lines.append(f"| {name} | {r['blur_px']:.1f} | {counted} | " + " | ".join(cells) + " |")
    if records:
        means = [np.mean([r["operators"][k] for r in records.values()]) for k in OPERATORS]
        means += [np.mean([r["renders"][k] for r in records.values()]) for k in renders]
        lines.append("| mean | | | " + " | ".join(f"{m:.5f}" for m in means) + " |")
    lines += [
        "",
        "PSNR (dB) of the default settings with the true motion at each grid alpha, on the "
        "family's render and on the one with 9 x 9 rays per pixel side and 9x the instants:",
        "",
        "| scene | render | " + " | ".join(f"{a:g}" for a in protocol.ALPHAS) + " |",
        "|---|---|" + "---|" * len(protocol.ALPHAS),
    ]
    for name, r in records.items():
        for label, values in r["psnr"].items():
            best = int(np.argmax(values))
            cells = [f"**{v:.2f}**" if k == best else f"{v:.2f}" for k, v in enumerate(values)]
            lines.append(f"| {name} | {label} | " + " | ".join(cells) + " |")
    return lines


def main(argv=None) -> int:
    return protocol.run_study(
        "model_error",
        model_error,
        report,
        16,
        "The true sharp frame's misfit under the true motion on noiseless frames.",
        argv,
    )


if __name__ == "__main__":
    raise SystemExit(main())
