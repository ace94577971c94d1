"""Time the IRLS deconvolution (paper defaults: 10 IRLS x 25 CG) at several image sizes.

Run from the repository root::

    python benchmarks/bench_irls.py                 # all sizes, 3 runs each
    python benchmarks/bench_irls.py --runs 5 --sizes 640x480

    python benchmarks/bench_irls.py --plain         # CG products as forward then adjoint
    python benchmarks/bench_irls.py --interpolation bilinear   # the paper's operator

Each size runs in its own subprocess so that the reported peak resident memory
(``resource.getrusage``) belongs to that size alone. Reported per size: the median and
minimum wall time of ``deblur_irls`` over the runs (numba compilation excluded by a
warm-up) and its median CPU time (all threads), the part of the wall time spent inside
the operator's ``forward`` / ``adjoint`` / ``gram`` (the sparse products), the rest (CG
vectors, gradients, weights: the solver's own cost), the median time of one RGB
``forward`` (``A I``) and one RGB ``gram`` (``A^T W^2 A I``, what each CG step uses),
the operator's nonzeros per row, and the peak RSS of the subprocess. ``--plain`` hides
``gram`` from the solver, which then takes a ``forward`` and an ``adjoint`` per CG step.

Operators: ``synthetic`` is a spatially varying motion blur built here with scipy.sparse
(length 5-25 px, slightly tilted from horizontal, bilinear along y, about 30 nonzeros per
row) wrapped in ``SparseBlur``; ``homography`` is the paper's operator for one
fronto-parallel plane under a random rigid motion, with the package's default
interpolation unless ``--interpolation`` says otherwise (cubic; bilinear is the paper's).
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time

import numpy as np
import scipy.sparse as sp

from stereodeblur.settings import DEFAULT_INTERPOLATION, INTERPOLATIONS

SIZES = ((320, 240), (640, 480), (1242, 375))


def synthetic_blur(height: int, width: int, seed: int = 0):
    """Spatially varying linear motion blur as a ``SparseBlur`` (rows sum to one)."""
    from stereodeblur.blur.operator import SparseBlur

    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    phase = rng.uniform(0, 2 * np.pi, 3)
    field = 0.5 + 0.25 * (np.sin(2 * np.pi * xs / width + phase[0]) + np.cos(np.pi * ys / height))
    lengths = (5 + 2 * np.round(field * 10)).astype(np.int64)  # odd, 5 .. 25
    slope = 0.3 * np.sin(2 * np.pi * ys / height + phase[1]) * np.cos(np.pi * xs / width + phase[2])
    half = lengths // 2
    offsets = np.arange(-half.max(), half.max() + 1, dtype=np.float64)
    n = height * width
    rows_all, cols_all, vals_all = [], [], []
    for start in range(0, height, 64):  # bands of rows keep the temporaries small
        band = slice(start, min(start + 64, height))
        inside = np.abs(offsets) <= half[band][..., None]
        px = np.clip(xs[band][..., None] + offsets, 0, width - 1).astype(np.int64)
        py = np.clip(ys[band][..., None] + slope[band][..., None] * offsets, 0, height - 1)
        y0 = np.floor(py).astype(np.int64)
        fy = py - y0
        y1 = np.minimum(y0 + 1, height - 1)
        weight = (1.0 / lengths[band])[..., None]
        row = (ys[band] * width + xs[band]).astype(np.int64)[..., None]
        row = np.broadcast_to(row, inside.shape)
        for yy, ww in ((y0, 1.0 - fy), (y1, fy)):
            rows_all.append(row[inside])
            cols_all.append((yy * width + px)[inside])
            vals_all.append((weight * ww)[inside].astype(np.float32))
    matrix = sp.coo_matrix(
        (np.concatenate(vals_all), (np.concatenate(rows_all), np.concatenate(cols_all))),
        shape=(n, n),
    ).tocsr()
    matrix.eliminate_zeros()
    return SparseBlur(matrix.astype(np.float32), (height, width))


def homography_operator(height: int, width: int, interpolation: str, seed: int = 0):
    """The paper's blur for one fronto-parallel plane under a random rigid motion."""
    from stereodeblur.blur.homography import homography_blur
    from stereodeblur.geometry.camera import Exposure, StereoCamera
    from stereodeblur.sceneflow.model import SceneFlow

    rng = np.random.default_rng(seed)
    focal = 0.9 * width
    K = np.array([[focal, 0, (width - 1) / 2], [0, focal, (height - 1) / 2], [0, 0, 1]])
    camera = StereoCamera(K, 0.5)
    depth = 10.0
    # Translation and rotation giving roughly 10-20 px of motion per frame interval.
    v = rng.uniform(-1, 1, 3) * np.array([15, 8, 2]) * depth / focal
    omega = rng.uniform(-1, 1, 3) * np.array([0.5, 0.5, 2.0]) * 8 / focal
    flow = SceneFlow(
        camera,
        labels=np.zeros((height, width), np.int32),
        normals=np.array([[0.0, 0.0, 1.0 / depth]]),
        twists=np.concatenate([v, omega])[None],
        occlusion=np.zeros((height, width), bool),
    )
    return homography_blur(
        flow, Exposure(frame_rate=25.0, exposure=0.03), interpolation=interpolation
    )


class TimedOperator:
    """Wraps an operator and accumulates the seconds spent in its products."""

    def __init__(self, operator, *, plain: bool = False):
        self.operator = operator
        self.shape = operator.shape
        self.seconds = 0.0
        if not plain:
            self.gram = self._gram

    def _gram(self, image, squared_weights=None):
        start = time.perf_counter()
        out = self.operator.gram(image, squared_weights)
        self.seconds += time.perf_counter() - start
        return out

    def forward(self, image):
        start = time.perf_counter()
        out = self.operator.forward(image)
        self.seconds += time.perf_counter() - start
        return out

    def adjoint(self, image):
        start = time.perf_counter()
        out = self.operator.adjoint(image)
        self.seconds += time.perf_counter() - start
        return out


def natural_image(height: int, width: int) -> np.ndarray:
    from skimage import data, transform

    image = data.astronaut().astype(np.float64) / 255.0
    return transform.resize(image, (height, width, 3), anti_aliasing=True).astype(np.float32)


def product_seconds(function, image, repeats: int = 20) -> float:
    """Median wall time of ``function(image)`` after one warm-up call."""
    function(image)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function(image)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run_one(width: int, height: int, kind: str, runs: int, plain: bool, interpolation: str) -> dict:
    from stereodeblur.deconv import deblur_irls

    start = time.perf_counter()
    if kind == "synthetic":
        operator = synthetic_blur(height, width)
    else:
        operator = homography_operator(height, width, interpolation)
    build_seconds = time.perf_counter() - start
    sharp = natural_image(height, width)
    rng = np.random.default_rng(1)
    blurred = operator.forward(sharp) + rng.normal(0, 0.005, sharp.shape).astype(np.float32)
    blurred = blurred.astype(np.float32)
    # Warm-up: compiles (or loads from cache) the numba kernels, excluded from the timings.
    deblur_irls(blurred[:16, :16], synthetic_blur(16, 16), num_irls=1, num_cg=2)
    totals, cpu, operator_seconds = [], [], []
    for _ in range(runs):
        timed = TimedOperator(operator, plain=plain)
        start, start_cpu = time.perf_counter(), time.process_time()
        result = deblur_irls(blurred, timed)
        totals.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
        operator_seconds.append(timed.seconds)

    def psnr(image):
        return float(10 * np.log10(1.0 / np.mean((np.clip(image, 0, 1) - sharp) ** 2)))

    median = statistics.median(totals)
    median_operator = statistics.median(operator_seconds)
    return {
        "size": f"{width}x{height}",
        "operator": kind,
        "nnz_per_row": operator.matrix.nnz / (width * height),
        "build_s": build_seconds,
        "median_s": median,
        "min_s": min(totals),
        "cpu_s": statistics.median(cpu),
        "runs_s": totals,
        "forward_ms": 1e3 * product_seconds(operator.forward, sharp),
        "gram_ms": 1e3 * product_seconds(operator.gram, sharp),
        "operator_s": median_operator,
        "own_s": median - median_operator,
        "psnr_blurred": psnr(blurred),
        "psnr_deblurred": psnr(result.image),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per size (default %(default)s)")
    parser.add_argument(
        "--sizes",
        nargs="*",
        default=[f"{w}x{h}" for w, h in SIZES],
        help="WIDTHxHEIGHT ... (default: %(default)s)",
    )
    parser.add_argument(
        "--operators",
        nargs="*",
        default=["synthetic", "homography"],
        help="synthetic and/or homography (default: both)",
    )
    parser.add_argument("--plain", action="store_true", help="forward then adjoint, no gram")
    parser.add_argument(
        "--interpolation",
        choices=INTERPOLATIONS,
        default=DEFAULT_INTERPOLATION,
        help="of the homography operator (the synthetic one is bilinear)",
    )
    parser.add_argument("--single", nargs=2, metavar=("SIZE", "OPERATOR"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.single:
        width, height = (int(v) for v in args.single[0].split("x"))
        row = run_one(width, height, args.single[1], args.runs, args.plain, args.interpolation)
        print(json.dumps(row))
        return
    header = (
        f"{'size':>9} {'operator':>10} {'nnz/row':>7} {'median s':>8} {'min s':>6} "
        f"{'CPU s':>6} {'in A s':>7} {'own s':>6} {'A ms':>5} {'gram ms':>7} "
        f"{'PSNR in':>7} {'PSNR out':>8} {'RSS MB':>7}"
    )
    print(f"homography operator: {args.interpolation} interpolation")
    print(header)
    for size in args.sizes:
        for kind in args.operators:
            output = subprocess.run(
                [sys.executable, __file__, "--single", size, kind, "--runs", str(args.runs)]
                + ["--interpolation", args.interpolation]
                + (["--plain"] if args.plain else []),
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            row = json.loads(output.strip().splitlines()[-1])
            print(
                f"{row['size']:>9} {row['operator']:>10} {row['nnz_per_row']:7.1f} "
                f"{row['median_s']:8.2f} {row['min_s']:6.2f} {row['cpu_s']:6.2f} "
                f"{row['operator_s']:7.2f} {row['own_s']:6.2f} "
                f"{row['forward_ms']:5.1f} {row['gram_ms']:7.1f} "
                f"{row['psnr_blurred']:7.2f} {row['psnr_deblurred']:8.2f} "
                f"{row['peak_rss_mb']:7.0f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
