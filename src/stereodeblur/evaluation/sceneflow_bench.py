"""Scene-flow benchmark: disparity, flow and rigid-motion errors, and the motorcycle check.

Scenes (any list of scene folders with ground truth) are read with
:func:`stereodeblur.io.scene.open_scene`; the scene flow is estimated from the
blurred frames ``frame`` and ``frame + 1`` of both views. Measures, over every
pixel with known ground truth (holes and non-finite estimates count as zero
disparity / zero flow, :mod:`.metrics`):

* ADE: mean absolute disparity error at frame t, of the scene flow's dense
  disparity and of the initial semi-global matching (with its holes);
* AEP: mean endpoint error of the left-view flow t -> t + 1, of the initial
  optical flow (DIS) and of the scene flow's 2D projection;
* the same outside ``gt/mixed`` where the scene has it;
* per object of ``gt/objects.json`` (if present): the rotation error (degrees)
  of the estimated motion ``R_est R_true^T``, the translation error (scene units,
  and relative to the true translation in %), and the angle between the
  estimated and true plane normals (degrees). An object's pixels are those whose
  true disparity and flow its plane and motion reproduce within 0.5 px; its
  error is the median over those pixels of their segments' errors.

The motorcycle check (:func:`run_motorcycle_check`) uses the Middlebury 2014
pair shipped with scikit-image (``skimage.data.stereo_motorcycle``, 741 x 500,
calibration from its docstring: ``fx = 994.978`` px, principal point
``(311.193, 254.877)``, baseline 0.193001 m; the principal-point offset of the
right camera, ``doffs = 31.086`` px, is left out, so disparities are the
dataset's own ``x_left - x_right``) as a static clip: the same pair at t and
t + 1. The estimated motion should vanish, and the dense disparity's rate of
errors > 2 px (over pixels with known ground truth) is compared with plain
semi-global matching on the same pair (holes count as errors; the rate over its
valid pixels only is reported too).
"""

from __future__ import annotations

import json
import os
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..geometry.camera import StereoCamera
from ..geometry.rigid import se3_exp, so3_log
from ..progress import ProgressCallback, report
from .metrics import disparity_error, endpoint_error

MOTORCYCLE_K = np.array([[994.978, 0.0, 311.193], [0.0, 994.978, 254.877], [0.0, 0.0, 1.0]])
MOTORCYCLE_BASELINE = 0.193001
SIZES = ((640, 480),)
FRAME = 1


@dataclass(frozen=True)
class ObjectMotionError:
    """Errors of one object's estimated plane and rigid motion (see the module docstring)."""

    object_id: int
    name: str
    num_pixels: int
    rotation_deg: float
    translation_error: float
    translation_relative_percent: float
    normal_deg: float


@dataclass(frozen=True)
class SceneFlowBenchResult:
    """Scene-flow errors on one scene (pixels, degrees, percent; NaN where not available).

    ``seconds`` is the wall time of the estimation, ``cpu_seconds`` the CPU time of
    all its threads (on an otherwise idle machine with 2 cores, wall time lies
    between ``cpu_seconds / 2`` and ``cpu_seconds``).
    """

    scene: str
    frame: int
    size: tuple[int, int]
    ade: float
    ade_initial: float
    aep: float
    aep_initial: float
    ade_outside_mixed: float
    aep_outside_mixed: float
    objects: tuple[ObjectMotionError, ...]
    seconds: float
    warnings: tuple[str, ...] = ()
    diagnostics: dict = field(default_factory=dict)
    cpu_seconds: float = float("nan")


@dataclass(frozen=True)
class MotorcycleResult:
    """The static motorcycle check: motion should vanish; > 2 px disparity error rates."""

    size: tuple[int, int]
    bad2_sceneflow: float
    bad2_sgbm: float
    bad2_sgbm_valid_only: float
    sgbm_hole_fraction: float
    ade_sceneflow: float
    mean_flow: float
    max_flow: float
    max_rotation_deg: float
    max_translation: float
    seconds: float
    warnings: tuple[str, ...] = ()


def _read_objects(root: Path) -> list[dict]:
    path = root / "gt" / "objects.json"
    if not path.is_file():
        return []
    data = json.loads(path.read_text(encoding="utf-8"))
    return list(data.get("objects", []))


def object_errors(sceneflow, objects: list[dict], disparity_gt, flow_gt, frame: int):
    """Per-object plane and motion errors (see the module docstring).

    Only planar objects (with a ``normal`` in gt/objects.json) are matched; solids are skipped.
    """
    from ..geometry.plane import move_plane, plane_disparity
    from ..sceneflow.model import SceneFlow

    camera = sceneflow.camera
    height, width = sceneflow.shape
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    labels = sceneflow.labels
    M_est = se3_exp(sceneflow.twists)
    best = np.full((height, width), np.inf)
    owner = np.full((height, width), -1)
    truths = []
    objects = [obj for obj in objects if "normal" in obj]
    for k, obj in enumerate(objects):
        twist = np.asarray(obj["twist"], dtype=np.float64)
        M0 = se3_exp(frame * twist)
        normal = move_plane(np.asarray(obj["normal"], dtype=np.float64), M0[:3, :3], M0[:3, 3])
        truths.append((normal, se3_exp(twist)))
        single = SceneFlow(
            camera,
            np.zeros((height, width), np.int32),
            normal[None],
            twist[None],
            np.zeros((height, width), bool),
        )
        with np.errstate(invalid="ignore"):
            derr = np.abs(plane_disparity(camera, normal, x, y) - disparity_gt)
            ferr = np.linalg.norm(single.flow() - flow_gt, axis=-1)
            score = np.where((derr < 0.5) & (ferr < 0.5), derr + ferr, np.inf)
        better = score < best
        best[better] = score[better]
        owner[better] = k
    out = []
    for k, obj in enumerate(objects):
        mask = owner == k
        count = int(mask.sum())
        normal, M = truths[k]
        if count == 0:
            out.append(
                ObjectMotionError(
                    int(obj.get("id", k)), str(obj.get("name", "")), 0, *(float("nan"),) * 4
                )
            )
            continue
        segs = labels[mask]
        R_err = M_est[segs, :3, :3] @ M[:3, :3].T
        rot = np.degrees(np.linalg.norm(so3_log(R_err), axis=-1))
        trans = np.linalg.norm(M_est[segs, :3, 3] - M[:3, 3], axis=-1)
        scale = np.linalg.norm(M[:3, 3])
        n_est = sceneflow.normals[segs]
        cos = n_est @ normal / (np.linalg.norm(n_est, axis=-1) * np.linalg.norm(normal))
        ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        out.append(
            ObjectMotionError(
                object_id=int(obj.get("id", k)),
                name=str(obj.get("name", "")),
                num_pixels=count,
                rotation_deg=float(np.median(rot)),
                translation_error=float(np.median(trans)),
                translation_relative_percent=(
                    float(100 * np.median(trans) / scale) if scale > 1e-12 else float("nan")
                ),
                normal_deg=float(np.median(ang)),
            )
        )
    return tuple(out)


def evaluate_scene(root: str | os.PathLike, *, frame: int = 1, out=None) -> SceneFlowBenchResult:
    """Estimate the scene flow of one scene's frame and measure it against the ground truth."""
    from ..io.scene import open_scene
    from ..sceneflow.estimate import estimate_scene_flow
    from ..sceneflow.storage import write_sceneflow_outputs

    root = Path(root)
    scene = open_scene(root)
    frames = [scene.read_frame(v, i) for i in (frame, frame + 1) for v in ("left", "right")]
    debug = None if out is None else Path(out) / root.name / "debug"
    start, cpu_start = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = estimate_scene_flow(
            *frames, scene.info.camera, exposure=scene.info.exposure, debug_dir=debug
        )
    seconds = time.perf_counter() - start
    cpu_seconds = time.process_time() - cpu_start
    sf = est.sceneflow
    disparity, flow = sf.disparity(), sf.flow()
    d_gt = scene.read_gt_disparity("left", frame)
    f_gt = scene.read_gt_flow("left", frame)
    if scene.has_gt("mixed", "left", frame):
        keep = ~scene.read_gt_mixed("left", frame)
        ade_out = disparity_error(disparity[keep], d_gt[keep])
        aep_out = endpoint_error(flow[keep], f_gt[keep])
    else:
        ade_out = aep_out = float("nan")
    objects = object_errors(sf, _read_objects(root), d_gt, f_gt, frame)
    if out is not None:
        write_sceneflow_outputs(Path(out) / root.name, est, frame)
    return SceneFlowBenchResult(
        scene=root.name,
        frame=frame,
        size=(scene.shape[1], scene.shape[0]),
        ade=disparity_error(disparity, d_gt),
        ade_initial=disparity_error(est.initial_disparity, d_gt),
        aep=endpoint_error(flow, f_gt),
        aep_initial=endpoint_error(est.initial_flow, f_gt),
        ade_outside_mixed=ade_out,
        aep_outside_mixed=aep_out,
        objects=objects,
        seconds=seconds,
        warnings=est.warnings,
        diagnostics=dict(est.diagnostics),
        cpu_seconds=cpu_seconds,
    )


def run_sceneflow_benchmark(scene_roots, *, frame: int = 1, out=None) -> list[SceneFlowBenchResult]:
    """Evaluate the scene flow on every scene of ``scene_roots`` (see the module docstring).

    Parameters
    ----------
    scene_roots : iterable of path
        Scene folders with ``gt/disparity`` and ``gt/flow`` for ``frame``.
    frame : int
        Frame t; frames t and t + 1 are used.
    out : path, optional
        If given: per scene ``OUT/<scene>/`` with the outputs of
        :func:`~stereodeblur.sceneflow.storage.write_sceneflow_outputs` and debug
        pictures, and ``OUT/sceneflow_bench.json`` with all results.
    """
    from ..io.outputs import atomic_write_text

    results = [evaluate_scene(root, frame=frame, out=out) for root in scene_roots]
    if out is not None:
        path = Path(out) / "sceneflow_bench.json"
        atomic_write_text(path, json.dumps([asdict(r) for r in results], indent=2) + "\n")
    return results


def run_motorcycle_check(*, num_segments: int | None = None) -> MotorcycleResult:
    """Scene flow of the Middlebury motorcycle pair used as a static clip (module docstring)."""
    import skimage.data

    from ..sceneflow.estimate import estimate_scene_flow
    from ..sceneflow.initial import initial_disparity

    left, right, disp_gt = skimage.data.stereo_motorcycle()
    left = left.astype(np.float32) / 255.0
    right = right.astype(np.float32) / 255.0
    disp_gt = np.asarray(disp_gt, dtype=np.float64)
    known = np.isfinite(disp_gt) & (disp_gt > 0)
    camera = StereoCamera(MOTORCYCLE_K, MOTORCYCLE_BASELINE)
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        est = estimate_scene_flow(left, right, left, right, camera, num_segments=num_segments)
    seconds = time.perf_counter() - start
    sf = est.sceneflow
    disparity = sf.disparity()
    sgbm = initial_disparity(left, right)
    err_sf = np.abs(np.nan_to_num(disparity, nan=0.0) - disp_gt)[known]
    err_sgbm = np.abs(np.nan_to_num(sgbm, nan=0.0) - disp_gt)[known]
    sgbm_valid = np.isfinite(sgbm)[known]
    flow = np.linalg.norm(sf.flow(), axis=-1)
    M = se3_exp(sf.twists)
    rot = np.degrees(np.linalg.norm(so3_log(M[:, :3, :3]), axis=-1))
    return MotorcycleResult(
        size=(left.shape[1], left.shape[0]),
        bad2_sceneflow=float(np.mean(err_sf > 2)),
        bad2_sgbm=float(np.mean(err_sgbm > 2)),
        bad2_sgbm_valid_only=float(np.mean(err_sgbm[sgbm_valid] > 2)),
        sgbm_hole_fraction=float(1 - np.mean(sgbm_valid)),
        ade_sceneflow=float(np.mean(err_sf)),
        mean_flow=float(np.mean(flow)),
        max_flow=float(np.max(flow)),
        max_rotation_deg=float(np.max(rot)),
        max_translation=float(np.max(np.linalg.norm(M[:, :3, 3], axis=-1))),
        seconds=seconds,
        warnings=tuple(str(w.message) for w in caught),
    )


def _f(value: float, digits: int = 3) -> str:
    return "n/a" if value is None or not np.isfinite(value) else f"{value:.{digits}f}"


def format_sceneflow_table(results, motorcycle: MotorcycleResult | None = None) -> str:
    """Markdown tables of benchmark results (and of the motorcycle check, if given)."""
    lines = [
        "| scene | size | ADE SGBM | ADE scene flow | AEP initial flow | AEP scene flow "
        "| ADE / AEP outside mixed | time (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r.scene} | {r.size[0]}x{r.size[1]} | {_f(r.ade_initial)} | {_f(r.ade)} | "
            f"{_f(r.aep_initial)} | {_f(r.aep)} | {_f(r.ade_outside_mixed)} / "
            f"{_f(r.aep_outside_mixed)} | {r.seconds:.1f} |"
        )
    rows = [(r.scene, o) for r in results for o in r.objects]
    if rows:
        lines += [
            "",
            "| scene | object | pixels | rotation error (deg) | translation error "
            "| translation error (%) | normal error (deg) |",
            "|---|---|---|---|---|---|---|",
        ]
        for scene, o in rows:
            lines.append(
                f"| {scene} | {o.object_id} {o.name} | {o.num_pixels} | {_f(o.rotation_deg)} | "
                f"{_f(o.translation_error, 4)} | {_f(o.translation_relative_percent, 2)} | "
                f"{_f(o.normal_deg)} |"
            )
    if motorcycle is not None:
        m = motorcycle
        lines += [
            "",
            "| motorcycle (static) | > 2 px errors | ADE | mean / max flow (px) "
            "| max rotation (deg) | max translation (m) | time (s) |",
            "|---|---|---|---|---|---|---|",
            f"| scene flow | {100 * m.bad2_sceneflow:.1f}% | {_f(m.ade_sceneflow)} | "
            f"{_f(m.mean_flow, 4)} / {_f(m.max_flow, 4)} | {_f(m.max_rotation_deg, 4)} | "
            f"{_f(m.max_translation, 5)} | {m.seconds:.1f} |",
            f"| plain SGBM | {100 * m.bad2_sgbm:.1f}% (holes {100 * m.sgbm_hole_fraction:.1f}%; "
            f"{100 * m.bad2_sgbm_valid_only:.1f}% of its valid pixels) | | | | | |",
        ]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class SceneFlowBench:
    """A run of :func:`run_sceneflow_bench`: results, the Markdown tables, the files."""

    results: tuple[SceneFlowBenchResult, ...]
    motorcycle: MotorcycleResult | None
    table: str
    markdown: Path
    json: Path


def run_sceneflow_bench(
    work: str | os.PathLike,
    *,
    sizes: Sequence[tuple[int, int]] = SIZES,
    scenes: Sequence[str] | None = None,
    frame: int = FRAME,
    motorcycle: bool = True,
    progress: ProgressCallback | None = None,
) -> SceneFlowBench:
    """Render the missing scenes under ``work``, estimate and measure their scene flow.

    Parameters
    ----------
    work : path
        Folder for the rendered scenes (``WORK/WxH/NAME``) and the results
        (``WORK/sceneflow.md``, ``WORK/sceneflow.json``).
    sizes : sequence of (width, height)
    scenes : sequence of str, optional
        Planar motions and object scenes, ``NAME_noisy`` for a noisy variant (default:
        every planar motion and every noiseless object scene).
    frame : int
        Frame t whose motion to t + 1 is estimated.
    motorcycle : bool
        Also run :func:`run_motorcycle_check`.
    progress : callable, optional
        Receives :class:`~stereodeblur.progress.Progress` reports.
    """
    from ..io.outputs import atomic_write_text
    from ..synth.objects import OBJECT_SCENES
    from ..synth.planar import PLANAR_MOTIONS, write_planar_set
    from .paper_bench import render_missing, scene_kind

    work = Path(work)
    names = list(scenes) if scenes else list(PLANAR_MOTIONS) + list(OBJECT_SCENES)
    for name in names:
        scene_kind(name)  # an InputError for an unknown name, before anything is rendered
    results = []
    for width, height in sizes:
        base = work / f"{width}x{height}"
        missing = [n for n in names if not (base / n / "camera.json").is_file()]
        planar = [n for n in missing if n in PLANAR_MOTIONS]
        if planar:
            report(progress, f"rendering {len(planar)} planar scene(s) at {width}x{height}")
            write_planar_set(base, size=(width, height), names=planar, progress=progress)
        others = [n for n in missing if n not in planar]
        render_missing(base, others, (width, height), progress=progress)
        for k, name in enumerate(names):
            report(progress, f"scene flow {width}x{height} {name}", k, len(names))
            results.append(evaluate_scene(base / name, frame=frame))
    check = None
    if motorcycle:
        report(progress, "scene flow: motorcycle (static clip)")
        check = run_motorcycle_check()
    table = format_sceneflow_table(results, check)
    work.mkdir(parents=True, exist_ok=True)
    markdown = atomic_write_text(work / "sceneflow.md", table)
    data = {
        "scenes": [asdict(r) for r in results],
        "motorcycle": None if check is None else asdict(check),
    }
    path = atomic_write_text(work / "sceneflow.json", json.dumps(data, indent=1) + "\n")
    return SceneFlowBench(tuple(results), check, table, markdown, path)
