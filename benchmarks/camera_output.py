"""The default on camera output and with a wrong exposure time: a user's own footage.

Run from the repository root (PyAV for the H.264 column: ``pip install av``)::

    python benchmarks/camera_output.py --work DIR                 # 40 test scenes, 320x240
    python benchmarks/camera_output.py --work DIR --scenes 4      # smoke run

Scenes: the calibration protocol's test split as its README figures use it
(``calibrate_defaults.py --split test --skip 200``: the randomised family and the semi-real
streets, alternating, seeds 1100 on), rendered in linear light with their noise.
Frame 1 of the left view is deblurred with the defaults and the estimated motion from:

- ``linear``: the rendered frames, the true exposure time;
- ``x0.5``, ``x2``: the same frames, told half or twice the true exposure (at most the frame
  interval);
- ``camera``: every frame of both views through a camera (:func:`camera_frame`: shot noise
  of :data:`FULL_WELL` electrons at white and :data:`READ_NOISE` electrons of read noise on
  the linear values, the sRGB curve, 8 bits), a scene whose ``camera.json`` says ``srgb``,
  the true exposure;
- ``h264``: those 8-bit frames of each view encoded as one H.264 video (libx264 through
  PyAV, :data:`BITS_PER_PIXEL` bits per pixel and frame, yuv420p) and decoded again;
- ``auto``, ``camera-auto``, ``h264-auto``: the linear, camera and H.264 frames with the
  exposure withheld (``--exposure auto``: estimated from the frames);
- ``sharp-auto``: the scene rendered again with exposure 0 (sharp frames, same noise), the
  exposure withheld; scored against its input (a sharp frame should pass through).

With an exposure given, the run's exposure check (the frames' estimate, a warning beyond a
factor :data:`~stereodeblur.pipeline.exposure.EXPOSURE_TOLERANCE`) is part of the run; the
``auto`` runs deblur for the estimate.

Scores: PSNR against ``gt/sharp`` without the protocol's border, of the result and of the
blurred input it was given; the linear runs in linear values, the camera runs in what a user
sees, 8-bit sRGB (the truth and the result encoded and rounded alike). Written: ``--output``
(markdown, default ``benchmarks/results/camera_output_WxH.md``); each run is cached under
``--work`` with the tree of ``src/`` it ran on, so a rerun of the same code resumes.
``--reuse TREE`` also takes the runs cached from another ``src/`` tree, once the current code
has reproduced each variant's first scene to 0.01 dB; with an exposure given, their exposure
check is made anew (:func:`exposure_check`).
"""

from __future__ import annotations

import argparse
import io
import json
import shutil
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from calibrate_defaults import code_version, ensure_scene, scene_list

FRAME = 1
FULL_WELL = 2000.0
"""Electrons at white: the shot noise of a small sensor at a raised gain (low light)."""
READ_NOISE = 3.0
"""Read noise in electrons."""
BELOW = -0.005
"""dB: a gain that rounds to 0.00 (a frame passed through) is not below the input."""
BITS_PER_PIXEL = 0.3
"""H.264 bits per pixel and frame: 1.8 Mbit/s for 640x480 at 20 frames per second."""
VARIANTS = (
    "linear",
    "auto",
    "x0.5",
    "x2",
    "camera",
    "camera-auto",
    "h264",
    "h264-auto",
    "sharp-auto",
)


def camera_frame(linear: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``linear`` (float, [0, 1]) as an 8-bit sRGB camera would store it."""
    electrons = rng.poisson(np.clip(linear, 0.0, 1.0) * FULL_WELL).astype(np.float64)
    electrons += rng.normal(0.0, READ_NOISE, linear.shape)
    return encode8(np.clip(electrons / FULL_WELL, 0.0, 1.0))


def encode8(linear: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] as 8-bit sRGB."""
    from stereodeblur.io.srgb import linear_to_srgb

    return np.round(linear_to_srgb(np.clip(linear, 0.0, 1.0)) * 255.0).astype(np.uint8)


def h264_round_trip(frames: list[np.ndarray], fps: float) -> list[np.ndarray]:
    """8-bit RGB or grey ``frames`` encoded as one H.264 stream and decoded again (one
    thread, so the same frames give the same stream); an odd size is padded by its last row
    or column for the encoder (yuv420p) and cropped again."""
    import av

    rows, cols = frames[0].shape[:2]
    grey = frames[0].ndim == 2
    pad = [(0, rows % 2), (0, cols % 2)] + [(0, 0)] * (frames[0].ndim - 2)
    frames = [np.pad(f, pad, mode="edge") for f in frames]
    height, width = frames[0].shape[:2]
    buffer = io.BytesIO()
    with av.open(buffer, "w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=round(fps))
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.bit_rate = int(BITS_PER_PIXEL * width * height * fps)
        stream.options = {"preset": "medium", "threads": "1"}
        for frame in frames:
            rgb = np.repeat(frame[..., None], 3, axis=2) if frame.ndim == 2 else frame
            container.mux(stream.encode(av.VideoFrame.from_ndarray(rgb, format="rgb24")))
        container.mux(stream.encode())
    buffer.seek(0)
    with av.open(buffer) as container:
        decoded = [f.to_ndarray(format="rgb24")[:rows, :cols] for f in container.decode(video=0)]
    if grey:
        return [np.round(f.mean(axis=2)).astype(np.uint8) for f in decoded]
    return decoded


def camera_scene(root: Path, work: Path, video: bool) -> Path:
    """The scene ``root`` through the camera (and H.264 if ``video``), written once."""
    import cv2

    from stereodeblur.io.scene import open_scene

    out = work / ("h264" if video else "camera") / root.name
    if (out / "camera.json").is_file():
        return out
    scene = open_scene(root)
    seed = int.from_bytes(root.name.encode(), "little") % (2**32)
    temporary = out.with_name(out.name + ".tmp")
    shutil.rmtree(temporary, ignore_errors=True)
    for v, view in enumerate(("left", "right")):
        rng = np.random.default_rng([seed, v])
        frames = [camera_frame(scene.read_frame(view, i), rng) for i in range(scene.num_frames)]
        if video:
            frames = h264_round_trip(frames, scene.info.exposure.frame_rate)
        (temporary / view).mkdir(parents=True)
        for i, frame in enumerate(frames):
            bgr = frame if frame.ndim == 2 else frame[..., ::-1]
            cv2.imwrite(str(temporary / view / f"{i:06d}.png"), bgr)
    info = json.loads((root / "camera.json").read_text(encoding="utf-8"))
    (temporary / "camera.json").write_text(json.dumps(info | {"color": "srgb"}, indent=2))
    temporary.rename(out)
    return out


def run_variant(root: Path, variant: str, work: Path) -> dict:
    """PSNR of the default's result and of its input for one variant of scene ``root``."""
    from stereodeblur.evaluation.metrics import border_for, psnr
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline import deblur_frame
    from stereodeblur.settings import DeblurSettings

    original = open_scene(root)
    truth = original.read_gt_sharp("left", FRAME)
    encoded, auto = is_encoded(variant), variant.endswith("auto")
    scene = _variant_scene(root, variant, work)
    settings = DeblurSettings(exposure="auto" if auto else "given")
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = deblur_frame(scene, FRAME, view="left", settings=settings)
    seconds = time.perf_counter() - start
    border = border_for(truth.shape[1])
    if encoded:  # scored in 8-bit sRGB, what the user sees
        blurred = scene.read_frame("left", FRAME, linear=False)
        scores = [
            psnr(image, encode8(truth) / 255.0, border=border)
            for image in (encode8(result.image) / 255.0, blurred)
        ]
    elif variant == "sharp-auto":  # against the input: what passing through keeps
        scores = [psnr(result.image, result.blurred, border=border), float("inf")]
    else:
        scores = [psnr(image, truth, border=border) for image in (result.image, result.blurred)]
    return {
        "psnr": scores[0],
        "blurred": scores[1],
        "exposure": result.exposure,
        "truth": 0.0 if variant == "sharp-auto" else original.info.exposure.exposure,
        "alpha": None if result.alpha is None else float(result.alpha),
        "seconds": seconds,
        "warnings": [str(w.message) for w in caught],
    }


def _reused(data: dict, root: Path, variant: str, work: Path) -> dict | None:
    """A run of another tree, its exposure check (with an exposure given) made anew; None for a
    run with the exposure estimated where this code deblurs for another exposure."""
    data = data | {"reused": data.get("reused", data["source"])}
    check = exposure_check(root, variant, work)
    if variant.endswith("auto"):
        return data if check["used"] == data["exposure"] else None
    kept = [w for w in data["warnings"] if "looks too" not in w]
    doubt = check["doubt"]
    return data | {
        "estimate": check["estimate"],
        "doubt": doubt,
        "warnings": kept + ([doubt] if doubt else []),
    }


def exposure_check(root: Path, variant: str, work: Path) -> dict:
    """The frames' estimate of the exposure, the exposure ``--exposure auto`` deblurs for and
    the warning the run of ``variant`` gives, computed as
    :func:`~stereodeblur.pipeline.deblur_frame` does with the defaults."""
    from stereodeblur.pipeline.exposure import estimate_exposure, exposure_doubt
    from stereodeblur.pipeline.motion import view_dense_flow
    from stereodeblur.pipeline.window import read_window, views_read
    from stereodeblur.settings import DeblurSettings

    scene = _variant_scene(root, variant, work)
    settings = DeblurSettings()
    views = views_read(settings, ("left",))
    window = read_window(scene, FRAME, views, settings)
    found = estimate_exposure(window, {v: view_dense_flow(window, v) for v in views})
    doubt = exposure_doubt(window.exposure, found, f"frame {FRAME}")
    used = 0.0 if found.sharp else found.exposure.exposure
    return {"estimate": found.exposure.exposure, "used": used, "doubt": doubt}


def sharp_scene(root: Path, work: Path) -> Path:
    """The scene ``root`` (of the randomised family) rendered again with exposure 0, once."""
    from dataclasses import replace

    from stereodeblur.synth.family import family_scene
    from stereodeblur.synth.scenespec import write_family_scene
    from stereodeblur.synth.street import street_scene

    out = work / "sharp" / root.name
    if not (out / "camera.json").is_file():
        facts = json.loads((root / "gt" / "family.json").read_text(encoding="utf-8"))
        make = family_scene if facts["kind"] == "family" else street_scene
        spec = replace(make(facts["seed"], size=tuple(facts["size"])), duty_cycle=0.0)
        temporary = out.with_name(out.name + ".tmp")
        shutil.rmtree(temporary, ignore_errors=True)
        write_family_scene(spec, temporary)
        temporary.rename(out)
    return out


def is_encoded(variant: str) -> bool:
    """Whether ``variant``'s frames went through the camera (8-bit sRGB, maybe H.264)."""
    return variant.split("-")[0] in ("camera", "h264")


def _variant_scene(root: Path, variant: str, work: Path):
    from stereodeblur.io.scene import open_scene
    from stereodeblur.io.sources import open_source

    if variant == "sharp-auto":
        return open_scene(sharp_scene(root, work))
    if is_encoded(variant):
        return open_scene(camera_scene(root, work, variant.startswith("h264")))
    original = open_scene(root)
    factor = {"linear": 1.0, "auto": 1.0, "x0.5": 0.5, "x2": 2.0}[variant]
    exposure = min(
        factor * original.info.exposure.exposure, 1.0 / original.info.exposure.frame_rate
    )
    return open_source(root, exposure=exposure)


def run_scene(root: Path, facts: dict, work: Path, variants, version: str, reuse: dict) -> dict:
    """Every variant of the scene folder ``root`` (``facts``: its blur and noise), cached;
    ``reuse``: {tree: {variant: reproduced}} of other trees' runs to take (``--reuse``)."""
    cache = work / "camera_results" / root.name
    cache.mkdir(parents=True, exist_ok=True)
    row = {"scene": root.name} | facts
    for variant in variants:
        path = cache / f"{variant}.json"
        data = json.loads(path.read_text()) if path.is_file() else None
        tree = None if data is None else data.get("source")
        if tree != version and tree in reuse:
            if variant not in reuse[tree]:  # reproduce this variant's first run once
                fresh = run_variant(root, variant, work)
                same = fresh["psnr"] == data["psnr"] or abs(fresh["psnr"] - data["psnr"]) <= 0.01
                reuse[tree][variant] = same  # (a frame passed through scores inf twice)
                print(f"{variant}: {root.name} reproduced: {reuse[tree][variant]}", file=sys.stderr)
                data = fresh | {"source": version}
                path.write_text(json.dumps(data, indent=1))
            elif reuse[tree][variant]:
                data = _reused(data, root, variant, work)
                if data is not None:
                    data |= {"source": version}
                    path.write_text(json.dumps(data, indent=1))
        if data is None or data.get("source") != version:
            data = run_variant(root, variant, work) | {"source": version}
            path.write_text(json.dumps(data, indent=1))
        row[variant] = data
        print(
            f"{root.name} {variant}: {data['psnr']:.2f} dB (input {data['blurred']:.2f}) "
            f"{data['seconds']:.1f} s",
            file=sys.stderr,
            flush=True,
        )
    return row


def table(rows, variants) -> list[str]:
    """Per scene, PSNR of the result / of the input; then the means, gains and losses."""
    sharp = "sharp-auto" in variants
    variants = [v for v in variants if v != "sharp-auto"]
    lines = [
        "| scene | blur px | noise | " + " | ".join(variants) + " |",
        "|---|---:|---:|" + "---:|" * len(variants),
    ]
    for row in rows:
        noise = "-" if row["noise"] is None else f"{row['noise']:.3f}"
        cells = [f"{row[v]['psnr']:.2f} / {row[v]['blurred']:.2f}" for v in variants]
        lines.append(f"| {row['scene']} | {row['blur_px']:.1f} | {noise} | {' | '.join(cells)} |")
    lines += ["", "| variant | mean PSNR | mean input | mean gain | worst gain | below input |"]
    lines += ["|---|---:|---:|---:|---:|---:|"]
    for v in variants:
        gains = [row[v]["psnr"] - row[v]["blurred"] for row in rows]
        worst = min(range(len(rows)), key=lambda k: gains[k])
        lines.append(
            f"| {v} | {statistics.mean(row[v]['psnr'] for row in rows):.2f} | "
            f"{statistics.mean(row[v]['blurred'] for row in rows):.2f} | "
            f"{statistics.mean(gains):+.2f} | {gains[worst]:+.2f} ({rows[worst]['scene']}) | "
            f"{sum(g < BELOW for g in gains)} / {len(rows)} |"
        )
    warned = {v: sum(bool(row[v]["warnings"]) for row in rows) for v in variants}
    doubted = {
        v: sum(any("looks too" in w for w in row[v]["warnings"]) for row in rows) for v in variants
    }
    lines += ["", "Frames with a warning: " + ", ".join(f"{v} {n}" for v, n in warned.items())]
    lines += [
        "Of them, the exposure given doubted: "
        + ", ".join(f"{v} {n}" for v, n in doubted.items() if not v.endswith("auto"))
    ]
    blurred = [row for row in rows if row["blur_px"] >= 5]
    for v in (v for v in variants if v.endswith("auto")):
        errors = [row[v]["exposure"] / row[v]["truth"] - 1 for row in blurred]
        within = sum(abs(e) <= 0.2 for e in errors)
        worst = max(errors, key=abs) if errors else float("nan")
        lines.append(
            f"Exposure estimated ({v}): within 20 % of the truth on {within} / {len(blurred)} "
            f"scenes with a longest blur of 5 px or more (worst {worst:+.0%})."
        )
    if sharp:
        scores = [(row["sharp-auto"]["psnr"], row["scene"]) for row in rows]
        still = sum(row["sharp-auto"]["exposure"] == 0 for row in rows)
        lines.append(
            f"Sharp renders (exposure 0), exposure withheld: PSNR against the input 40 dB or "
            f"more on {sum(p >= 40 for p, _ in scores)} / {len(rows)} (passed through: {still}), "
            f"median {statistics.median(p for p, _ in scores):.2f} dB, lowest "
            f"{min(scores)[0]:.2f} dB ({min(scores)[1]})."
        )
    return lines


def report(scenes, clips, args, seconds: float) -> str:
    width, height = args.size
    command = f"python benchmarks/camera_output.py --work DIR --scenes {args.scenes} --skip "
    command += f"{args.skip} --size {width}x{height}"
    command += f" --clips {args.clips}" if clips else ""
    command += f" --reuse {','.join(args.reuse)}" if args.reuse else ""
    lines = [
        f"# The default on camera output and with a wrong exposure, {width}x{height}",
        "",
        f"`{command}`, commit {code_version()}, {time.strftime('%Y-%m-%d')}, "
        f"{seconds / 60:.1f} min (cached runs of the same `src/` reused). Frame {FRAME}, left "
        "view, defaults, estimated motion. PSNR dB of the result / of the blurred input "
        "(linear runs in linear values, camera runs in 8-bit sRGB).",
    ]
    if scenes:
        lines += ["", f"## The calibration protocol's test split, {width}x{height}", ""]
        lines += table(scenes, args.variants)
    if clips:
        lines += ["", "## Semi-real KITTI clips (kitti_semireal.py), 1242x375", ""]
        lines += table(clips, [v for v in args.variants if v != "sharp-auto"])
    reused = [
        r[v]["reused"] for r in scenes + clips for v in args.variants if "reused" in r.get(v, {})
    ]
    if reused:
        lines += [
            "",
            f"{len(reused)} runs were taken from the runs of `src/` tree(s) "
            f"{', '.join(sorted(set(reused)))} (`--reuse`), after this code reproduced each "
            "variant's first scene to 0.01 dB; their exposure check is this code's.",
        ]
    return "\n".join(lines) + "\n"


def clip_rows(folder: Path, variants, work: Path, version: str, reuse: dict) -> list[dict]:
    """The rows of ``kitti_semireal.py``'s clips in its ``--work`` folder ``folder``."""
    rows, variants = [], [v for v in variants if v != "sharp-auto"]  # no renderer of theirs
    for root in sorted(p for p in folder.iterdir() if (p / "gt" / "sharp").is_dir()):
        facts = json.loads((folder / f"{root.name.split('_')[0]}.json").read_text())
        blur = {"blur_px": facts["longest blur (px)"], "noise": None}
        rows.append(run_scene(root, blur, work, variants, version, reuse))
    return rows


def parse(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, required=True, help="scenes and cached runs")
    parser.add_argument("--scenes", type=int, default=40, help="test scenes (0: none)")
    parser.add_argument("--skip", type=int, default=200, help="test scenes skipped first")
    parser.add_argument("--size", default="320x240", help="WxH (default 320x240)")
    parser.add_argument("--clips", type=Path, help="kitti_semireal.py's --work folder")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--output", type=Path)
    parser.add_argument(
        "--reuse",
        default="",
        help="comma-separated src/ trees whose cached runs may be taken once reproduced",
    )
    args = parser.parse_args(argv)
    args.size = tuple(int(v) for v in args.size.lower().split("x"))
    args.variants = tuple(v for v in args.variants.split(",") if v)
    args.reuse = [t for t in args.reuse.split(",") if t]
    unknown = set(args.variants) - set(VARIANTS)
    if unknown:
        parser.error(f"unknown variants {sorted(unknown)}; choose from {VARIANTS}")
    return args


def main(argv=None) -> int:
    args = parse(argv)
    version = code_version("HEAD:src")  # a commit outside src/ keeps the cached runs
    reuse = {tree: {} for tree in args.reuse}
    start = time.perf_counter()
    scenes = []
    for kind, seed in scene_list("test", args.scenes, ("family", "street"), args.skip):
        root = ensure_scene(kind, seed, args.size, args.work)
        spec = json.loads((root / "gt" / "family.json").read_text(encoding="utf-8"))
        facts = {"blur_px": spec["blur_px"], "noise": spec["noise"]}
        scenes.append(run_scene(root, facts, args.work, args.variants, version, reuse))
    clips = clip_rows(args.clips, args.variants, args.work, version, reuse) if args.clips else []
    text = report(scenes, clips, args, time.perf_counter() - start)
    width, height = args.size
    output = args.output or Path(f"benchmarks/results/camera_output_{width}x{height}.md")
    output.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
