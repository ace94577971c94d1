"""Ablation of the adaptive boundary handling and gating rules for it (issue 12), train split.

Run from the repository root (the calibration protocol's renders are reused)::

    nice -n 10 python benchmarks/study_boundary.py --scenes 64 --jobs 2 \\
        --scenes-from /tmp/calib/work --work /tmp/boundary_study

Frame 1 of the left view of every scene of the calibration protocol's **train split only**
(``benchmarks/calibrate_defaults.py``, seeds 0-999; the script refuses any other seed) is
deblurred at the fixed ``alpha = 0.001`` (the paper's, so that only the boundary handling
differs) with the motion computed once per scene and source (``gt``, ``sceneflow``) and
reused by every column. The parts of ``boundary_weights='adaptive'`` are switched on and off
one at a time by monkeypatching the pipeline (``src/`` is not edited):

- ``O``: the small data weight where the exposure path leaves the view
  (``deconv.trust.OUTSIDE_WEIGHT`` set to 1 switches it off);
- ``R``: the operator's rows near the motion boundaries from the dense optical flow
  (``FrameMotion.boundary_flow`` set to None switches it off; with ``gt`` motion the
  pipeline has no dense flow, the study adds DIS's for the ``R`` columns);
- ``A``: the anchor to the blurred frame where the motion is not trusted
  (``deconv.trust.trust_anchor``; the pipeline sets it only without ``R``);
- ``V``: the occlusion-aware homography operator and its hidden-surface weights
  (``pipeline.operator.visibility``; the pipeline uses it only without ``R``).

The trust-driven alpha (``alpha_from_trust``) and the noise-driven one (``alpha_from_sigma``)
act only with ``alpha='auto'`` and are out of this study (``benchmarks/alpha_study.py``).
A column is a set of parts; ``none`` is ``boundary_weights='none'`` (the paper's ``w = 1``),
``full`` the pipeline's adaptive handling (``OAV`` with gt motion, ``OR`` with the scene
flow). ``gate:...`` columns restrict ``R`` to a mask computed from what a user has (the two
trust maps and the flows' disagreement, :func:`gate_masks`).

Per scene and source the study records features (number of distinct rigid motions of the
scene flow, share of pixels near its motion boundaries, disagreement of the scene flow and
the dense flow there, the trusts), and then scores gating rules that switch a part on or
off per scene from those features, their constant fitted by leave-one-scene-out
cross-validation. Per-scene results are cached as json under ``--work`` (a rerun resumes);
written: ``--output`` (markdown) and the same path with ``.json``.
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402
import study_boundary_report as reporting  # noqa: E402

ALPHA = 1e-3
FRAME = protocol.FRAME
SOURCES = ("gt", "sceneflow")
PARTS = "ORAV"
FULL = {"gt": "OAV", "sceneflow": "OR"}
"""The parts the pipeline's adaptive handling uses with each motion source."""
ABLATIONS = {
    "gt": ("none", "OAV", "AV", "OV", "OA", "V", "O", "A", "OR"),
    "sceneflow": ("none", "OR", "R", "O", "OAV", "V", "A", "OV", "OA"),
}
"""Columns per source: ``none`` and sets of parts (``R`` with ``A`` or ``V`` is not
measured: the pipeline sets neither where it takes the dense rows)."""
GATES = (
    "better>0.1",
    "untrusted&disagree>1",
    "better>0.25",
    "untrusted&disagree>3",
)
"""Pixel gates of ``R`` (with ``O``), sceneflow only: dense rows where the dense flow
predicts the neighbouring frames better than the scene flow by more than the trust margin,
or where the scene flow's trust is below 0.5 and the flows differ by more than X px."""
DILATED = ("better>0.1~d8", "better>0.25~d8", "better>0.25~d16")
"""Gates grown by R px (``GATE~dR``; :func:`scene_features`), added after the first results."""
FIRST_PASS = {
    "gt": ("none", "OAV", "AV", "OV", "OA", "V"),
    "sceneflow": ("none", "OR", "R", "O", "OAV", "gate:better>0.1", "gate:untrusted&disagree>1"),
}
"""The columns of ``--first-pass``: the full handling, each part removed, and two gates."""
SIGNATURE = "boundary study 1"


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@contextmanager
def only_parts(parts: str, motion):
    """The pipeline with only ``parts`` of the adaptive handling; yields the motion to use."""
    import stereodeblur.deconv.trust as trust
    import stereodeblur.pipeline.operator as operator

    saved = (trust.OUTSIDE_WEIGHT, trust.trust_anchor, operator.visibility)
    try:
        if "O" not in parts:
            trust.OUTSIDE_WEIGHT = 1.0
        if "A" not in parts:
            trust.trust_anchor = lambda value, **_: None
        if "V" not in parts:
            operator.visibility = lambda *_, **__: None
        if "R" not in parts:
            motion = replace(motion, boundary_flow=None)
        yield motion
    finally:
        trust.OUTSIDE_WEIGHT, trust.trust_anchor, operator.visibility = saved


@contextmanager
def gated_rows(mask: np.ndarray):
    """``R`` restricted to ``mask`` (bool ``(H, W)``) within the pipeline's band."""
    import stereodeblur.pipeline.operator as operator

    original = operator.boundary_motion

    def gated(motion, duty_cycle):
        moved, band = original(motion, duty_cycle)
        keep = band & mask
        inside = keep[..., None]
        forward = np.where(inside, moved.flow_forward, motion.flow_forward).astype(np.float32)
        backward = np.where(inside, moved.flow_backward, motion.flow_backward)
        return replace(moved, flow_forward=forward, flow_backward=backward.astype(np.float32)), keep

    operator.boundary_motion = gated
    try:
        yield
    finally:
        operator.boundary_motion = original


def settings_for(source: str, column: str):
    from stereodeblur.settings import DeblurSettings

    weights = "none" if column == "none" else "adaptive"
    return DeblurSettings(motion_source=source, alpha=ALPHA, boundary_weights=weights)


def deblur(scene, source: str, motion, truth, column: str, masks) -> dict:
    """PSNR of one column (see the module docstring)."""
    import warnings

    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.pipeline import deblur_frame

    settings = settings_for(source, column)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if column == "none":
            result = deblur_frame(scene, FRAME, view="left", settings=settings, motion=motion)
        elif column.startswith("gate:"):
            with only_parts("OR", motion) as used, gated_rows(masks[column[5:]]):
                result = deblur_frame(scene, FRAME, view="left", settings=settings, motion=used)
        else:
            with only_parts(column, motion) as used:
                result = deblur_frame(scene, FRAME, view="left", settings=settings, motion=used)
    border = protocol.border_of(truth.shape[1])
    return {
        "psnr": psnr(result.image, truth, border=border),
        "seconds": time.perf_counter() - start,
    }


def scene_motion(scene, source: str, blurred, cache: Path):
    """The frame's motion from ``source`` with the view's dense flow as ``boundary_flow``
    (computed once, pickled under ``cache``)."""
    import warnings

    from stereodeblur.pipeline import frame_motion, with_boundary_flow

    path = cache / f"{source}_motion.pkl"
    if path.is_file():
        return pickle.loads(path.read_bytes())
    settings = replace(settings_for(source, "OR"), alpha="auto")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        motion = frame_motion(scene, FRAME, "left", settings, blurred)
        if motion.boundary_flow is None:
            motion = with_boundary_flow(motion, scene, settings, blurred)
    path.write_bytes(pickle.dumps(motion))
    return motion


def rigid_motions(sceneflow, *, tolerance: float = 1.0, relative: float = 0.05, rest=0.02):
    """Distinct rigid motions of a scene flow and the share its dominant one does not explain.

    Greedy: the segment covering most unexplained pixels gives a motion; every segment whose
    pixels (median) move by it within ``max(tolerance, relative |f|)`` px is explained by it;
    repeated until less than ``rest`` of the pixels is left (at most 8 motions).
    """
    flow = sceneflow.flow()
    labels = sceneflow.labels
    length = np.hypot(flow[..., 0], flow[..., 1])
    limit = np.maximum(tolerance, relative * length)
    unexplained = np.ones(sceneflow.num_segments, bool)
    area = np.bincount(labels.ravel(), minlength=sceneflow.num_segments)
    count, dominant_share = 0, 0.0
    while area[unexplained].sum() > rest * labels.size and count < 8:
        pick = int(np.argmax(np.where(unexplained, area, -1)))
        twists = np.tile(sceneflow.twists[pick], (sceneflow.num_segments, 1))
        moved = replace(sceneflow, twists=twists).flow()
        fits = np.hypot(*np.moveaxis(moved - flow, -1, 0)) <= limit
        fit_share = np.bincount(labels.ravel(), fits.ravel(), sceneflow.num_segments)
        explained = unexplained & (fit_share >= 0.5 * np.maximum(area, 1))
        explained[pick] = True
        if count == 0:
            dominant_share = 1.0 - float(area[explained].sum()) / labels.size
        unexplained &= ~explained
        count += 1
    return count, dominant_share


def scene_features(scene, motion, blurred) -> tuple[dict, dict]:
    """Features of one scene and source, and the gate masks of :data:`GATES`."""
    import warnings

    from scipy import ndimage

    from stereodeblur.deconv.noise import estimate_noise_sigma
    from stereodeblur.deconv.trust import leaves_view, near_motion_boundaries
    from stereodeblur.pipeline.weights import frame_trusts
    from stereodeblur.pipeline.window import read_window

    settings = settings_for("gt", "OR")
    window = read_window(
        scene, FRAME, ("left",), settings, motion=False, known={("left", FRAME): blurred}
    )
    duty = float(window.exposure.duty_cycle)
    own = motion.sceneflow.flow()
    band = near_motion_boundaries(motion.flow_forward, duty)
    dense_f, dense_b = motion.boundary_flow
    dense_b = -dense_f if dense_b is None else dense_b
    dense = replace(motion, flow_forward=dense_f, flow_backward=dense_b, boundary_flow=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sigma = estimate_noise_sigma(blurred)
        t_own, t_dense = frame_trusts(
            window, "left", (motion, dense), noise_sigma=sigma, bands=(band, band)
        )
    disagree = np.hypot(*np.moveaxis(dense_f - motion.flow_forward, -1, 0))
    n_motions, moving = rigid_motions(motion.sceneflow)
    inband = band if band.any() else np.ones_like(band)
    better = t_dense - t_own
    features = {
        "duty_cycle": duty,
        "noise_sigma": float(sigma),
        "n_motions": n_motions,
        "moving_share": moving,
        "band_share": float(band.mean()),
        "disagree_band_mean": float(disagree[inband].mean()),
        "disagree_band_share2": float(np.mean(disagree[inband] > 2.0)),
        "disagree_mean": float(disagree.mean()),
        "trust_own_band": float(t_own[inband].mean()),
        "trust_dense_band": float(t_dense[inband].mean()),
        "better_band_share": float(np.mean(better[inband] > 0.1)),
        "untrusted_share": float(np.mean(t_own < 0.5)),
        "outside_share": float(leaves_view(motion.flow_forward, motion.flow_backward, duty).mean()),
        "flow_p95": float(np.percentile(np.hypot(own[..., 0], own[..., 1]), 95)),
    }
    untrusted = t_own < 0.5
    masks = {
        "better>0.1": better > 0.1,
        "better>0.25": better > 0.25,
        "untrusted&disagree>1": untrusted & (disagree > 1.0),
        "untrusted&disagree>3": untrusted & (disagree > 3.0),
    }
    for name in DILATED:  # "GATE~dR": GATE grown by R px
        gate, radius = name.split("~d")
        grow = ndimage.distance_transform_edt(~masks[gate]) <= float(radius)
        masks[name] = grow if masks[gate].any() else masks[gate]
    for name, mask in masks.items():
        features[f"gate_share:{name}"] = float(mask[band].mean()) if band.any() else 0.0
    return features, masks


PROTOCOL_COLUMNS = {"none": "paper", "OAV": "alpha=0.001", "OR": "alpha=0.001"}
"""The calibration protocol's cached columns that equal a study column: ``paper`` is
``none`` at alpha 0.001; ``alpha=0.001`` is the full adaptive handling (``OAV`` with gt
motion, ``OR`` with the scene flow). Spot-checked: equal to 0.001 dB on 13 of 14."""


def _from_protocol(root: Path, source: str, column: str) -> dict | None:
    """A column's result from the protocol's cache (``--scenes-from``), if it has it."""
    if column not in ("none", FULL[source]):
        return None
    path = root.parent.parent / "results" / root.name / f"{source}_{PROTOCOL_COLUMNS[column]}.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    return {"psnr": data["psnr"], "seconds": data["seconds"], "from": "calibration cache"}


def run_scene(task) -> dict:
    """Every column of one scene, reusing cached results."""
    from stereodeblur.io.scene import open_scene

    kind, seed, size, scenes_from, work, first_pass, only = task
    if not 0 <= seed < 1000:
        raise SystemExit(f"seed {seed} is not in the train split (0-999)")
    root = protocol.ensure_scene(kind, seed, size, Path(scenes_from))
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", FRAME)
    blurred = scene.read_frame("left", FRAME)
    cache = Path(work) / root.name
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / "results.json"
    data = json.loads(path.read_text()) if path.is_file() else {}
    if data.get("signature") != SIGNATURE:
        data = {"signature": SIGNATURE, "scene": root.name, "kind": kind, "seed": seed}
    for source in SOURCES:
        motion = scene_motion(scene, source, blurred, cache)
        features, masks = scene_features(scene, motion, blurred)
        data.setdefault("features", {})[source] = features
        columns = data.setdefault("columns", {}).setdefault(source, {})
        wanted = list(ABLATIONS[source])
        if source == "sceneflow":
            wanted += [f"gate:{g}" for g in GATES + DILATED]
        if first_pass:
            wanted = list(FIRST_PASS[source])
        if only:
            wanted = [c.split(":", 1)[1] for c in only if c.startswith(source + ":")]
        for column in wanted:
            if column in columns:
                continue
            columns[column] = _from_protocol(root, source, column)
            if columns[column] is None:
                columns[column] = deblur(scene, source, motion, truth, column, masks)
            _log(f"{root.name} {source} {column}: {columns[column]['psnr']:.2f} dB")
            tmp = path.with_suffix(".tmp")
            tmp.write_text(json.dumps(data, indent=1))
            tmp.replace(path)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)
    return data


def _cached_row(work: Path, kind: str, seed: int) -> dict | None:
    """The cached results of a scene if both sources have their first-pass columns."""
    path = work / f"{kind}_{seed:04d}" / "results.json"
    if not path.is_file():
        return None
    data = json.loads(path.read_text())
    done = data.get("columns", {})
    if all(set(FIRST_PASS[s]) <= set(done.get(s, {})) for s in SOURCES):
        return data
    return None


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--scenes", type=int, default=64, help="train scenes (default 64)")
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--scenes-from", default="/tmp/calib/work", help="protocol's --work")
    parser.add_argument("--work", default="/tmp/boundary_study", help="per-scene cache")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument(
        "--first-pass", action="store_true", help="only the columns of FIRST_PASS (resumable)"
    )
    parser.add_argument(
        "--columns",
        default="",
        help="only these SOURCE:COLUMN (comma-separated), e.g. sceneflow:V,gt:O (resumable)",
    )
    parser.add_argument(
        "--report-only", action="store_true", help="tables of the cached scenes, no runs"
    )
    parser.add_argument("--output", default=None, help="markdown output (and .json beside)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    args.size_pair = (width, height)
    args.columns = tuple(c for c in args.columns.split(",") if c)
    if args.output is None:
        args.output = f"benchmarks/results/boundary_study_train_{args.size}.md"
    return args


def main(argv=None) -> int:
    from stereodeblur.io.outputs import atomic_write_text

    args = parse(argv)
    scenes_from = Path(args.scenes_from) / args.size
    work = Path(args.work) / args.size
    tasks = [
        (kind, seed, args.size_pair, str(scenes_from), str(work), args.first_pass, args.columns)
        for kind, seed in protocol.scene_list("train", args.scenes, protocol.KINDS)
    ]
    start = time.perf_counter()
    if args.report_only:
        rows = [_cached_row(work, kind, seed) for kind, seed, *_ in tasks]
        rows = [r for r in rows if r is not None]
    else:
        rows = protocol.run_all(run_scene, tasks, args.jobs)
    seconds = time.perf_counter() - start
    text, summary = reporting.report(rows, seconds, " ".join(sys.argv[1:]))
    output = Path(args.output)
    atomic_write_text(output, text)
    atomic_write_text(output.with_suffix(".json"), json.dumps(summary, indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
