"""``stereodeblur bench paper``: the layout of the paper's Tables 2, 3 and 4.

Frame 1 of the left view of every scene is deblurred by each *column*, a
combination of the pipeline's switches (:class:`~stereodeblur.pipeline.DeblurSettings`):

============================  ===============  ============  =================  ========
column                        motion source    kernels       boundary weights   alpha
============================  ===============  ============  =================  ========
ground-truth 2D displacement  gt               displacement  none               0.001
initial optical flow          initial-flow     displacement  none               0.001
2D projection of scene flow   sceneflow        displacement  none               0.001
3D homographies               sceneflow        homography    none               0.001
paper (full)                  sceneflow        homography    paper (Eq. 5)      0.001
ours (full)                   sceneflow        homography    adaptive           auto
============================  ===============  ============  =================  ========

Table 2 ("without motion discontinuities") repeats the first four with
``boundary_mask='gt'``: the scene's gt/mixed pixels get weight 0 throughout.
Tables 3 (PSNR) and 4 (SSIM) use all six columns without the mask. A seventh run,
"ours, true motion" (:data:`TRUE_MOTION`: ours full with motion source gt, the same
piecewise-planar model fitted to the true disparity and flow), is no method but shows how
far a better motion estimate could take the blur model. AEP is the
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
The alpha sweep (``--alpha-sweep``) deblurs with "ours (full)" at every alpha of
:data:`ALPHA_SWEEP` and compares with ``alpha='auto'``.

Everything is cached under the work folder, so an interrupted run resumes:
``WORK/SIZE/scenes/NAME`` (rendered scenes), ``WORK/SIZE/cache/NAME/`` (scene
flow, initial flow, one JSON and one PNG per column), ``WORK/SIZE/figures/NAME.png``
(input | each method | sharp, with 4x |difference| images below), and the tables
``WORK/SIZE/paper.md`` and ``paper.json``.
"""

from __future__ import annotations

import json
import math
import shutil
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

FRAME = 1
PAPER_ALPHA = 1e-3
ALPHA_SWEEP = (3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
PLANAR_SCENES = ("upward", "forward", "forward_yaw")
NOISY_SUFFIX = "_noisy"
LOW_WEIGHT = 0.5
NEAR_MIXED_PX = 3.0
FLOW_ERROR_PX = 1.0
CHANGE = 0.05
RENDER_SAMPLES = 48
DIFFERENCE_GAIN = 4.0


@dataclass(frozen=True)
class Column:
    """One method of the tables: a combination of the pipeline's switches."""

    key: str
    title: str
    motion_source: str
    kernels: str
    boundary_weights: str = "none"
    alpha: float | str = PAPER_ALPHA
    boundary_mask: str | None = None

    def settings(self, base):
        """``base`` (a DeblurSettings) with this column's switches."""
        from dataclasses import replace

        return replace(
            base,
            motion_source=self.motion_source,
            kernels=self.kernels,
            boundary_weights=self.boundary_weights,
            alpha=self.alpha,
            boundary_mask=self.boundary_mask,
        )

    def flags(self) -> str:
        """The equivalent ``stereodeblur deblur`` options."""
        weights = (
            "--no-boundary-weights"
            if self.boundary_weights == "none"
            else f"--boundary-weights {self.boundary_weights}"
        )
        mask = f" --boundary-mask {self.boundary_mask}" if self.boundary_mask else ""
        return (
            f"--motion-source {self.motion_source} --kernels {self.kernels} {weights} "
            f"--alpha {self.alpha}{mask}"
        )


COLUMNS = (
    Column("gt-displacement", "gt 2D displacement", "gt", "displacement"),
    Column("initial-flow", "initial optical flow", "initial-flow", "displacement"),
    Column("sceneflow-2d", "2D projection of scene flow", "sceneflow", "displacement"),
    Column("homographies", "3D homographies", "sceneflow", "homography"),
    Column("paper-full", "paper (full)", "sceneflow", "homography", "paper"),
    Column("ours-full", "ours (full)", "sceneflow", "homography", "adaptive", "auto"),
)
"""Tables 3 and 4."""

MASKED_COLUMNS = tuple(
    Column(
        "masked-" + c.key, c.title, c.motion_source, c.kernels, c.boundary_weights, c.alpha, "gt"
    )
    for c in COLUMNS[:4]
)
"""Table 2: the 2D and 3D kernels with gt/mixed masked out."""

FULL_KEYS = ("paper-full", "ours-full")

TRUE_MOTION = Column(
    "ours-true-motion", "ours, true motion", "gt", "homography", "adaptive", "auto"
)
"""Ours (full) with the scene flow fitted to the true disparity and flow: how far a better
motion estimate could take the blur model (not a method; kept out of Tables 3 and 4)."""


def sweep_column(alpha: float) -> Column:
    """ "ours (full)" at a fixed ``alpha``."""
    return Column(
        f"sweep-{alpha:g}", f"ours, alpha {alpha:g}", "sceneflow", "homography", "adaptive", alpha
    )


@dataclass(frozen=True)
class ColumnResult:
    """One column on one scene.

    ``aep`` / ``ade`` are NaN where the column has no such estimate; the weight
    statistics are NaN for fixed weights.
    """

    column: str
    psnr: float
    ssim: float
    aep: float
    ade: float
    alpha: float
    seconds: float
    low_weight_percent: float = math.nan
    low_weight_explained_percent: float = math.nan
    changed_last_percent: float = math.nan
    signature: dict = field(default_factory=dict)


@dataclass(frozen=True)
class SceneResult:
    """All columns on one scene, plus the blurred input's scores."""

    scene: str
    kind: str  # 'object' or 'planar'
    noisy: bool
    size: str
    psnr_blurred: float
    ssim_blurred: float
    columns: dict
    sceneflow_seconds: float = math.nan
    warnings: tuple[str, ...] = ()


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
        f"planar one ({', '.join(PLANAR_MOTIONS)}), optionally with the suffix _noisy"
    )


def default_scenes() -> list[str]:
    """Every object scene and the paper's planar motions, each noiseless and noisy."""
    from ..synth.objects import OBJECT_SCENES

    names = list(OBJECT_SCENES) + list(PLANAR_SCENES)
    return [n + suffix for n in names for suffix in ("", NOISY_SUFFIX)]


def render_missing(base: Path, names, size, *, num_samples: int = RENDER_SAMPLES, progress=None):
    """Render and write the scenes of ``names`` not yet under ``base`` (both variants at once)."""
    from ..synth.objects import NOISE_SIGMA, add_noise, make_object_scene
    from ..synth.planar import make_planar_scene, write_rendered_scene

    missing = [n for n in names if not (base / n / "camera.json").is_file()]
    for root in dict.fromkeys(n.removesuffix(NOISY_SUFFIX) for n in missing):
        if progress is not None:
            progress(f"rendering {root} at {size[0]}x{size[1]}")
        if scene_kind(root) == "object":
            scene = make_object_scene(root, size=size, num_samples=num_samples)
        else:
            scene = make_planar_scene(root, size=size, num_samples=num_samples)
        for name in (root, root + NOISY_SUFFIX):
            if name in missing:
                variant = scene if name == root else add_noise(scene, NOISE_SIGMA)
                # Written aside and renamed, so that an interrupted run leaves no half scene.
                partial = base / f".{name}.partial"
                if partial.exists():
                    shutil.rmtree(partial)
                write_rendered_scene(variant, partial)
                partial.rename(base / name)


# --- motions --------------------------------------------------------------------------------


def _quiet(function, *args, **kwargs):
    """Call ``function``, returning ``(result, warning messages)`` instead of warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = function(*args, **kwargs)
    return result, tuple(dict.fromkeys(str(w.message) for w in caught))


def cached_motion(scene, source: str, settings, cache: Path):
    """The :class:`~stereodeblur.pipeline.FrameMotion` of frame 1 (left) from ``source``.

    Scene flow and initial flow are stored under ``cache`` and read back on later runs;
    gt motion is recomputed (it is cheap). Returns ``(motion, seconds, warnings)``.
    """
    from dataclasses import replace

    from ..pipeline import FrameMotion, dense_flow, frame_motion, neighbour_of
    from ..sceneflow.storage import load_sceneflow, save_sceneflow

    kernels = "displacement" if source == "initial-flow" else settings.kernels
    settings = replace(settings, motion_source=source, kernels=kernels)
    neighbour = neighbour_of(FRAME, scene.num_frames)
    path = cache / f"{source}.npz"
    if source == "sceneflow" and path.is_file():
        sf = load_sceneflow(path)
        dense = dense_flow(scene, FRAME, "left", scene.read_frame("left", FRAME))
        motion = FrameMotion(FRAME, neighbour, "left", sf, sf.flow(), sf.reversed().flow(), dense)
        return motion, 0.0, ()
    if source == "initial-flow" and path.is_file():
        with np.load(path) as data:
            backward = data["backward"] if data["backward"].size else None
            motion = FrameMotion(FRAME, neighbour, "left", None, data["forward"], backward)
        return motion, 0.0, ()
    start = time.perf_counter()
    blurred = scene.read_frame("left", FRAME)
    motion, messages = _quiet(frame_motion, scene, FRAME, "left", settings, blurred)
    seconds = time.perf_counter() - start
    cache.mkdir(parents=True, exist_ok=True)
    if source == "sceneflow":
        save_sceneflow(path, motion.sceneflow)
    elif source == "initial-flow":
        backward = np.zeros(0) if motion.flow_backward is None else motion.flow_backward
        np.savez_compressed(path, forward=motion.flow_forward, backward=backward)
    return motion, seconds, messages


# --- one column -----------------------------------------------------------------------------


def _border(shape) -> int:
    return max(4, round(0.025 * shape[1]))


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


def run_column(scene, column: Column, base_settings, motion, truth: dict) -> tuple:
    """Deblur frame 1 with ``column``; returns ``(ColumnResult, image)``."""
    from ..pipeline import deblur_frame
    from .metrics import disparity_error, endpoint_error, psnr, ssim

    settings = column.settings(base_settings)
    start = time.perf_counter()
    result, _ = _quiet(deblur_frame, scene, FRAME, settings=settings, motion=motion)
    seconds = time.perf_counter() - start
    sharp = truth["sharp"]
    border = _border(sharp.shape)
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
            signature=_signature(column, base_settings),
            **stats,
        ),
        image,
    )


def _signature(column: Column, settings) -> dict:
    """What a cached result depends on."""
    return {**asdict(column.settings(settings)), "frame": FRAME}


# --- one scene ------------------------------------------------------------------------------


def evaluate_scene(
    root: Path, cache: Path, columns, base_settings, *, progress=None
) -> SceneResult:
    """All ``columns`` on the scene at ``root``, reusing results cached under ``cache``."""
    from ..io.formats import write_png
    from ..io.scene import open_scene
    from .metrics import psnr, ssim

    say = progress or (lambda message: None)
    scene = open_scene(root)
    name = root.name
    truth = {
        "sharp": scene.read_gt_sharp("left", FRAME),
        "flow": scene.read_gt_flow("left", FRAME),
        "disparity": scene.read_gt_disparity("left", FRAME),
        "mixed": scene.read_gt_mixed("left", FRAME),
    }
    blurred = scene.read_frame("left", FRAME)
    border = _border(blurred.shape)
    results = {}
    motions = {}
    messages: list[str] = []
    sceneflow_seconds = math.nan
    for column in columns:
        json_path = cache / f"{column.key}.json"
        signature = _signature(column, base_settings)
        if json_path.is_file():
            data = json.loads(json_path.read_text(encoding="utf-8"))
            if data.get("signature") == json.loads(json.dumps(signature)):
                results[column.key] = ColumnResult(**data)
                continue
        if column.motion_source not in motions:
            say(f"{name}: motion ({column.motion_source})")
            motion, seconds, caught = cached_motion(
                scene, column.motion_source, base_settings, cache
            )
            motions[column.motion_source] = motion
            messages += caught
            if column.motion_source == "sceneflow" and seconds:
                sceneflow_seconds = seconds
        say(f"{name}: {column.key}")
        motion = motions[column.motion_source]
        result, image = run_column(scene, column, base_settings, motion, truth)
        cache.mkdir(parents=True, exist_ok=True)
        write_png(cache / f"{column.key}.png", np.clip(image, 0, 1), bit_depth=16)
        json_path.write_text(json.dumps(asdict(result), indent=1), encoding="utf-8")
        results[column.key] = result
        say(f"{name}: {column.key} PSNR {result.psnr:.2f} dB ({result.seconds:.0f} s)")
    timing = cache / "sceneflow_seconds.json"
    if not math.isnan(sceneflow_seconds):
        timing.write_text(json.dumps(sceneflow_seconds), encoding="utf-8")
    elif timing.is_file():
        sceneflow_seconds = float(json.loads(timing.read_text(encoding="utf-8")))
    return SceneResult(
        scene=name,
        kind=scene_kind(name),
        noisy=name.endswith(NOISY_SUFFIX),
        size=f"{blurred.shape[1]}x{blurred.shape[0]}",
        psnr_blurred=psnr(blurred, truth["sharp"], border=border),
        ssim_blurred=ssim(blurred, truth["sharp"], border=border),
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


# --- tables ---------------------------------------------------------------------------------


def _value(row: SceneResult, key: str, metric: str) -> float:
    entry = row.columns.get(key)
    return math.nan if entry is None else float(entry[metric])


def _fmt(value: float, digits: int = 2) -> str:
    return "–" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def _mean_row(rows, getter) -> float:
    values = [getter(r) for r in rows]
    values = [v for v in values if not math.isnan(v)]
    return float(np.mean(values)) if values else math.nan


def _groups(rows):
    for noisy, label in ((False, "noiseless"), (True, "noisy, sigma = 0.01")):
        for kind in ("planar", "object"):
            chosen = [r for r in rows if r.noisy == noisy and r.kind == kind]
            if chosen:
                yield f"{kind} scenes, {label}", chosen


def table_masked(rows) -> str:
    """Table 2: masked boundaries; PSNR of the 2D and 3D kernels with AEP / ADE."""
    head = (
        "| scene | gt 2D displacement PSNR | initial flow AEP | PSNR | 2D proj. scene flow AEP "
        "| PSNR | 3D homographies ADE | PSNR |\n|---|---:|---:|---:|---:|---:|---:|---:|"
    )
    keys = [c.key for c in MASKED_COLUMNS]
    out = []
    for label, group in _groups(rows):
        lines = [f"**{label}**", "", head]
        for r in group + ["mean"]:
            rr = group if r == "mean" else [r]

            def m(key, metric, rr=rr):
                return _mean_row(rr, lambda x: _value(x, key, metric))

            psnrs = [m(k, "psnr") for k in keys]
            best = np.nanmax(psnrs) if not all(math.isnan(p) for p in psnrs) else math.nan
            cells = [f"**{_fmt(p)}**" if p == best else _fmt(p) for p in psnrs]
            name = "mean" if r == "mean" else r.scene
            lines.append(
                f"| {name} | {cells[0]} | {_fmt(m(keys[1], 'aep'))} | {cells[1]} | "
                f"{_fmt(m(keys[2], 'aep'))} | {cells[2]} | {_fmt(m(keys[3], 'ade'))} | {cells[3]} |"
            )
        out.append("\n".join(lines))
    return "\n\n".join(out)


def table_metric(rows, metric: str) -> str:
    """Table 3 (``metric='psnr'``) or Table 4 (``'ssim'``): all columns, no mask."""
    digits = 2 if metric == "psnr" else 3
    titles = " | ".join(c.title for c in COLUMNS)
    head = f"| scene | blurred | {titles} |\n|---|" + "---:|" * (len(COLUMNS) + 1)
    out = []
    for label, group in _groups(rows):
        lines = [f"**{label}**", "", head]
        for r in group + ["mean"]:
            rr = group if r == "mean" else [r]
            values = [_mean_row(rr, lambda x, k=c.key: _value(x, k, metric)) for c in COLUMNS]
            blurred = _mean_row(rr, lambda x: getattr(x, f"{metric}_blurred"))
            finite = [v for v in values if not math.isnan(v)]
            best = max(finite) if finite else math.nan
            cells = [f"**{_fmt(v, digits)}**" if v == best else _fmt(v, digits) for v in values]
            name = "mean" if r == "mean" else r.scene
            lines.append(f"| {name} | {_fmt(blurred, digits)} | " + " | ".join(cells) + " |")
        out.append("\n".join(lines))
    return "\n\n".join(out)


def table_weights(rows) -> str:
    """Weight diagnostics of the full methods (module docstring)."""
    lines = [
        "| scene | ours: % trust < 0.5 | of those: % near gt/mixed or flow error > 1 px "
        "| % changed > 0.05 in last iteration | paper: % w < 0.5 | of those explained "
        "| % changed in last iteration |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        cells = []
        for key in FULL_KEYS[::-1]:
            for metric in (
                "low_weight_percent",
                "low_weight_explained_percent",
                "changed_last_percent",
            ):
                cells.append(_fmt(_value(r, key, metric), 1))
        lines.append(f"| {r.scene} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def table_sweep(rows) -> str:
    """PSNR of ours (full) at each fixed alpha and at auto."""
    sweep = [sweep_column(a).key for a in ALPHA_SWEEP]
    head = (
        "| scene | " + " | ".join(f"{a:g}" for a in ALPHA_SWEEP) + " | auto (alpha) | best - auto |"
    )
    lines = [head, "|---|" + "---:|" * (len(ALPHA_SWEEP) + 2)]
    for r in rows:
        values = [_value(r, k, "psnr") for k in sweep]
        auto = _value(r, "ours-full", "psnr")
        alpha = _value(r, "ours-full", "alpha")
        finite = [v for v in values if not math.isnan(v)]
        best = max(finite) if finite else math.nan
        cells = [f"**{_fmt(v)}**" if v == best else _fmt(v) for v in values]
        lines.append(
            f"| {r.scene} | " + " | ".join(cells) + f" | {_fmt(auto)} ({alpha:.2g}) | "
            f"{_fmt(best - auto)} |"
        )
    return "\n".join(lines)


def table_true_motion(rows) -> str:
    """PSNR / SSIM of ours with the estimated and the true motion, and the initial flow."""
    keys = ("initial-flow", "ours-full", TRUE_MOTION.key)
    head = (
        "| scene | initial optical flow | ours (full) | ours, true motion |\n|---|---:|---:|---:|"
    )
    out = []
    for label, group in _groups(rows):
        lines = [f"**{label}**", "", head]
        for r in group + ["mean"]:
            rr = group if r == "mean" else [r]
            cells = [
                f"{_fmt(_mean_row(rr, lambda x, k=k: _value(x, k, 'psnr')))} / "
                f"{_fmt(_mean_row(rr, lambda x, k=k: _value(x, k, 'ssim')), 3)}"
                for k in keys
            ]
            name = "mean" if r == "mean" else r.scene
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        out.append("\n".join(lines))
    return "\n\n".join(out)


def summary(rows, *, sweep: bool) -> list[str]:
    """The issue's checks, as sentences (object scenes; noiseless and noisy separately)."""
    out = []
    for noisy in (False, True):
        group = [r for r in rows if r.kind == "object" and r.noisy == noisy]
        if not group:
            continue
        label = "noisy" if noisy else "noiseless"

        def diff(a, b, metric="psnr", group=group):
            return np.array([_value(r, a, metric) - _value(r, b, metric) for r in group])

        d_hom = diff("ours-full", "homographies")
        d_flow = diff("ours-full", "initial-flow")
        ssim_means = {
            c.key: _mean_row(group, lambda x, k=c.key: _value(x, k, "ssim")) for c in COLUMNS
        }
        best_ssim = max(
            ssim_means, key=lambda k: -np.inf if math.isnan(ssim_means[k]) else ssim_means[k]
        )
        out.append(
            f"object scenes, {label}: ours (full) - 3D homographies = {np.nanmean(d_hom):+.2f} dB "
            f"mean, {np.nanmin(d_hom):+.2f} dB worst scene; ours (full) - initial optical flow "
            f"= {np.nanmean(d_flow):+.2f} dB mean; best mean SSIM: {best_ssim} "
            f"({ssim_means[best_ssim]:.3f}; ours {ssim_means['ours-full']:.3f})"
        )
        d_true = diff(TRUE_MOTION.key, "initial-flow")
        if not np.all(np.isnan(d_true)):
            out.append(
                f"object scenes, {label}: ours with the true motion - initial optical flow = "
                f"{np.nanmean(d_true):+.2f} dB mean ({np.nanmin(d_true):+.2f} to "
                f"{np.nanmax(d_true):+.2f})"
            )
        explained = [_value(r, "ours-full", "low_weight_explained_percent") for r in group]
        changed = [_value(r, "ours-full", "changed_last_percent") for r in group]
        out.append(
            f"object scenes, {label}: ours (full) trust < 0.5 explained by gt/mixed or flow "
            f"error: {np.nanmean(explained):.1f} % mean, {np.nanmin(explained):.1f} % worst; "
            f"changed > 0.05 in the last iteration: {np.nanmean(changed):.2f} % mean, "
            f"{np.nanmax(changed):.2f} % worst"
        )
    if sweep:
        for noisy in (False, True):
            group = [r for r in rows if r.noisy == noisy]
            if not group:
                continue
            gaps = []
            for r in group:
                values = [_value(r, sweep_column(a).key, "psnr") for a in ALPHA_SWEEP]
                gaps.append(np.nanmax(values) - _value(r, "ours-full", "psnr"))
            out.append(
                f"alpha sweep, {'noisy' if noisy else 'noiseless'} (all scenes): best fixed alpha "
                f"- auto = {np.nanmean(gaps):+.2f} dB mean, {np.nanmax(gaps):+.2f} dB worst"
            )
    return out


def legend(columns) -> str:
    """Every column as the ``stereodeblur deblur`` options that give it."""
    lines = ["| column | options |", "|---|---|"]
    lines += [f"| {c.key} | `{c.flags()}` |" for c in columns]
    return "\n".join(lines)


def report(rows, *, sweep: bool, command: str, seconds: float) -> str:
    """The whole Markdown report."""
    parts = [
        "# Paper benchmark (Tables 2-4)",
        f"Command: `{command}`; {seconds / 60:.1f} min in this run (cached results are reused).",
        "## Table 2: deblurring with gt motion boundaries masked (PSNR dB, AEP / ADE px)",
        table_masked(rows),
        "## Table 3: deblurring with motion boundaries (PSNR dB)",
        table_metric(rows, "psnr"),
        "## Table 4: deblurring with motion boundaries (SSIM)",
        table_metric(rows, "ssim"),
        "## Ours with the true motion (PSNR dB / SSIM)",
        table_true_motion(rows),
        "## Motion-boundary weights of the full methods",
        table_weights(rows),
    ]
    if sweep:
        parts += ["## Alpha sweep: ours (full) at fixed alpha vs auto (PSNR dB)", table_sweep(rows)]
    parts += ["## Checks", "\n".join(f"- {s}" for s in summary(rows, sweep=sweep))]
    parts += ["## Columns", legend(COLUMNS + (TRUE_MOTION,) + MASKED_COLUMNS)]
    return "\n\n".join(parts) + "\n"


# --- CLI ------------------------------------------------------------------------------------


def main(args) -> int:
    """CLI entry: render missing scenes, evaluate (resumably), write tables and figures."""
    import sys

    from ..cli import Progress, parse_size
    from ..pipeline import DeblurSettings

    say = Progress(args.quiet)
    start = time.perf_counter()
    width, height = parse_size(args.size)
    size = f"{width}x{height}"
    names = [n.strip() for n in args.scenes.split(",")] if args.scenes else default_scenes()
    for name in names:
        scene_kind(name)
    work = Path(args.work) / size
    columns = list(COLUMNS) + [TRUE_MOTION]
    columns += [] if args.no_masked else list(MASKED_COLUMNS)
    if args.alpha_sweep:
        columns += [sweep_column(a) for a in ALPHA_SWEEP]
    base = DeblurSettings(
        num_samples=args.samples, num_irls=args.irls, num_cg=args.cg, num_segments=args.segments
    )
    render_missing(
        work / "scenes", names, (width, height), num_samples=args.render_samples, progress=say
    )
    rows = []
    for name in names:
        cache = work / "cache" / name
        row = evaluate_scene(work / "scenes" / name, cache, columns, base, progress=say)
        write_figure(work / "scenes" / name, cache, COLUMNS, work / "figures" / f"{name}.png")
        rows.append(row)
    command = "stereodeblur " + " ".join(sys.argv[1:] if args.argv is None else args.argv)
    seconds = time.perf_counter() - start
    text = report(rows, sweep=args.alpha_sweep, command=command, seconds=seconds)
    print(text)
    (work / "paper.md").write_text(text, encoding="utf-8")
    (work / "paper.json").write_text(
        json.dumps([asdict(r) for r in rows], indent=1, allow_nan=True), encoding="utf-8"
    )
    say(f"wrote {work / 'paper.md'}, {work / 'paper.json'} and {work / 'figures'}")
    return 0
