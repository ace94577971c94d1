"""Calibration protocol of the defaults: tune on one half of a scene set, report on the other.

Run from the repository root::

    python benchmarks/calibrate_defaults.py --scenes 3                       # smoke run, train
    python benchmarks/calibrate_defaults.py --scenes 50 --size 640x480 --jobs 2
    python benchmarks/calibrate_defaults.py --split test --scenes 40 --size 320x240
    python benchmarks/calibrate_defaults.py --split test --scenes 40 --skip 240  # never looked at

Scenes: the seeded randomised family (:mod:`stereodeblur.synth.family`) and the semi-real
street scenes (:mod:`stereodeblur.synth.street`), alternating (``--kinds``); scene ``j`` of
the train split has seed ``j // len(kinds)`` (0-999), of the test split ``1000 + j //
len(kinds)``. **Tune only on ``--split train`` (the default); the test split is run and
printed only when asked for explicitly with ``--split test``, to report results that
were never looked at while tuning.**

For every scene, frame 1 of the left view is deblurred with the pipeline
(:func:`stereodeblur.pipeline.deblur_frame`) from each motion source of ``--motions``
(``gt``: the piecewise-planar model fitted to the true disparity and flow; ``sceneflow``:
estimated), the motion computed once per scene and source
(:func:`~stereodeblur.pipeline.frame_motion`) and reused by every column:

- ``default``: :class:`~stereodeblur.pipeline.DeblurSettings` defaults;
- ``paper``: the paper's settings, ``alpha=0.001``, ``boundary_weights='none'``, 10 IRLS x
  25 CG iterations;
- the candidates of :data:`CANDIDATES` (``alpha='cross-view'`` computes the motion of both
  views itself), each checked like the default against the grid of its own boundary handling
  (``--candidates`` runs some of them, ``none`` none);
- ``alpha=A`` for A in :data:`ALPHAS`, the default boundary handling, and ``HANDLING-alpha=A``
  for a candidate's other handling;

and once with the monocular path with the same defaults (``motion_source='initial-flow',
kernels='displacement'``, with the boundary handling of its strongest version,
:data:`~stereodeblur.settings.MONOCULAR_BOUNDARY_WEIGHTS`). PSNR and SSIM are measured
against gt/sharp without a border of 2.5 % of the width (at least 4 px), as
``stereodeblur bench paper`` does.

Checks, per motion source: the default is within 0.5 dB of the best alpha on average and
within 1.5 dB on every scene, and never more than 0.5 dB below the paper's settings; with the
estimated motion, the default is at least 0.5 dB above the monocular path on average and on
every semi-real (street) scene. Written: ``--output`` (markdown, default
``benchmarks/results/calibrate_defaults_SPLIT_WxH.md``) and the same path with ``.json``.
Rendered scenes and per-column results are cached under ``--work``, so a rerun resumes.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import re
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from stereodeblur.evaluation.metrics import border_for as border_of
from stereodeblur.io.outputs import atomic_write_text
from stereodeblur.pipeline.alpha import local_alpha_acts, local_alpha_signature, rules_version
from stereodeblur.pipeline.motion import relabel_rule
from stereodeblur.pipeline.observations import neighbours_version
from stereodeblur.sceneflow.from_gt import FIT_VERSION
from stereodeblur.sceneflow.settings import SceneFlowSettings
from stereodeblur.settings import PAPER_ALPHA, PAPER_CG, PAPER_IRLS, range_guard_signature

ALPHAS = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3)
PAPER = {
    "alpha": PAPER_ALPHA,
    "boundary_weights": "none",
    "interpolation": "bilinear",
    "observations": "single",
    "num_irls": PAPER_IRLS,
    "num_cg": PAPER_CG,
    "range_guard": False,
}
FRAME = 1
MOTIONS = ("gt", "sceneflow")
KINDS = ("family", "street")
WITHIN_BEST_MEAN, WITHIN_BEST_EACH, BELOW_PAPER = 0.5, 1.5, 0.5
"""dB limits of the alpha checks: mean and worst gap to the best grid alpha, and below the
paper's settings."""
OVER_MONOCULAR = 0.5
"""dB the estimated-motion default must beat the monocular path by on the semi-real
scenes, on average and on every one."""
FEATURES_VERSION = " features 1"
MOTION_STORED = " motion stored"
"""In the signature of the scene-flow columns computed from the stored scene flow."""
CANDIDATES = {
    "auto": {"alpha": "auto"},
    "cross-view": {"alpha": "cross-view"},
    "adaptive": {"boundary_weights": "adaptive", "alpha": "auto"},
    "adaptive-cross-view": {"alpha": "cross-view", "boundary_weights": "adaptive"},
    "observations": {"observations": "all", "alpha": "auto"},
    "single": {"observations": "single"},
    "other-view": {"observations": "other-view"},
    "all": {"observations": "all"},
    "iterations-10x25": {"num_irls": PAPER_IRLS, "num_cg": PAPER_CG, "alpha": "auto"},
    "cubic": {"interpolation": "cubic"},
    "bilinear": {"interpolation": "bilinear"},
    "no-relabel": {"relabel_radius": 0},
    "relabel-occlusion": {"boundary_flow": False},
    "census-0.004": {"sceneflow": SceneFlowSettings(census_threshold=0.004)},
    "dominant-leave": {"sceneflow": SceneFlowSettings(dominant_leave_window=16.0)},
    "other-side": {"sceneflow": SceneFlowSettings(other_side=True)},
    "local-alpha": {"local_alpha": "always"},
    "no-local-alpha": {"local_alpha": "off"},
}
"""Candidate settings (overrides of the defaults), each checked like the default: ``auto`` the
noise rule's alpha alone, ``cross-view`` one grid step above the best predictor of the other
view, ``adaptive`` and ``adaptive-cross-view`` the adaptive boundary handling, ``observations``
every observation with the noise rule's alpha, ``single`` / ``other-view`` / ``all`` the
observations each view is fitted to (its own frame; + the other view; + the neighbouring
frames), ``iterations-10x25`` the paper's iteration counts with the noise rule's alpha,
``cubic`` and ``bilinear`` the kernels' interpolation, ``no-relabel`` the estimate's own segment
boundaries, ``relabel-occlusion`` the moved boundaries with the occlusion-aware operator
everywhere, ``census-0.004`` a lower census threshold, ``dominant-leave`` the scene flow's
dominant motions allowed to leave the view at a correct match's cost, ``other-side`` what leaves
the view at t + 1 matched at t - 1, ``local-alpha`` the prior weight varying over the view on
every frame and ``no-local-alpha`` one alpha per view. The defaults and the reason for each:
``docs/defaults.md``."""


@dataclass(frozen=True)
class Column:
    """One deblurring of frame 1: its key, motion source and settings overrides."""

    key: str
    motion_source: str
    overrides: dict = field(default_factory=dict)

    def settings(self):
        from stereodeblur.pipeline import DeblurSettings
        from stereodeblur.settings import MONOCULAR_BOUNDARY_WEIGHTS

        if self.motion_source == "initial-flow":
            monocular = {
                "kernels": "displacement",
                "boundary_weights": MONOCULAR_BOUNDARY_WEIGHTS,
                "observations": "single",  # without a scene flow there is no other
            }
            return DeblurSettings(motion_source="initial-flow", **(monocular | self.overrides))
        return DeblurSettings(motion_source=self.motion_source, **self.overrides)


def alpha_key(alpha: float) -> str:
    return f"alpha={alpha:g}"


def grid_prefix(key: str) -> str:
    """The prefix of the alpha grid column ``key`` is compared with: its own handling's."""
    handling = CANDIDATES.get(key, {}).get("boundary_weights")
    return "" if handling is None else f"{handling}-"


def grid_columns(source: str, prefix: str = "", overrides=None) -> list[Column]:
    """The alpha grid's columns (:data:`ALPHAS`) for motion source ``source``, their keys
    prefixed by ``prefix`` and their settings by ``overrides``."""
    overrides = overrides or {}
    return [Column(prefix + alpha_key(a), source, overrides | {"alpha": a}) for a in ALPHAS]


def columns_for(motions, candidates=tuple(CANDIDATES), grid: bool = True) -> list[Column]:
    """Every column for the motion sources ``motions`` and the keys ``candidates`` of
    :data:`CANDIDATES` (and the alpha grid unless not ``grid``); the monocular one with
    ``sceneflow``."""
    chosen = {key: CANDIDATES[key] for key in candidates}
    handlings = dict.fromkeys(grid_prefix(key) for key in chosen if grid_prefix(key))
    out = []
    for source in motions:
        out.append(Column("default", source))
        out.append(Column("paper", source, dict(PAPER)))
        out += [Column(key, source, dict(overrides)) for key, overrides in chosen.items()]
        if not grid:
            continue
        out += grid_columns(source)
        for prefix in handlings:
            out += grid_columns(source, prefix, {"boundary_weights": prefix[:-1]})
    if "sceneflow" in motions:  # the estimated-motion method it competes with
        out.append(Column("monocular", "initial-flow"))
    return out


LOOKED_AT = 80
"""The test split's first seeds per kind (1000-1079), whose scenes were looked at while the defaults
were tuned; the scenes of later seeds were rendered after the defaults last changed (commit
49db94b, 2026-12-05)."""


def scene_list(split: str, count: int, kinds, skip: int = 0) -> list[tuple[str, int]]:
    """``(kind, seed)`` of ``count`` scenes of ``split`` after its first ``skip`` (a multiple
    of the number of kinds), kinds alternating."""
    from stereodeblur.synth.family import seeds_of

    per_kind, skipped = math.ceil(count / len(kinds)), skip // len(kinds)
    seeds = seeds_of(split, skipped + per_kind)[skipped:]
    return [(kinds[j % len(kinds)], seeds[j // len(kinds)]) for j in range(count)]


def ensure_scene(kind: str, seed: int, size, work: Path) -> Path:
    """The rendered scene folder, rendered first if it is not in ``work`` yet. Another
    process rendering the same scene into ``work`` is waited for (a lock per scene), not
    interfered with."""
    import shutil

    from stereodeblur.io.outputs import OutputLock
    from stereodeblur.synth.family import family_scene, spec_json, write_family_scene
    from stereodeblur.synth.street import street_scene

    make = family_scene if kind == "family" else street_scene
    spec = make(seed, size=size)
    scenes = work / "scenes"
    scenes.mkdir(parents=True, exist_ok=True)
    root = scenes / spec.name
    record = root / "gt" / "family.json"
    with OutputLock(scenes, name=f".{spec.name}.lock", wait=True):
        if record.is_file() and record.read_text(encoding="utf-8") != spec_json(spec):
            _log(f"{spec.name}: the cached scene is stale (another generator version): rendering")
            shutil.rmtree(root)
            shutil.rmtree(work / "results" / spec.name, ignore_errors=True)
        if not record.is_file():
            write_family_scene(spec, root)
    return root


def _log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _signature(settings, *, rules: bool = True) -> str:
    """What a cached column depends on: the settings (``observations`` only when not
    ``'single'``, ``interpolation`` only when not ``'bilinear'``, ``range_guard`` only when on,
    ``local_alpha`` only where it acts, ``boundary_flow`` only when off, ``relabel_radius`` only
    where it acts, so results from before those options stay valid; not the scene flow's
    settings, which act through the motion that :func:`motion_tag` names), the relabelling
    rule's version where it acts, for the rules that predict the other view their version
    (unless not ``rules``: what does not depend on the alpha), for the true motion the version
    of its fit and the version of the neighbouring frames' data terms where they are
    observed."""
    text = repr(settings).replace(", observations='single'", "")
    text = text.replace(", interpolation='bilinear'", "").replace(", range_guard=False", "")
    text = text.replace(", boundary_flow=True", "")
    text = re.sub(r", sceneflow=SceneFlowSettings\([^)]*\)", "", text)
    if not local_alpha_acts(settings):
        text = text.replace(f", local_alpha={settings.local_alpha!r}", "")
    if relabel_rule(settings) is None:
        text = text.replace(f", relabel_radius={settings.relabel_radius}", "")
    else:
        text += f" relabel rule {relabel_rule(settings)}"
    version = rules_version(settings) if rules else None
    stored = MOTION_STORED if settings.motion_source == "sceneflow" else ""
    fit = f" true motion fit {FIT_VERSION}" if settings.motion_source == "gt" else ""
    guard = range_guard_signature(settings)
    rules_text = "" if version is None else f" alpha rules {version}"
    nb = neighbours_version(settings)
    neighbours = "" if nb is None else f" neighbours {nb}"
    return text + rules_text + stored + fit + guard + neighbours + local_alpha_signature(settings)


def _cached(path: Path, signature: str) -> dict | None:
    """The cached result at ``path`` if it was made with ``signature``; None if it is
    missing, unreadable or stale."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("signature") == signature else None


def _archived(cache: Path, source: str, signature: str) -> Path:
    """Where a result made with ``signature`` is kept once its column's settings changed."""
    digest = hashlib.sha1(signature.encode("utf-8")).hexdigest()[:12]
    return cache / "archive" / f"{source}_{digest}.json"


def _archive(path: Path) -> None:
    """Keep the result at ``path`` under :func:`_archived` before it is replaced: a column
    whose settings a default takes over (e.g. the default until then as a candidate) finds it
    there."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        signature = data["signature"]
    except (OSError, ValueError, KeyError, TypeError):
        return
    source = path.stem.split("_", 1)[0]
    target = _archived(path.parent, source, signature)
    target.parent.mkdir(exist_ok=True)
    atomic_write_text(target, json.dumps(data, indent=1))


def _cached_elsewhere(cache: Path, source: str, signature: str) -> dict | None:
    """A result made with ``signature`` under another column's name or archived."""
    data = _cached(_archived(cache, source, signature), signature)
    if data is not None:
        return data
    for path in sorted(cache.glob(f"{source}_*.json")):
        data = _cached(path, signature)
        if data is not None:
            return data
    return None


def run_column(scene, column: Column, motion, truth) -> dict:
    """Deblur frame 1 with ``column`` and the given motion; PSNR, SSIM, alpha, seconds."""
    import warnings

    from stereodeblur.evaluation.metrics import psnr, ssim
    from stereodeblur.evaluation.paper_bench import deblur_with_motion

    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = deblur_with_motion(scene, FRAME, column.settings(), motion)
    seconds = time.perf_counter() - start
    border = border_of(truth.shape[1])
    return {
        "psnr": psnr(result.image, truth, border=border),
        "ssim": ssim(result.image, truth, border=border),
        "alpha": float(result.alpha) if result.alpha is not None else math.nan,
        "seconds": seconds,
        "unexplained": 0.0 if result.unexplained is None else float(result.unexplained.mean()),
    }


HIGH_FREQUENCY = 0.25  # cycles per pixel above which the spectrum counts as fine texture
TEXTURE_LEVEL = 0.01  # local RMS of the noise mask's response that counts as strong texture
UNTRUSTED = 0.5  # trust below which a pixel counts as untrusted


def spectral_share(grey: np.ndarray, cutoff: float = HIGH_FREQUENCY) -> float:
    """Share of the (Hann-windowed, mean-free) power spectrum above ``cutoff`` cycles/px."""
    H, W = grey.shape
    window = np.outer(np.hanning(H), np.hanning(W))
    power = np.abs(np.fft.rfft2((grey - grey.mean()) * window)) ** 2
    fy = np.fft.fftfreq(H)[:, None]
    fx = np.fft.rfftfreq(W)[None, :]
    radius = np.hypot(fy, fx)
    total = power[radius > 0].sum()
    return float(power[radius > cutoff].sum() / total) if total > 0 else 0.0


def frame_features(scene, motion, source: str, blurred: np.ndarray) -> dict:
    """What the pipeline knows before solving, stored with each scene's results: noise
    estimate, blur length (flow length to the neighbour times the duty cycle), fine texture,
    untrusted pixels, paths leaving the view, the default's alpha."""
    import warnings

    from scipy import ndimage

    from stereodeblur.deconv.noise import _MASK, estimate_noise_sigma
    from stereodeblur.deconv.trust import leaves_view
    from stereodeblur.pipeline.operator import view_operator
    from stereodeblur.pipeline.weights import data_terms
    from stereodeblur.pipeline.window import read_window

    settings = Column("default", source).settings()
    known = {("left", FRAME): blurred}
    window = read_window(scene, FRAME, ("left",), settings, motion=False, known=known)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        operator = view_operator(motion, window.exposure, settings)
        terms = data_terms(scene, window, "left", operator, settings)
    duty = float(window.exposure.duty_cycle)
    flow = operator.motion.flow_forward
    length = np.hypot(flow[..., 0], flow[..., 1]) * duty
    grey = np.asarray(blurred, np.float64)
    grey = grey.mean(axis=2) if grey.ndim == 3 else grey
    response = ndimage.correlate(grey, _MASK, mode="reflect") / 6.0
    local = np.sqrt(np.maximum(ndimage.uniform_filter(response**2, 5), 0.0))
    outside = leaves_view(operator.motion.flow_forward, operator.motion.flow_backward, duty)
    trust = terms.trust if terms.trust is not None else np.ones_like(grey)
    return {
        "noise_sigma": estimate_noise_sigma(blurred),
        "duty_cycle": duty,
        "blur_p50": float(np.percentile(length, 50)),
        "blur_p95": float(np.percentile(length, 95)),
        "blur_max": float(length.max()),
        "hf_share": spectral_share(grey),
        "texture_share": float(np.mean(local > TEXTURE_LEVEL)),
        "gradient_rms": float(np.sqrt(np.mean(np.sum(np.square(np.gradient(grey)), 0)))),
        "untrusted_share": float(np.mean(trust < UNTRUSTED)),
        "outside_share": float(np.mean(outside)),
        "auto_alpha": float(terms.alpha),
        "saturated_share": float(np.mean(grey > 0.98)),
    }


def unmoved(source: str):
    """The default settings of motion ``source`` with the boundaries as estimated: what a
    stored motion and the frame features are computed with (the deblurring moves them)."""
    return replace(Column("default", source).settings(), relabel_radius=0)


def motion_for(scene, column: Column, motions: dict, seconds: dict, cache: Path):
    """Frame 1's motion for ``column``: its source's with the default settings but the
    column's superpixels and scene-flow settings, computed once per scene and estimator into
    ``motions`` (the default estimator's time into ``seconds``), its boundaries as estimated
    (the deblurring moves them, ``relabel_radius``). The default estimator's
    scene flow and initial flow are stored in ``cache`` and read back on later runs
    (:func:`~stereodeblur.evaluation.motion_cache.cached_motion`): the scene flow of these
    scenes differed by up to 0.44 dB in the results between runs of the same code."""
    import warnings

    from stereodeblur.evaluation.motion_cache import cached_motion
    from stereodeblur.pipeline import frame_motion

    own = column.settings()
    source = column.motion_source
    key = (source, own.num_segments, own.sceneflow)
    if key not in motions:
        estimated = unmoved(source)
        settings = replace(estimated, num_segments=own.num_segments, sceneflow=own.sceneflow)
        if settings == estimated:
            motions[key], spent, _ = cached_motion(scene, source, settings, cache)
            seconds.setdefault(source, spent)
        else:
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                blurred = scene.read_frame("left", FRAME)
                motions[key] = frame_motion(scene, FRAME, "left", settings, blurred)
            seconds.setdefault(source, time.perf_counter() - start)
    return motions[key]


def cached_column(scene, column: Column, truth, cache: Path, motions: dict, seconds: dict) -> dict:
    """:func:`run_column`'s result for ``column`` on ``scene`` (``truth``: its sharp frame 1),
    from ``cache`` when its settings and its motion (:func:`motion_for`) match, else computed
    and cached."""
    motion, signature = _column_signature(scene, column, motions, seconds, cache)
    path = _column_path(cache, column)
    data = _stored(path, column.motion_source, signature)
    if data is None:
        data = run_column(scene, column, motion, truth) | {"signature": signature}
        _archive(path)
        atomic_write_text(path, json.dumps(data, indent=1))
        name = f"{Path(scene.root).name} {column.motion_source}/{column.key}"
        _log(f"{name}: {data['psnr']:.2f} dB ({data['seconds']:.1f} s)")
    return data


def _column_signature(scene, column: Column, motions: dict, seconds: dict, cache: Path):
    """``column``'s motion on ``scene`` (:func:`motion_for`) and its cached result's signature."""
    motion = motion_for(scene, column, motions, seconds, cache)
    return motion, _signature(column.settings()) + motion_tag(motion)


def motion_tag(motion) -> str:
    """The part of a cached result's signature that names its motion
    (:func:`~stereodeblur.evaluation.motion_cache.motion_digest`)."""
    from stereodeblur.evaluation.motion_cache import motion_digest

    return f" motion {motion_digest(motion)}"


def _column_path(cache: Path, column: Column) -> Path:
    """Where ``column``'s result on a scene is cached (``cache``: the scene's folder)."""
    return cache / f"{column.motion_source}_{column.key}.json"


def _stored(path: Path, source: str, signature: str) -> dict | None:
    """A column's cached result: at ``path`` or, with the same ``signature``, under another
    column of ``source`` in the same folder or its archive; None if there is none."""
    return _cached(path, signature) or _cached_elsewhere(path.parent, source, signature)


def run_scene(task) -> dict:
    """Every column on one scene (rendered first if needed), reusing cached results."""
    from stereodeblur.evaluation.metrics import psnr, ssim
    from stereodeblur.io.scene import open_scene

    kind, seed, size, work, motions, candidates, grid = task
    work = Path(work)
    start = time.perf_counter()
    root = ensure_scene(kind, seed, size, work)
    render_seconds = time.perf_counter() - start
    spec = json.loads((root / "gt" / "family.json").read_text(encoding="utf-8"))
    scene = open_scene(root)
    truth = scene.read_gt_sharp("left", FRAME)
    blurred = scene.read_frame("left", FRAME)
    border = border_of(truth.shape[1])
    cache = work / "results" / root.name
    cache.mkdir(parents=True, exist_ok=True)
    results, motion_seconds, motion_cache = {}, {}, {}
    for column in columns_for(motions, candidates, grid):
        data = cached_column(scene, column, truth, cache, motion_cache, motion_seconds)
        results[f"{column.motion_source}/{column.key}"] = {
            k: data[k] for k in ("psnr", "ssim", "alpha", "seconds")
        } | {"unexplained": data.get("unexplained", 0.0)}
    features = {}
    for source in motions:
        path = cache / f"{source}_features.json"
        motion = motion_for(scene, Column("default", source), motion_cache, motion_seconds, cache)
        signature = _signature(unmoved(source), rules=False) + motion_tag(motion)
        signature += FEATURES_VERSION
        data = _cached(path, signature)
        if data is None:
            data = frame_features(scene, motion, source, blurred)
            data["signature"] = signature
            atomic_write_text(path, json.dumps(data, indent=1))
        features[source] = {k: v for k, v in data.items() if k != "signature"}
    return {
        "scene": root.name,
        "kind": kind,
        "seed": seed,
        "split": spec["split"],
        "blur_px": spec["blur_px"],
        "noise": spec["noise"],
        "duty_cycle": spec["duty_cycle"],
        "description": spec["description"],
        "blurred": {
            "psnr": psnr(blurred, truth, border=border),
            "ssim": ssim(blurred, truth, border=border),
        },
        "columns": results,
        "features": features,
        "render_seconds": render_seconds,
        "motion_seconds": motion_seconds,
    }


def gaps(row: dict, source: str, key: str = "default") -> dict:
    """Default (or column ``key``), paper and best alpha of one scene and source, and the
    default's gaps."""
    columns = row["columns"]
    value = {k.split("/", 1)[1]: v["psnr"] for k, v in columns.items() if k.startswith(source)}
    grid = [grid_prefix(key) + alpha_key(a) for a in ALPHAS]
    best_key = max(grid, key=lambda k: value[k])
    return {
        "default": value[key],
        "default_alpha": columns[f"{source}/{key}"]["alpha"],
        "paper": value["paper"],
        "best": value[best_key],
        "best_alpha": best_key.rsplit("=", 1)[1],
        "below_best": value[best_key] - value[key],
        "below_paper": value["paper"] - value[key],
    }


def checks(rows, motions, key: str = "default") -> list[tuple[str, bool, str]]:
    """The three alpha checks per motion source (:data:`WITHIN_BEST_MEAN`,
    :data:`WITHIN_BEST_EACH`, :data:`BELOW_PAPER`): ``(name, passed, figures)``; of the
    default, or of the column ``key``."""
    out = []
    for source in motions:
        g = [gaps(r, source, key) for r in rows]
        mean_best = sum(x["below_best"] for x in g) / len(g)
        worst_best = max(g, key=lambda x: x["below_best"])
        worst_paper = max(g, key=lambda x: x["below_paper"])
        i_best, i_paper = g.index(worst_best), g.index(worst_paper)
        out += [
            (
                f"{source}: {key} within {WITHIN_BEST_MEAN} dB of the best alpha on average",
                mean_best <= WITHIN_BEST_MEAN,
                f"mean gap {mean_best:+.2f} dB",
            ),
            (
                f"{source}: {key} within {WITHIN_BEST_EACH} dB of the best alpha on every scene",
                worst_best["below_best"] <= WITHIN_BEST_EACH,
                f"worst {worst_best['below_best']:+.2f} dB ({rows[i_best]['scene']})",
            ),
            (
                f"{source}: {key} never more than {BELOW_PAPER} dB below the paper's settings",
                worst_paper["below_paper"] <= BELOW_PAPER,
                f"worst {worst_paper['below_paper']:+.2f} dB ({rows[i_paper]['scene']})",
            ),
        ]
    return out


def _streets(rows) -> list[dict]:
    """The semi-real (street) rows that have the monocular column."""
    return [r for r in rows if r["kind"] == "street" and "initial-flow/monocular" in r["columns"]]


def monocular_checks(rows, keys) -> list[tuple[str, bool, str]]:
    """The semi-real check of each column of ``keys`` (estimated motion): at least
    :data:`OVER_MONOCULAR` dB over the monocular path on average and on every street scene."""
    street = _streets(rows)
    if not street:
        return []
    out = []
    for key in keys:
        gains = [
            r["columns"][f"sceneflow/{key}"]["psnr"]
            - r["columns"]["initial-flow/monocular"]["psnr"]
            for r in street
        ]
        worst = min(range(len(gains)), key=gains.__getitem__)
        mean = sum(gains) / len(gains)
        figures = f"mean {mean:+.2f} dB, worst {gains[worst]:+.2f} dB ({street[worst]['scene']})"
        name = f"sceneflow: {key} at least {OVER_MONOCULAR} dB over the monocular path on the "
        ok = mean >= OVER_MONOCULAR and gains[worst] >= OVER_MONOCULAR
        out.append(
            (name + f"{len(street)} semi-real scenes, on average and on every one", ok, figures)
        )
    return out


def monocular_bounds(rows, motions) -> list[str]:
    """What the semi-real check could reach at most with each motion source of
    ``motions``: its best grid alpha per street scene (an oracle) over the monocular path."""
    street = _streets(rows)
    out = []
    for source in motions:
        gains = []
        for r in street:
            grid = [v["psnr"] for k, v in r["columns"].items() if k.startswith(f"{source}/alpha=")]
            if grid:
                gains.append(max(grid) - r["columns"]["initial-flow/monocular"]["psnr"])
        if len(gains) == len(street) and gains:
            below = sum(g < OVER_MONOCULAR for g in gains)
            out.append(
                f"- Bound, not a check: {source} at its best grid alpha per scene, "
                f"mean {sum(gains) / len(gains):+.2f} dB over the monocular path, less than "
                f"{OVER_MONOCULAR} dB above it on {below} of {len(gains)}"
            )
    return out


def _cell(entry: dict | None) -> str:
    return "–" if entry is None else f"{entry['psnr']:.2f} / {entry['ssim']:.3f}"


def scene_table(row: dict, motions) -> list[str]:
    """One scene: every column's PSNR / SSIM per motion source."""
    lines = [
        f"### {row['scene']}",
        "",
        f"{row['description']}; longest blur {row['blur_px']:.1f} px, noise "
        f"{row['noise']:.4f}, duty cycle {row['duty_cycle']:.2f}; blurred input "
        f"{row['blurred']['psnr']:.2f} dB",
        "",
        "| column | " + " | ".join(f"{m} PSNR / SSIM" for m in motions) + " |",
        "|---|" + "---|" * len(motions),
    ]
    candidates = [k for k in CANDIDATES if f"{motions[0]}/{k}" in row["columns"]]
    prefixes = dict.fromkeys(["", *(grid_prefix(k) for k in candidates)])
    keys = ["default", *candidates, "paper"]
    keys += [p + alpha_key(a) for p in prefixes for a in ALPHAS]
    for key in keys:
        cells = [_cell(row["columns"].get(f"{m}/{key}")) for m in motions]
        if key == "default" or key in candidates:
            alphas = [row["columns"][f"{m}/{key}"]["alpha"] for m in motions]
            key = f"{key} (alpha " + ", ".join(f"{a:.2g}" for a in alphas) + ")"
        lines.append(f"| {key} | " + " | ".join(cells) + " |")
    mono = row["columns"].get("initial-flow/monocular")
    if mono is not None:
        lines.append(f"| monocular (initial flow, same defaults) | {_cell(mono)} |")
    return lines + [""]


def summary_table(rows, motions) -> list[str]:
    """Per scene and source: default, paper, best alpha and the default's gaps (dB)."""
    lines = [
        "| scene | blur px | noise | motion | default | paper | best alpha | best | "
        "best - default | paper - default | monocular |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        mono = row["columns"].get("initial-flow/monocular", {"psnr": math.nan})["psnr"]
        for source in motions:
            g = gaps(row, source)
            lines.append(
                f"| {row['scene']} | {row['blur_px']:.1f} | {row['noise']:.3f} | {source} | "
                f"{g['default']:.2f} | {g['paper']:.2f} | {g['best_alpha']} | {g['best']:.2f} | "
                f"{g['below_best']:+.2f} | {g['below_paper']:+.2f} | "
                + ("–" if math.isnan(mono) else f"{mono:.2f}")
                + " |"
            )
    return lines


def code_version(revision: str = "HEAD") -> str:
    """The repository's commit (``revision``, short; ``'HEAD:src'``: the tree of ``src/``) and
    whether ``src/`` differs from it, if git can tell."""
    import subprocess

    try:
        run = dict(
            capture_output=True, text=True, check=True, cwd=Path(__file__).resolve().parents[1]
        )
        commit = subprocess.run(["git", "rev-parse", "--short", revision], **run).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], **run).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return commit + (" with uncommitted changes under src/" if dirty.strip() else "")


def candidate_table(rows, motions, candidates) -> list[str]:
    """Per motion source and candidate: its mean PSNR and the default's difference to it
    (mean, worst scene, scenes where the default is lower)."""
    lines = [
        "| motion | column | mean PSNR | default - column: mean | worst | default lower on |",
        "|---|---|---|---|---|---|",
    ]
    for source in motions:
        default = [r["columns"][f"{source}/default"]["psnr"] for r in rows]
        lines.append(f"| {source} | default | {sum(default) / len(default):.2f} | | | |")
        for key in candidates:
            values = [r["columns"][f"{source}/{key}"]["psnr"] for r in rows]
            diff = [d - v for d, v in zip(default, values, strict=True)]
            worst = min(range(len(diff)), key=diff.__getitem__)
            lines.append(
                f"| {source} | {key} | {sum(values) / len(values):.2f} | "
                f"{sum(diff) / len(diff):+.2f} | {diff[worst]:+.2f} ({rows[worst]['scene']}) | "
                f"{sum(d < 0 for d in diff)} of {len(diff)} |"
            )
    return lines


def split_note(args) -> str:
    """What the scenes of ``args`` were used for."""
    if args.split == "train":
        return "Train split: the scenes the defaults may be tuned on."
    from stereodeblur.synth.scenespec import TEST_SEEDS

    seeds = args.skip // len(args.kinds)
    first = f"Test split from seed {TEST_SEEDS[seeds]}"
    if seeds >= LOOKED_AT:
        return f"{first}: rendered after the defaults last changed, never looked at."
    return (
        f"{first}: not tuned on, but its seeds {TEST_SEEDS[0]}-{TEST_SEEDS[LOOKED_AT - 1]} were "
        f"looked at while the defaults were tuned; `--skip "
        f"{LOOKED_AT * len(args.kinds)}` reports scenes never looked at."
    )


def report(rows, args, seconds: float) -> str:
    motions = args.motions
    passed = []
    if args.grid:
        passed = checks(rows, motions)
        for key in args.candidates:
            passed += checks(rows, motions, key)
    lines = [
        f"# Calibration protocol: {args.split} split, {args.size}, {len(rows)} scenes",
        "",
        f"Command: `python benchmarks/calibrate_defaults.py {' '.join(sys.argv[1:])}`; "
        f"{seconds / 60:.1f} min wall time ({os.cpu_count()} cores, --jobs {args.jobs}, "
        "renders and columns cached in --work reused where present); "
        f"code {code_version()} at the end of the run.",
        "",
        split_note(args),
        "",
    ]
    if args.grid:
        lines += ["## Checks: the default's alpha", ""]
    else:
        lines += ["## The default against the candidates (no alpha grid: no alpha checks)", ""]
        lines += candidate_table(rows, motions, args.candidates)
    lines += [f"- {'PASS' if ok else 'FAIL'}: {name} ({figures})" for name, ok, figures in passed]
    if "sceneflow" in motions:
        semi_real = monocular_checks(rows, ["default", *args.candidates])
        if semi_real:
            lines += ["", "## Checks: semi-real scenes against the monocular path", ""]
            lines += [f"- {'PASS' if ok else 'FAIL'}: {n} ({f})" for n, ok, f in semi_real]
            lines += monocular_bounds(rows, motions)
    if args.grid:
        lines += ["", "## Summary (PSNR, dB)", ""] + summary_table(rows, motions)
    lines += ["", "## Per scene (PSNR dB / SSIM)", ""]
    for row in rows:
        lines += scene_table(row, motions)
    return "\n".join(lines) + "\n"


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument(
        "--split",
        choices=("train", "test"),
        default="train",
        help="train: seeds 0-999, the scenes to tune on; test: seeds 1000-1999 (default train)",
    )
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    parser.add_argument("--scenes", type=int, default=3, help="number of scenes (default 3)")
    parser.add_argument(
        "--skip",
        type=int,
        default=0,
        help="skip the split's first SKIP scenes (a multiple of the number of kinds), e.g. "
        "those already looked at (default 0)",
    )
    parser.add_argument(
        "--kinds", default=",".join(KINDS), help="scene kinds, alternating (default family,street)"
    )
    parser.add_argument(
        "--only",
        default="",
        help="of those scenes, only these (comma-separated names, e.g. family_1049): the ones "
        "a change can act on",
    )
    parser.add_argument(
        "--motions",
        default=",".join(MOTIONS),
        help="motion sources: gt and/or sceneflow (default gt,sceneflow)",
    )
    parser.add_argument(
        "--work",
        default=str(Path(tempfile.gettempdir()) / "stereodeblur_calibration"),
        help="cache folder of rendered scenes and results (default: in the temp folder)",
    )
    parser.add_argument(
        "--candidates",
        default=",".join(CANDIDATES),
        help="keys of CANDIDATES to run, comma-separated, or 'none' (default: all)",
    )
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument(
        "--no-grid",
        dest="grid",
        action="store_false",
        help="without the alpha grid (and the checks against it): the default against the "
        "candidates only",
    )
    parser.add_argument(
        "--output",
        default=None,
        help="markdown output, and .json beside it "
        "(default benchmarks/results/calibrate_defaults_SPLIT_WxH.md)",
    )
    args = parser.parse_args(argv)
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(f"--size must be WIDTHxHEIGHT, got {args.size!r}")
    args.size_pair = (width, height)
    args.kinds = tuple(k for k in args.kinds.split(",") if k)
    args.motions = tuple(m for m in args.motions.split(",") if m)
    args.only = tuple(n for n in args.only.split(",") if n)
    names = args.candidates.split(",") if args.candidates != "none" else []
    args.candidates = tuple(n for n in names if n)
    if set(args.candidates) - set(CANDIDATES):
        parser.error(f"--candidates must name some of {', '.join(CANDIDATES)} or be 'none'")
    if not args.kinds or set(args.kinds) - set(KINDS):
        parser.error(f"--kinds must name some of {', '.join(KINDS)}")
    if not args.motions or set(args.motions) - set(MOTIONS):
        parser.error(f"--motions must name some of {', '.join(MOTIONS)}")
    if args.scenes < 1 or args.jobs < 1:
        parser.error("--scenes and --jobs must be at least 1")
    if args.skip < 0 or args.skip % len(args.kinds):
        parser.error(f"--skip must be a multiple of the number of kinds, got {args.skip}")
    scenes = scene_list(args.split, args.scenes, args.kinds, args.skip)
    missing = set(args.only) - {f"{kind}_{seed:04d}" for kind, seed in scenes}
    if missing:
        parser.error(f"--only names scenes not among these: {', '.join(sorted(missing))}")
    if args.output is None:
        args.output = f"benchmarks/results/calibrate_defaults_{args.split}_{args.size}.md"
    return args


def run_all(function, tasks, jobs: int) -> list:
    """``function(task)`` for every task: here, or in ``jobs`` spawned single-threaded processes
    that end with this one (a killed run leaves none behind)."""
    if jobs == 1:
        return [function(t) for t in tasks]
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        jobs, mp_context=context, initializer=_start_worker, initargs=(os.getpid(),)
    ) as pool:
        return list(pool.map(function, tasks))


def _start_worker(parent: int) -> None:
    """A worker of :func:`run_all`: single-threaded, ending with ``parent``. The threads are
    set by numba's and OpenCV's calls: a ``NUMBA_NUM_THREADS`` set in this process's
    environment after numba started its threads would make every later compilation fail."""
    from stereodeblur.clip.worker import set_threads, watch_parent

    watch_parent(parent)
    set_threads(1)


def main(argv=None) -> int:
    args = parse(argv)
    work = Path(args.work) / args.size
    tasks = [
        (kind, seed, args.size_pair, str(work), args.motions, args.candidates, args.grid)
        for kind, seed in scene_list(args.split, args.scenes, args.kinds, args.skip)
        if not args.only or f"{kind}_{seed:04d}" in args.only
    ]
    start = time.perf_counter()
    rows = run_all(run_scene, tasks, args.jobs)
    seconds = time.perf_counter() - start
    text = report(rows, args, seconds)
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(output, text)
    atomic_write_text(output.with_suffix(".json"), json.dumps(rows, indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
