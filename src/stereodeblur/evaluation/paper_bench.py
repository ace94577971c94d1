"""``bench paper``: every column of the paper's Tables 2-4 on every scene, resumably.

The columns are :mod:`.paper_columns`, the report :mod:`.paper_tables`. AEP is the
mean endpoint error of the 2D motion a column's kernels come from against
gt/flow; ADE the mean absolute disparity error of the scene flow against
gt/disparity. PSNR and SSIM skip a border of 2.5 % of the width (content that
enters the view). Scenes: the object set (:mod:`stereodeblur.synth.objects`) and
the paper's three planar motions (upward, forward, forward_yaw), each noiseless
and with noise of deviation 0.01 (``NAME_noisy``).

Motion-boundary weight diagnostics of the full methods: of the pixels whose
final weight (ours: trust in the blur model) is below 0.5, the share that lie
within 3 px of gt/mixed or where the scene flow's endpoint error exceeds 1 px
("explained"); and the share of all pixels whose weight changed by more than
0.05 in the last IRLS iteration.

Everything is cached under the work folder, so an interrupted run resumes:
``WORK/SIZE/scenes/NAME`` (rendered scenes), ``WORK/SIZE/cache/NAME/`` (scene
flow, initial flow, one JSON and one PNG per column), ``WORK/SIZE/figures/NAME.png``
(input | each method | sharp, with 4x ``|difference|`` images below), and the tables
``WORK/SIZE/paper.md`` and ``paper.json``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..progress import ProgressCallback, report
from ..settings import DeblurSettings
from .motion_cache import cached_motion, motion_digest, quiet
from .paper_columns import (
    ALPHA_SWEEP,
    COLUMNS,
    FRAME,
    MASKED_COLUMNS,
    TRUE_MOTION,
    Column,
    ColumnResult,
    SceneResult,
    sweep_column,
)
from .paper_tables import markdown_report

PLANAR_SCENES = ("upward", "forward", "forward_yaw")
NOISY_SUFFIX = "_noisy"
LOW_WEIGHT = 0.5
NEAR_MIXED_PX = 3.0
FLOW_ERROR_PX = 1.0
CHANGE = 0.05
RENDER_SAMPLES = 48
SIZE = (640, 480)
DIFFERENCE_GAIN = 4.0


# --- scenes ---------------------------------------------------------------------------------


def scene_kind(name: str) -> str:
    """``'object'`` or ``'planar'`` for a scene name (with or without ``_noisy``)."""
    from ..synth.objects import OBJECT_SCENES
    from ..synth.planar import PLANAR_MOTIONS

    base = name.removesuffix(NOISY_SUFFIX)
    if base in OBJECT_SCENES:
        return "object"
    if base in PLANAR_MOTIONS:
        return "planar"
    raise InputError(
        f"unknown scene {name!r}: expected an object scene ({', '.join(OBJECT_SCENES)}) or a "
        f"planar one ({', '.join(PLANAR_MOTIONS)}), optionally with the suffix _noisy",
        parameter="scenes",
    )


def default_scenes() -> list[str]:
    """Every object scene and the paper's planar motions, each noiseless and noisy."""
    from ..synth.objects import OBJECT_SCENES

    names = list(OBJECT_SCENES) + list(PLANAR_SCENES)
    return [n + suffix for n in names for suffix in ("", NOISY_SUFFIX)]


def render_missing(
    base: Path,
    names,
    size,
    *,
    num_samples: int = RENDER_SAMPLES,
    progress: ProgressCallback | None = None,
) -> None:
    """Render and write the scenes of ``names`` not yet under ``base`` (both variants at once).
    Another process rendering the same scene into ``base`` is waited for (a lock per scene)."""
    from ..io.outputs import OutputLock
    from ..synth.objects import NOISE_SIGMA, add_noise, make_object_scene
    from ..synth.planar import make_planar_scene, write_rendered_scene

    def missing(name) -> bool:
        return name in names and not (base / name / "camera.json").is_file()

    base.mkdir(parents=True, exist_ok=True)
    for root in dict.fromkeys(n.removesuffix(NOISY_SUFFIX) for n in names if missing(n)):
        with OutputLock(base, name=f".{root}.lock", wait=True):
            todo = [n for n in (root, root + NOISY_SUFFIX) if missing(n)]
            if not todo:  # rendered by another process meanwhile
                continue
            report(progress, f"rendering {root} at {size[0]}x{size[1]}")
            if scene_kind(root) == "object":
                scene = make_object_scene(root, size=size, num_samples=num_samples)
            else:
                scene = make_planar_scene(root, size=size, num_samples=num_samples)
            for name in todo:
                variant = scene if name == root else add_noise(scene, NOISE_SIGMA)
                # Written aside and renamed, so that an interrupted run leaves no half scene.
                partial = base / f".{name}.partial"
                if partial.exists():
                    shutil.rmtree(partial)
                write_rendered_scene(variant, partial)
                partial.rename(base / name)


# --- one column -----------------------------------------------------------------------------


def weight_statistics(result, mixed: np.ndarray, flow_error: np.ndarray | None) -> dict:
    """The weight diagnostics of a deblurring (module docstring), in percent.

    For the adaptive method the "weights" are its trust in the blur model (computed once,
    before the IRLS, so nothing changes in the last iteration); for Eq. 5 the data weights.
    """
    from scipy import ndimage

    history = result.result.weights_history
    if result.trust is not None:
        final, changed = np.asarray(result.trust), np.zeros(mixed.shape, bool)
    elif history:
        final = np.asarray(result.result.weights)
        changed = (
            np.abs(np.asarray(history[-1]) - np.asarray(history[-2])) > CHANGE
            if len(history) >= 2
            else np.zeros(mixed.shape, bool)
        )
    else:
        return {}
    low = final < LOW_WEIGHT
    near = (
        ndimage.distance_transform_edt(~mixed) <= NEAR_MIXED_PX
        if mixed.any()
        else np.zeros_like(mixed)
    )
    explained = near if flow_error is None else near | (flow_error > FLOW_ERROR_PX)
    return {
        "low_weight_percent": float(100 * low.mean()),
        "low_weight_explained_percent": (
            float(100 * (low & explained).sum() / low.sum()) if low.any() else math.nan
        ),
        "changed_last_percent": float(100 * changed.mean()),
    }


def deblur_with_motion(scene, index: int, settings: DeblurSettings, motion):
    """Frame ``index`` of the left view deblurred with its known ``motion`` (a scene flow's
    boundaries as estimated, :func:`~.motion_cache.cached_motion`); where ``settings`` need
    both views' (:func:`~stereodeblur.pipeline.frame.needs_stereo_pass`), by the stereo pass
    from the motion's scene flow."""
    from ..pipeline import deblur_frame, deblur_stereo_frame
    from ..pipeline.frame import needs_stereo_pass
    from ..pipeline.motion import relabelled

    if not needs_stereo_pass(settings):
        return deblur_frame(scene, index, settings=settings, motion=relabelled(motion, settings))
    sf = motion.sceneflow if settings.motion_source == "sceneflow" else None
    stereo = deblur_stereo_frame(scene, index, views=("left",), settings=settings, sceneflow=sf)
    return stereo.frames["left"]


def scene_groups(names) -> list[tuple[str, list[str]]]:
    """``(label, names)`` of the scene groups that have scenes: object and planar scenes,
    noiseless and noisy, e.g. ``('object, noisy (5)', [...])``."""
    out = []
    for kind in ("object", "planar"):
        for noisy in (False, True):
            chosen = [
                n for n in names if scene_kind(n) == kind and n.endswith(NOISY_SUFFIX) == noisy
            ]
            if chosen:
                label = f"{kind}, {'noisy' if noisy else 'noiseless'} ({len(chosen)})"
                out.append((label, chosen))
    return out


def run_column(scene, column: Column, base_settings: DeblurSettings, motion, truth: dict) -> tuple:
    """Deblur frame 1 with ``column``; returns ``(ColumnResult, image)``."""
    from .metrics import border_for, disparity_error, endpoint_error, masked_mse, psnr, ssim

    settings = column.settings(base_settings)
    start = time.perf_counter()
    result, _ = quiet(deblur_with_motion, scene, FRAME, settings, motion)
    seconds = time.perf_counter() - start
    sharp = truth["sharp"]
    border = border_for(sharp.shape[1])
    flow = motion.flow_forward if column.kernels == "displacement" else motion.sceneflow.flow()
    aep = math.nan if column.motion_source == "gt" else endpoint_error(flow, truth["flow"])
    ade = math.nan
    flow_error = None
    if motion.sceneflow is not None and column.motion_source == "sceneflow":
        ade = disparity_error(motion.sceneflow.disparity(), truth["disparity"])
        flow_error = np.linalg.norm(motion.sceneflow.flow() - truth["flow"], axis=-1)
    stats = weight_statistics(result, truth["mixed"], flow_error)
    image = result.image
    return (
        ColumnResult(
            column=column.key,
            psnr=psnr(image, sharp, border=border),
            ssim=ssim(image, sharp, border=border),
            aep=float(aep),
            ade=float(ade),
            alpha=float(result.alpha),
            seconds=seconds,
            signature=_signature(column, base_settings, motion),
            mixed_mse=masked_mse(image, sharp, truth["mixed"] > 0, border=border),
            **stats,
        ),
        image,
    )


def _signature(column: Column, settings, motion) -> dict:
    """What a cached result depends on: its ``motion`` (:func:`~.motion_cache.motion_digest`)
    and its settings (``observations`` only when not ``'single'``,
    ``interpolation`` only when not ``'bilinear'``, ``range_guard`` only when on,
    ``boundary_flow`` only when off, ``relabel_radius`` and ``local_alpha`` only where they
    act, so results from before those options stay valid; the versions of the alpha rules
    that predict the other view, of the relabelling rule, of the true motion's fit and of the
    neighbouring frames' data terms where they are observed)."""
    from ..pipeline.alpha import local_alpha_acts, local_alpha_signature, rules_version
    from ..pipeline.motion import relabel_rule
    from ..pipeline.observations import neighbours_version
    from ..sceneflow.from_gt import FIT_VERSION
    from ..settings import range_guard_signature

    own = column.settings(settings)
    fields = asdict(own)
    for name, old in (
        ("observations", "single"),
        ("interpolation", "bilinear"),
        ("range_guard", False),
        ("boundary_flow", True),
    ):
        if fields[name] == old:
            del fields[name]
    if local_alpha_acts(own):
        fields["local_alpha"] = local_alpha_signature(own).strip()
    else:
        del fields["local_alpha"]
    if relabel_rule(own) is None:
        del fields["relabel_radius"]
    else:
        fields["relabel_rule"] = relabel_rule(own)
    if rules_version(own) is not None:
        fields["alpha_rules"] = rules_version(own)
    if own.range_guard:
        fields["range_guard"] = range_guard_signature(own).strip()
    if own.motion_source == "gt":
        fields["gt_fit"] = FIT_VERSION
    if (neighbours := neighbours_version(own)) is not None:
        fields["neighbours"] = neighbours
    return {**fields, "frame": FRAME, "motion": motion_digest(motion)}


def _read_cached(path: Path) -> dict | None:
    """A cached column result, or None when there is none or it is unreadable."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


# --- one scene ------------------------------------------------------------------------------


def evaluate_scene(
    root: Path,
    cache: Path,
    columns,
    base_settings: DeblurSettings,
    *,
    progress: ProgressCallback | None = None,
) -> SceneResult:
    """All ``columns`` on the scene at ``root``, reusing results cached under ``cache``."""
    from ..io.formats import write_png
    from ..io.outputs import atomic_write_text
    from ..io.png import read_png
    from ..io.scene import open_scene
    from .metrics import border_for, masked_mse, psnr, ssim

    scene = open_scene(root)
    name = root.name
    truth = {
        "sharp": scene.read_gt_sharp("left", FRAME),
        "flow": scene.read_gt_flow("left", FRAME),
        "disparity": scene.read_gt_disparity("left", FRAME),
        "mixed": scene.read_gt_mixed("left", FRAME),
    }
    blurred = scene.read_frame("left", FRAME)
    border = border_for(blurred.shape[1])
    results = {}
    motions = {}
    messages: list[str] = []
    sceneflow_seconds = math.nan
    for column in columns:
        if column.motion_source not in motions:
            report(progress, f"{name}: motion ({column.motion_source})")
            motion, seconds, caught = cached_motion(
                scene, column.motion_source, base_settings, cache
            )
            motions[column.motion_source] = motion
            messages += caught
            if column.motion_source == "sceneflow" and seconds:
                sceneflow_seconds = seconds
        motion = motions[column.motion_source]
        json_path = cache / f"{column.key}.json"
        signature = _signature(column, base_settings, motion)
        cached = _read_cached(json_path)
        if cached is not None and cached.get("signature") == json.loads(json.dumps(signature)):
            if "mixed_mse" not in cached:  # cached before it was measured: from the image
                image = read_png(cache / f"{column.key}.png")
                cached["mixed_mse"] = masked_mse(
                    image, truth["sharp"], truth["mixed"] > 0, border=border
                )
                atomic_write_text(json_path, json.dumps(cached, indent=1))
            results[column.key] = ColumnResult(**cached)
            continue
        report(progress, f"{name}: {column.key}")
        result, image = run_column(scene, column, base_settings, motion, truth)
        cache.mkdir(parents=True, exist_ok=True)
        write_png(cache / f"{column.key}.png", np.clip(image, 0, 1), bit_depth=16)
        atomic_write_text(json_path, json.dumps(asdict(result), indent=1))
        results[column.key] = result
        report(progress, f"{name}: {column.key} PSNR {result.psnr:.2f} dB ({result.seconds:.0f} s)")
    timing = cache / "sceneflow_seconds.json"
    if not math.isnan(sceneflow_seconds):
        atomic_write_text(timing, json.dumps(sceneflow_seconds))
    elif timing.is_file():
        sceneflow_seconds = float(json.loads(timing.read_text(encoding="utf-8")))
    return SceneResult(
        scene=name,
        kind=scene_kind(name),
        noisy=name.endswith(NOISY_SUFFIX),
        size=f"{blurred.shape[1]}x{blurred.shape[0]}",
        psnr_blurred=psnr(blurred, truth["sharp"], border=border),
        ssim_blurred=ssim(blurred, truth["sharp"], border=border),
        mixed_mse_blurred=masked_mse(blurred, truth["sharp"], truth["mixed"] > 0, border=border),
        columns={k: asdict(v) for k, v in results.items()},
        sceneflow_seconds=sceneflow_seconds,
        warnings=tuple(dict.fromkeys(messages)),
    )


def write_figure(root: Path, cache: Path, columns, path: Path) -> Path:
    """Input | each column | sharp (sRGB), with ``4 |difference|`` images to sharp below."""
    from ..io.formats import linear_to_srgb, read_png, write_png
    from ..io.scene import open_scene

    scene = open_scene(root)
    sharp = scene.read_gt_sharp("left", FRAME)
    images = [scene.read_frame("left", FRAME)]
    images += [read_png(cache / f"{c.key}.png") for c in columns]
    images.append(sharp)
    top = np.concatenate([linear_to_srgb(np.clip(i, 0, 1)) for i in images], 1)
    diffs = [np.abs(np.clip(i, 0, 1) - sharp).mean(-1, keepdims=True) for i in images]
    bottom = np.concatenate(
        [np.repeat(np.clip(DIFFERENCE_GAIN * d, 0, 1), 3, -1) for d in diffs], 1
    )
    titles = ["input"] + [c.title for c in columns] + ["sharp"]
    head = _title_strip(titles, images[0].shape[1])
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_png(path, np.concatenate([head, top, bottom], 0), bit_depth=8)


def _title_strip(titles, width: int) -> np.ndarray:
    """A white strip with one black title per panel of ``width`` pixels, float RGB."""
    import cv2

    scale = max(0.25, min(0.6, width / 600))
    height = int(round(28 * scale)) + 6
    strip = np.full((height, width * len(titles), 3), 255, np.uint8)
    for k, title in enumerate(titles):
        cv2.putText(strip, title, (k * width + 4, height - 6), cv2.FONT_HERSHEY_SIMPLEX, scale,
                    (0, 0, 0), 1, cv2.LINE_AA)  # fmt: skip
    return strip.astype(np.float32) / 255.0


# --- the whole benchmark --------------------------------------------------------------------


@dataclass(frozen=True)
class PaperBench:
    """A run of :func:`run_paper_bench`: one row per scene, the Markdown report, its folder."""

    rows: tuple[SceneResult, ...]
    text: str
    folder: Path


def bench_columns(*, alpha_sweep: bool = False, masked: bool = True) -> list[Column]:
    """The columns a run deblurs with: Tables 3-4, the true motion, Table 2, the sweep."""
    columns = list(COLUMNS) + [TRUE_MOTION]
    columns += list(MASKED_COLUMNS) if masked else []
    columns += [sweep_column(a) for a in ALPHA_SWEEP] if alpha_sweep else []
    return columns


def run_paper_bench(
    work: str | os.PathLike,
    *,
    size: tuple[int, int] = SIZE,
    scenes: Sequence[str] | None = None,
    settings: DeblurSettings | None = None,
    alpha_sweep: bool = False,
    masked: bool = True,
    render_samples: int = RENDER_SAMPLES,
    command: str = "",
    progress: ProgressCallback | None = None,
) -> PaperBench:
    """Render missing scenes, evaluate every column (resumably), write tables and figures.

    Parameters
    ----------
    work : path
        Work folder; everything goes under ``WORK/WxH/`` (module docstring).
    size : (width, height)
    scenes : sequence of str, optional
        Scene names, ``NAME`` or ``NAME_noisy`` (default: :func:`default_scenes`).
    settings : DeblurSettings, optional
        Base settings (samples, iterations, segments); each column sets its own switches.
    alpha_sweep, masked : bool
        Also run the alpha sweep; run Table 2's masked columns.
    render_samples : int
        Instants averaged per rendered frame.
    command : str
        How the run was started, quoted in the report.
    progress : callable, optional
        Receives :class:`~stereodeblur.progress.Progress` reports.
    """
    from ..io.outputs import atomic_write_text

    start = time.perf_counter()
    names = list(scenes) if scenes else default_scenes()
    for name in names:
        scene_kind(name)
    folder = Path(work) / f"{size[0]}x{size[1]}"
    columns = bench_columns(alpha_sweep=alpha_sweep, masked=masked)
    base = DeblurSettings() if settings is None else settings
    render_missing(folder / "scenes", names, size, num_samples=render_samples, progress=progress)
    rows = []
    for name in names:
        cache = folder / "cache" / name
        row = evaluate_scene(folder / "scenes" / name, cache, columns, base, progress=progress)
        write_figure(folder / "scenes" / name, cache, COLUMNS, folder / "figures" / f"{name}.png")
        rows.append(row)
    seconds = time.perf_counter() - start
    text = markdown_report(rows, sweep=alpha_sweep, command=command, seconds=seconds)
    atomic_write_text(folder / "paper.md", text)
    data = json.dumps([asdict(r) for r in rows], indent=1, allow_nan=True)
    atomic_write_text(folder / "paper.json", data)
    report(progress, f"wrote {folder / 'paper.md'}, {folder / 'paper.json'} and figures")
    return PaperBench(tuple(rows), text, folder)
