"""The Markdown report of ``bench paper``: Tables 2-4, weights, alpha sweep and checks.

Every function takes the :class:`~.paper_columns.SceneResult` rows of a run. Values missing
from a row (a column not run) show as "–"; means skip them.
"""

from __future__ import annotations

import math

import numpy as np

from .paper_columns import (
    ALPHA_SWEEP,
    COLUMNS,
    FULL_KEYS,
    MASKED_COLUMNS,
    TRUE_MOTION,
    SceneResult,
    sweep_column,
)


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
    """Table 3 (``metric='psnr'``), Table 4 (``'ssim'``) or the gt/mixed error
    (``'mixed_mse'``, times 1000, lower is better): all columns, no mask."""
    digits = 3 if metric == "ssim" else 2
    scale, pick = (1000.0, min) if metric == "mixed_mse" else (1.0, max)
    titles = " | ".join(c.title for c in COLUMNS)
    head = f"| scene | blurred | {titles} |\n|---|" + "---:|" * (len(COLUMNS) + 1)
    out = []
    for label, group in _groups(rows):
        if all(math.isnan(_value(r, c.key, metric)) for r in group for c in COLUMNS):
            continue  # e.g. no gt/mixed pixels on the planar scenes
        lines = [f"**{label}**", "", head]
        for r in group + ["mean"]:
            rr = group if r == "mean" else [r]
            values = [
                scale * _mean_row(rr, lambda x, k=c.key: _value(x, k, metric)) for c in COLUMNS
            ]
            blurred = scale * _mean_row(rr, lambda x: getattr(x, f"{metric}_blurred"))
            finite = [v for v in values if not math.isnan(v)]
            best = pick(finite) if finite else math.nan
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
    """PSNR of ours (full) at each fixed alpha and with the default alpha."""
    sweep = [sweep_column(a).key for a in ALPHA_SWEEP]
    head = (
        "| scene | "
        + " | ".join(f"{a:g}" for a in ALPHA_SWEEP)
        + " | default (alpha) | best - default |"
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
        d_mono = diff("ours-full", "monocular")
        if not np.all(np.isnan(d_mono)):
            out.append(
                f"object scenes, {label}: ours (full) - monocular (same defaults) = "
                f"{np.nanmean(d_mono):+.2f} dB mean, {np.nanmin(d_mono):+.2f} dB worst scene"
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
    """Every column as the settings that give it."""
    lines = ["| column | settings |", "|---|---|"]
    lines += [f"| {c.key} | `{c.describe()}` |" for c in columns]
    return "\n".join(lines)


def markdown_report(rows, *, sweep: bool, command: str, seconds: float) -> str:
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
        "## Error in the pixels whose exposure mixes surfaces (gt/mixed; MSE x 1000)",
        table_metric(rows, "mixed_mse"),
        "## Ours with the true motion (PSNR dB / SSIM)",
        table_true_motion(rows),
        "## Motion-boundary weights of the full methods",
        table_weights(rows),
    ]
    if sweep:
        parts += [
            "## Alpha sweep: ours (full) at fixed alpha vs the default alpha (PSNR dB)",
            table_sweep(rows),
        ]
    parts += ["## Checks", "\n".join(f"- {s}" for s in summary(rows, sweep=sweep))]
    parts += ["## Columns", legend(COLUMNS + (TRUE_MOTION,) + MASKED_COLUMNS)]
    return "\n\n".join(parts) + "\n"
