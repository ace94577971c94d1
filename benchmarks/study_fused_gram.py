"""Study: a gram that reads A's tiles once (gather, weight, scatter). Not adopted.

    python benchmarks/study_fused_gram.py --work DIR

The left view's operator of ``bench_stereo_frame.py``'s 640x480 ``spheres`` frame (default
settings, estimated scene flow); medians of 15 products of today's gram (A's tiles, then A^T's)
and of the fused one, on one thread and on all, and the largest relative difference.
"""

import argparse
import time
import warnings
from pathlib import Path

import numba
import numpy as np
from bench_stereo_frame import render

from stereodeblur._threads import run_ranges
from stereodeblur.blur._tiled import _FAST, TILE, from_planar, to_planar


@numba.njit(**_FAST)
def _gram_tiles3(first, last, tile_ptr, starts, values, planes, scale, out, tile):
    acc = np.zeros((3, 16), np.float32)
    tile = np.uint64(tile)
    for t in range(first, last):
        a = np.uint64(t) * tile
        acc[:] = 0.0
        k0, k1 = np.uint64(tile_ptr[t]), np.uint64(tile_ptr[t + 1])
        for k in range(k0, k1):
            s, v = a + starts[k], values[k]
            for c in range(3):
                for j in range(tile):
                    acc[c, j] += v[j] * planes[c, s + j]
        for j in range(tile):
            w = scale[a + j] if a + j < scale.size else np.float32(0.0)
            for c in range(3):
                acc[c, j] *= w
        for k in range(k0, k1):
            s, v = a + starts[k], values[k]
            for c in range(3):
                for j in range(tile):
                    out[c, s + j] += v[j] * acc[c, j]


def fused_gram(tiles, flat, squared):
    """``A^T W^2 A x`` from A's tiles alone; ranges whose writes cannot overlap run together."""
    planes = to_planar(flat, tiles.margin)
    out = np.zeros((3, tiles.padded_rows + 2 * tiles.margin), np.float32)
    need = (2 * tiles.margin + 2 * TILE) // TILE + 1
    parts = max(1, min(16, tiles.num_tiles // need))
    bounds = np.linspace(0, tiles.num_tiles, parts + 1).round().astype(int)
    ranges = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    for phase in (ranges[0::2], ranges[1::2]):
        if phase:
            args = (tiles.tile_ptr, tiles.starts, tiles.values, planes, squared, out, TILE)
            run_ranges(_gram_tiles3, phase, *args)
    return from_planar(out[:, tiles.margin :], tiles.num_rows)


def median_ms(function, repeats=15) -> float:
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def main() -> None:
    from stereodeblur.io.scene import open_scene
    from stereodeblur.pipeline.frame import build_view_operator
    from stereodeblur.pipeline.motion import stereo_motion
    from stereodeblur.pipeline.window import read_window
    from stereodeblur.settings import DeblurSettings

    parser = argparse.ArgumentParser()
    parser.add_argument("--work", type=Path, required=True)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    settings = DeblurSettings()
    scene = open_scene(render(args.work, "spheres", (640, 480)))
    window = read_window(scene, 1, ("left", "right"), settings)
    motion = stereo_motion(scene, window, ("left", "right"), settings)
    blur = build_view_operator(window, motion.views["left"], settings).operator
    image = window.blurred("left").astype(np.float32)
    squared = np.random.default_rng(0).uniform(0.2, 1.0, image.shape[:2]).astype(np.float32)
    tiles = blur._tiled()[0]
    flat = image.reshape(-1, 3)
    today = blur.gram(image, squared).reshape(-1, 3)
    fused = fused_gram(tiles, flat, squared.ravel())
    print(f"nonzeros {blur.matrix.nnz}, margin {tiles.margin} px")
    print(f"largest relative difference {np.abs(fused - today).max() / np.abs(today).max():.1e}")
    for threads in (1, numba.config.NUMBA_NUM_THREADS):
        numba.set_num_threads(threads)
        now = median_ms(lambda: blur.gram(image, squared))
        once = median_ms(lambda: fused_gram(tiles, flat, squared.ravel()))
        print(f"{threads} thread(s): today's gram {now:.1f} ms, fused {once:.1f} ms")


if __name__ == "__main__":
    main()
