"""How short an estimated blur reads as sharp frames (a study for ``SHARP_BLUR``).

    python benchmarks/study_sharp_frames.py --blurred DIR --sharp DIR [--kitti DIR]

For every scene folder in ``--blurred`` (rendered with their exposure) and ``--sharp`` (the
same scenes rendered with exposure 0, ``camera_output.sharp_scene``): the exposure estimate of
frame 1 as ``deblur --exposure auto`` makes it, and the blur it gives the median moving window.
Then, per threshold, the sharp scenes passed through and the blurred ones passed through with an
estimate within 20 % of the truth or a worse one. ``--kitti``: a KITTI 2015 ``training`` folder,
whose frame pairs (``_10``, ``_11``) are sharp.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from stereodeblur.io import open_scene
from stereodeblur.io.kitti import open_kitti
from stereodeblur.pipeline.exposure import estimate_exposure
from stereodeblur.pipeline.motion import view_dense_flow
from stereodeblur.pipeline.window import read_window, views_read
from stereodeblur.settings import DeblurSettings

THRESHOLDS = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5)


def estimate(scene, index: int):
    """The duty cycle, the true one (None if unknown) and the blur of frame ``index``."""
    settings = DeblurSettings()
    views = views_read(settings, ("left",))
    window = read_window(scene, index, views, settings)
    found = estimate_exposure(window, {v: view_dense_flow(window, v) for v in views})
    return found.exposure.duty_cycle, window.exposure.duty_cycle, found.blur


def folder_rows(folder: Path) -> list[tuple]:
    rows = []
    for root in sorted(p for p in folder.iterdir() if (p / "camera.json").is_file()):
        duty, truth, blur = estimate(open_scene(root), 1)
        rows.append((root.name, duty, truth, blur))
        print(f"{root.name}: duty {duty:.2f} (truth {truth:.2f}), blur {blur:.1f} px", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blurred", type=Path, required=True)
    parser.add_argument("--sharp", type=Path, required=True)
    parser.add_argument("--kitti", type=Path)
    args = parser.parse_args()
    blurred, sharp = folder_rows(args.blurred), folder_rows(args.sharp)
    print(f"| blur under | sharp passed through ({len(sharp)}) | blurred: within 20 % / worse |")
    print("|---|---:|---:|")
    print(f"| (an estimate of 0) | {sum(r[1] == 0 for r in sharp)} | 0 / 0 |")
    for t in THRESHOLDS:
        gated = [r for r in blurred if 0 < r[3] < t]
        good = sum(abs(r[1] / r[2] - 1) <= 0.2 for r in gated)
        passed = sum(r[3] < t for r in sharp)
        print(f"| {t:g} px | {passed} | {good} / {len(gated) - good} |")
    if args.kitti:
        numbers = sorted({p.name.split("_")[0] for p in (args.kitti / "image_2").glob("*_10.png")})
        for number in numbers:
            source = open_kitti(
                args.kitti, kind="kitti-2015", sequence=int(number), require_exposure=False
            )
            duty, _, blur = estimate(source, 0)
            print(f"KITTI {number}: duty {duty:.2f}, blur {blur:.1f} px")


if __name__ == "__main__":
    main()
