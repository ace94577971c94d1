"""A frame-level fallback on the exposure check's doubt, from ``camera_output.py``'s cached runs
(a study: it changes no default).

    python benchmarks/study_exposure_fallback.py WORK

``WORK``: ``camera_output.py``'s ``--work`` folder, its runs of this ``src/`` tree. For the
exposure given true, halved and doubled (``linear``, ``x0.5``, ``x2``): the mean gain over the
blurred input, the scenes more than 0.5 dB below it and the worst, when a frame whose given
exposure the check doubts is deblurred as given (the default), passed through, or deblurred for
the frames' estimate (the ``auto`` run of the scene).
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

POLICIES = ("as given", "passed through", "the estimate")


def doubted(run: dict) -> bool:
    return any("looks too" in w for w in run["warnings"])


def gain(run: dict, auto: dict, policy: str) -> float:
    if not doubted(run) or policy == "as given":
        return run["psnr"] - run["blurred"]
    return 0.0 if policy == "passed through" else auto["psnr"] - auto["blurred"]


def main() -> None:
    results = Path(sys.argv[1]) / "camera_results"
    scenes = sorted(
        p for p in results.iterdir() if (p / "x2.json").is_file() and p.name[0].isalpha()
    )
    runs = {
        p.name: {
            v: json.loads((p / f"{v}.json").read_text()) for v in ("linear", "auto", "x0.5", "x2")
        }
        for p in scenes
    }
    print("| doubted frame | " + " | ".join(("true", "half", "twice")) + " |")
    print("|---|---:|---:|---:|")
    for policy in POLICIES:
        cells = []
        for variant in ("linear", "x0.5", "x2"):
            gains = [gain(r[variant], r["auto"], policy) for r in runs.values()]
            below = sum(g < -0.5 for g in gains)
            cells.append(
                f"{statistics.mean(gains):+.2f} dB ({below} below -0.5, worst {min(gains):+.2f})"
            )
        print(f"| {policy} | " + " | ".join(cells) + " |")
    print(
        "doubted:",
        {v: sum(doubted(r[v]) for r in runs.values()) for v in ("linear", "x0.5", "x2")},
    )


if __name__ == "__main__":
    main()
