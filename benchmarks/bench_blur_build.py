"""Time the assembly and application of both blur operators.

For each image size a random but realistic scene flow is drawn (seeded): a
camera moving forward with a little yaw and pitch over ~1200 planar segments
per 640x480 (scaled with the area, Voronoi cells of random seeds), depths 3 to
30, and a fifth of the segments moving independently. Exposure: 25 fps, 20 ms
(duty cycle 0.5), ``N = 70`` instants, the package's default interpolation unless
``--interpolation`` says otherwise (cubic; bilinear is the paper's and has 2.4-2.7x fewer
entries). The displacement operator uses the
scene flow's 2D flow forward and backward; "layered" is the occlusion-aware homography
operator, the segment each pixel shows at each instant included in its build.

Numba compilation is excluded from the timings (one warm-up build) and
reported separately. Each operator is then built ``--repeats`` times; the
script prints the median build time, nnz, matrix memory (CSR of A and of A^T),
the peak memory one build adds (resident memory sampled every millisecond
during the build, minus the memory before it), the median time of one forward and one adjoint on an
RGB float32 image (numba kernels, and scipy's SpMV for comparison), of one Gram product
``A^T W^2 A`` (``SparseBlur.gram``, what every CG step of the deconvolution takes), and
the peak resident memory of the whole process so far. Float32 products use the tiled
format (``stereodeblur.blur._tiled``: tiles of 16 rows sharing their column offsets, of
``A`` and ``A^T``, built on the first float32 product): the script reports their size,
their entries against the CSR's and their build time.

The memory-bandwidth floor: the script first measures this machine's streaming bandwidth
(a triad ``a = b + s c`` and a plain read over 64 MiB arrays, on all numba threads; the
best of several runs), then for every operator the shortest time to just read its CSR
arrays once on those threads, and to read the tiles of ``A`` once: no product that reads
the matrix once can be faster.

Run: ``python benchmarks/bench_blur_build.py [--sizes 320x240 640x480 1242x375]
[--interpolation bilinear|cubic]``
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import resource
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from itertools import pairwise

import numba
import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from stereodeblur.blur.displacement import displacement_blur
from stereodeblur.blur.homography import homography_blur
from stereodeblur.blur.visibility import sceneflow_visibility
from stereodeblur.geometry.camera import Exposure, StereoCamera
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.settings import DEFAULT_INTERPOLATION, INTERPOLATIONS

EXPOSURE = Exposure(frame_rate=25.0, exposure=0.02)
NUM_SAMPLES = 70
SEGMENTS_PER_PIXEL = 1200 / (640 * 480)


def random_scene(height: int, width: int, seed: int = 0) -> SceneFlow:
    """A seeded, realistic piecewise-rigid scene flow over an image of this size."""
    rng = np.random.default_rng(seed)
    f = 0.85 * max(height, width)
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
    camera = StereoCamera(K, baseline=0.54)
    num_segments = max(1, round(SEGMENTS_PER_PIXEL * height * width))
    seeds = rng.uniform([0, 0], [width, height], size=(num_segments, 2))
    y, x = np.mgrid[0:height, 0:width]
    _, labels = cKDTree(seeds).query(np.column_stack([x.ravel(), y.ravel()]))
    labels = labels.reshape(height, width).astype(np.int32)
    depth = rng.uniform(3.0, 30.0, num_segments)
    tilt = rng.uniform(-0.3, 0.3, (num_segments, 2))
    normals = np.column_stack([tilt, np.ones(num_segments)]) / depth[:, None]
    ego = np.array([0.05, 0.02, -1.0, 0.002, 0.01, 0.003])  # camera moves forward
    twists = np.tile(ego, (num_segments, 1))
    movers = rng.random(num_segments) < 0.2
    twists[movers, :3] += rng.normal(0, 0.5, (movers.sum(), 3))
    twists[movers, 3:] += rng.normal(0, 0.02, (movers.sum(), 3))
    return SceneFlow(camera, labels, normals, twists, np.zeros((height, width), bool))


def layered_blur(scene: SceneFlow, *, interpolation: str):
    """The occlusion-aware operator, with the visibility it needs."""
    visible = sceneflow_visibility(scene, EXPOSURE, NUM_SAMPLES)
    return homography_blur(
        scene, EXPOSURE, num_samples=NUM_SAMPLES, visible=visible, interpolation=interpolation
    )


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (``getrusage``), MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def current_rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * resource.getpagesize() / 2**20


def build_peak_mb(build) -> float:
    """Peak memory one build adds over the memory before it, sampled every millisecond.

    Freed memory is first handed back to the system (glibc ``malloc_trim``) so that
    the build cannot hide in memory the allocator kept from earlier builds.
    """
    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    before = current_rss_mb()
    peak = before
    done = threading.Event()

    def sample():
        nonlocal peak
        while not done.is_set():
            peak = max(peak, current_rss_mb())
            time.sleep(0.001)

    sampler = threading.Thread(target=sample)
    sampler.start()
    result = build()
    peak = max(peak, current_rss_mb())
    done.set()
    sampler.join()
    del result
    return peak - before


def timed(fn, repeats: int) -> tuple[float, object]:
    """Median wall time of ``fn()`` and its last result (earlier results are freed first)."""
    times = []
    result = None
    for _ in range(repeats):
        result = None
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), result


@njit(nogil=True, fastmath=True, cache=True)
def _read(indices, data):
    """Sum of ``data + indices``: one streaming read of both (vectorised)."""
    total = 0.0
    count = 0
    for k in range(data.size):
        total += data[k]
        count += indices[k]
    return total + count


@njit(nogil=True, fastmath=True, cache=True)
def _triad(a, b, c):
    for k in range(a.size):
        a[k] = b[k] + np.float32(0.5) * c[k]


_POOL = ThreadPoolExecutor(numba.get_num_threads())


def _on_threads(function, *arrays) -> None:
    """``function(*pieces)`` on equal contiguous pieces of ``arrays``, one piece per thread."""
    bounds = np.linspace(0, arrays[0].size, _POOL._max_workers + 1).astype(np.int64)
    futures = [_POOL.submit(function, *(x[a:b] for x in arrays)) for a, b in pairwise(bounds)]
    for future in futures:
        future.result()


def fastest(fn, repeats: int) -> float:
    """Shortest wall time of ``fn()`` over ``repeats`` calls: a floor is a best case."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bandwidth_gb_s(repeats: int) -> tuple[float, float]:
    """Best streaming bandwidth (triad, read) in GB/s over 64 MiB float32 arrays, all threads."""
    n = 1 << 24
    a, b, c = (np.full(n, v, np.float32) for v in (0.0, 1.0, 2.0))
    ints = np.ones(n, np.int32)
    _triad(a[:1], b[:1], c[:1]), _read(ints[:1], b[:1])  # compile first
    triad = fastest(lambda: _on_threads(_triad, a, b, c), 4 * repeats)
    read = fastest(lambda: _on_threads(_read, ints, b), 4 * repeats)
    return 3 * a.nbytes / triad / 1e9, 2 * b.nbytes / read / 1e9


def stream_seconds(op, repeats: int) -> tuple[float, float]:
    """Shortest times to read once, on all threads, ``op``'s CSR arrays and the tiles of
    ``A`` that a float32 product reads (values and starts)."""
    m = op.matrix
    _on_threads(_read, m.indices, m.data)  # warm-up
    csr = fastest(lambda: _on_threads(_read, m.indices, m.data), 4 * repeats)
    tiles = op._tiled()[0]
    values, starts = tiles.values.ravel(), tiles.starts.view(np.int64)
    _on_threads(_read, starts, starts)  # warm-up (compiles the int64 version)
    tiled = fastest(lambda: _on_threads(_read, values.view(np.int32), values), 4 * repeats)
    tiled += fastest(lambda: _on_threads(_read, starts, starts), 4 * repeats)
    return csr, tiled


def matrix_mb(op) -> tuple[float, float]:
    """MB of the CSR arrays of ``A`` and of the tiles of ``A`` and ``A^T``."""
    m = op.matrix
    csr = m.data.nbytes + m.indices.nbytes + m.indptr.nbytes
    return csr / 2**20, sum(t.nbytes for t in op._tiled()) / 2**20


def apply_times(op, image: np.ndarray, repeats: int) -> dict[str, float]:
    """Median seconds of one forward and one adjoint: numba kernels, and scipy's SpMV."""
    flat = image.reshape(-1, image.shape[2])
    A, At = op.matrix, op._transposed()
    squared = np.random.default_rng(2).uniform(0, 1, op.shape).astype(np.float32)
    csr, tiled = stream_seconds(op, repeats)
    return {
        "stream csr": csr,
        "stream tiles": tiled,
        "gram": timed(lambda: op.gram(image, squared), repeats)[0],
        "forward": timed(lambda: op.forward(image), repeats)[0],
        "adjoint": timed(lambda: op.adjoint(image), repeats)[0],
        "scipy forward": timed(lambda: A @ flat, repeats)[0],
        "scipy adjoint": timed(lambda: At @ flat, repeats)[0],
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sizes",
        nargs="+",
        default=["320x240", "640x480", "1242x375"],
        help="image sizes WIDTHxHEIGHT",
    )
    parser.add_argument(
        "--repeats", type=int, default=5, help="builds per operator (default %(default)s)"
    )
    parser.add_argument(
        "--interpolation",
        choices=INTERPOLATIONS,
        default=DEFAULT_INTERPOLATION,
        help="kernel sampling (default %(default)s, the package's; bilinear is the paper's)",
    )
    args = parser.parse_args(argv)
    sampling = {"num_samples": NUM_SAMPLES, "interpolation": args.interpolation}

    print(
        f"exposure duty cycle {EXPOSURE.duty_cycle}, N = {NUM_SAMPLES}, "
        f"{args.interpolation} interpolation, "
        f"repeats {args.repeats} (median)"
    )
    triad, read = bandwidth_gb_s(args.repeats)
    print(
        f"streaming bandwidth, {numba.get_num_threads()} threads: "
        f"triad {triad:.1f} GB/s, read {read:.1f} GB/s"
    )
    compiled = False
    for size in args.sizes:
        width, height = (int(v) for v in size.lower().split("x"))
        scene = random_scene(height, width)
        flow_forward = scene.flow()
        flow_backward = scene.reversed().flow()
        length = np.linalg.norm(flow_forward, axis=-1) * EXPOSURE.duty_cycle
        image = np.random.default_rng(1).random((height, width, 3), dtype=np.float32)
        builders = {
            "homography": partial(homography_blur, scene, EXPOSURE, **sampling),
            "displacement": partial(
                displacement_blur, flow_forward, flow_backward, EXPOSURE, **sampling
            ),
            "layered": partial(layered_blur, scene, interpolation=args.interpolation),
        }
        print(
            f"\n{width}x{height}: {scene.num_segments} segments, blur length px "
            f"median {np.median(length):.1f}, 95% {np.percentile(length, 95):.1f}, "
            f"max {length.max():.1f}"
        )
        for name, build in builders.items():
            t0 = time.perf_counter()
            op = build()
            op.adjoint(op.forward(image))
            first = time.perf_counter() - t0
            if not compiled:
                print(
                    f"  first call (numba compile or cache load + build + apply) "
                    f"{name}: {first:.2f} s"
                )
            build_time, op = timed(build, args.repeats)
            tile_time, _ = timed(lambda op=op: type(op)(op.matrix, op.shape)._tiled(), 3)
            ms = {k: 1e3 * v for k, v in apply_times(op, image, 4 * args.repeats).items()}
            csr_mb, tiles_mb = matrix_mb(op)
            tiled_entries = sum(t.values.size for t in op._tiled()) / 2 / op.matrix.nnz
            print(
                f"  {name:12s} build {build_time:6.3f} s   nnz {op.matrix.nnz / 1e6:6.2f} M "
                f"({op.matrix.nnz / op.matrix.shape[0]:4.1f}/row)   CSR A {csr_mb:6.1f} MB"
                f"   build peak +{build_peak_mb(build):5.0f} MB\n"
                f"  {'':12s} tiles of A and A^T: {tiles_mb:6.1f} MB, {tiled_entries:4.2f}x the "
                f"entries, built in {1e3 * tile_time:5.1f} ms (on first float32 product)\n"
                f"  {'':12s} RGB float32: forward {ms['forward']:5.1f} ms, adjoint "
                f"{ms['adjoint']:5.1f} ms (scipy {ms['scipy forward']:5.1f} / "
                f"{ms['scipy adjoint']:5.1f} ms), gram {ms['gram']:5.1f} ms; reading once: "
                f"the CSR of A {ms['stream csr']:5.1f} ms, the tiles of A {ms['stream tiles']:5.1f}"
                f" ms   process peak RSS {peak_rss_mb():5.0f} MB"
            )
            del op
        compiled = True


if __name__ == "__main__":
    main()
