"""The range guard's constants, varied on chosen calibration scenes.

Run from the repository root, after ``study_range_guard.py`` (which renders the scenes and
stores their motion in ``--work``)::

    python benchmarks/range_guard_variants.py family_0014:sceneflow family_0001:gt ...

Each argument is ``SCENE:SOURCE`` (``gt``, ``sceneflow`` or ``initial-flow``, the last with the
monocular path's settings). Frame 1 (left) is deblurred from the stored motion without the
guard and with each variant of ``(RANGE_EXCESS, RANGE_WINDOW, RANGE_SHARE, RANGE_AREA[,
RANGE_WHOLE])`` in ``--variants`` (without ``RANGE_WHOLE``: 1, never the whole view); the table
gives PSNR dB and, in brackets, the share of the pixels the guard deblurred with no motion.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import calibrate_defaults as protocol  # noqa: E402

VARIANTS = (
    (0.05, 15, 0.2, 0.0),
    (0.05, 15, 0.2, 0.02),
    (0.05, 31, 0.2, 0.02),
    (0.1, 15, 0.2, 0.02),
    (0.05, 15, 0.1, 0.02),
    (0.05, 15, 0.2, 0.01),
    (0.05, 15, 0.1, 0.01),
    (0.02, 15, 0.2, 0.02),
    (0.05, 15, 0.2, 0.02, 0.3),
    (0.05, 15, 0.2, 0.02, 0.2),
    (0.05, 15, 0.2, 0.02, 0.1),
    (0.05, 15, 0.2, 0.02, 0.05),
)


def run(name: str, source: str, variants, work: Path) -> list[tuple[float, float]]:
    """``(psnr, share)`` without the guard, then with each variant."""
    from stereodeblur import settings as constants
    from stereodeblur.evaluation.metrics import psnr
    from stereodeblur.evaluation.paper_bench import deblur_with_motion
    from stereodeblur.io.scene import open_scene

    scene = open_scene(work / "scenes" / name)
    truth = scene.read_gt_sharp("left", protocol.FRAME)
    border = protocol.border_of(truth.shape[1])
    column = protocol.Column("monocular" if source == "initial-flow" else "default", source)
    motion = protocol.motion_for(scene, column, {}, {}, work / "results" / name)
    out = []
    for variant in (None, *variants):
        if variant is not None:
            (
                constants.RANGE_EXCESS,
                constants.RANGE_WINDOW,
                constants.RANGE_SHARE,
                constants.RANGE_AREA,
                constants.RANGE_WHOLE,
            ) = (*variant, 1.0)[:5]
        settings = replace(column.settings(), range_guard=variant is not None)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = deblur_with_motion(scene, protocol.FRAME, settings, motion)
        share = 0.0 if result.unexplained is None else float(result.unexplained.mean())
        out.append((psnr(result.image, truth, border=border), share))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("pairs", nargs="+", help="SCENE:SOURCE")
    parser.add_argument("--variants", default=json.dumps(VARIANTS), help="JSON list")
    parser.add_argument(
        "--work",
        default=str(Path(tempfile.gettempdir()) / "stereodeblur_calibration" / "320x240"),
        help="calibrate_defaults.py's cache folder of one size (default: its default, 320x240)",
    )
    args = parser.parse_args(argv)
    variants = [tuple(v) for v in json.loads(args.variants)]
    head = ["scene", "motion", "no guard"] + ["/".join(f"{c:g}" for c in v) for v in variants]
    print("| " + " | ".join(head) + " |")
    print("|---|---|" + "---:|" * (len(head) - 2))
    for pair in args.pairs:
        name, source = pair.split(":")
        cells = [f"{p:.2f} ({s:.1%})" for p, s in run(name, source, variants, Path(args.work))]
        print(f"| {name} | {source} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
