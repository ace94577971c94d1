"""The homography-induced operator against independent constructions of paper Eq. 3-4."""

import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.blur.homography import homography_blur, homography_blur_reference
from stereodeblur.geometry import move_plane, se3_exp

from .scenes import EXPOSURE, random_sceneflow, translation_sceneflow

SHAPE = (40, 56)


@pytest.mark.parametrize("view", ["left", "right"])
@pytest.mark.parametrize("seed", [0, 1])
def test_sparse_equals_numpy_reference(view, seed):
    scene = random_sceneflow(SHAPE, seed, view=view, grid=(3, 4), speed=2.0)
    fast = homography_blur(scene, EXPOSURE, interpolation="bilinear").matrix
    slow = homography_blur_reference(scene, EXPOSURE, interpolation="bilinear").matrix
    np.testing.assert_array_equal(fast.indptr, slow.indptr)
    np.testing.assert_array_equal(fast.indices, slow.indices)
    np.testing.assert_allclose(fast.data, slow.data, rtol=0, atol=1e-6)


def test_reference_covers_positions_outside_the_image():
    """Content entering from outside: many samples of the fast path were clamped."""
    scene = translation_sceneflow(SHAPE, (1.5, -1.0))
    fast = homography_blur(scene, EXPOSURE, num_samples=9).matrix
    slow = homography_blur_reference(scene, EXPOSURE, num_samples=9).matrix
    assert abs(fast - slow).max() < 1e-6
    # Content moves right by ~9 px over the exposure: in the first half of it, blurred
    # column 0 shows content from outside, i.e. (border rule) the sharp edge column 0.
    rows = fast[np.arange(5, SHAPE[0] - 5) * SHAPE[1]].tocoo()
    on_edge = np.bincount(rows.row, weights=rows.data * (rows.col % SHAPE[1] == 0))
    np.testing.assert_allclose(on_edge, 5 / 9, atol=1e-6)  # 5 of 9 instants have s <= 0


@pytest.mark.parametrize(
    "velocity, offset",
    [
        ((0.3, 0.0), 0.0),
        ((0.2, -0.25), 0.0),
        ((-0.35, 0.1), 0.0),
        ((0.1, 0.05), 1.0),
        ((-0.08, 0.1), -1.0),
    ],
)
def test_fronto_parallel_translation_matches_ndimage_shift(velocity, offset):
    """``offset``: the exposure of the frame that many intervals away, from this sharp frame."""
    depth = 3.0
    scene = translation_sceneflow(SHAPE, velocity, depth)
    num_samples = 15
    op = homography_blur(
        scene, EXPOSURE, num_samples=num_samples, offset=offset, interpolation="bilinear"
    )
    image = np.random.default_rng(0).random(SHAPE)
    focal = scene.camera.K[[0, 1], [0, 1]]
    expected = np.zeros(SHAPE)
    for s in offset + EXPOSURE.sample_fractions(num_samples):
        dx, dy = s * focal * np.asarray(velocity) / depth  # content moves by (dx, dy)
        expected += ndimage.shift(image, (dy, dx), order=1, mode="nearest")
    expected /= num_samples
    span = abs(offset) + EXPOSURE.duty_cycle / 2
    reach = int(np.ceil(span * np.abs(focal * velocity / depth).max())) + 1
    inner = (slice(reach, -reach), slice(reach, -reach))
    blurred = op.forward(image)
    np.testing.assert_allclose(blurred[inner], expected[inner], atol=2e-6)
    assert np.abs(blurred - image)[inner].mean() > 0.05  # it does blur


def _tracked_reference_positions(scene, fractions):
    """For every pixel x and instant s: the reference pixel whose 3D point is seen at x at s.

    Independent of the homographies: intersect x's ray with the moved plane, move the
    point back to the reference instant and project it into the same view.
    """
    cam = scene.camera
    center = cam.center(scene.view)
    H, W = scene.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    rays = np.stack([x, y, np.ones_like(x)], -1) @ cam.K_inv.T
    out = np.empty((len(fractions), H, W, 2))
    for i, s in enumerate(fractions):
        points = np.empty((H, W, 3))
        for label in range(scene.num_segments):
            M = se3_exp(s * scene.twists[label])
            R, T = M[:3, :3], M[:3, 3]
            n_t = move_plane(scene.normals[label], R, T)  # left coordinates, instant s
            mask = scene.labels == label
            # Points c + d * ray with (c + d * ray)^T n_t = 1.
            d = (1.0 - center @ n_t) / (rays[mask] @ n_t)
            P_t = center + d[:, None] * rays[mask]
            points[mask] = (P_t - T) @ R  # R^T (P_t - T)
        out[i] = cam.project(points, scene.view)
    return out


@pytest.mark.parametrize("view", ["left", "right"])
def test_rows_follow_projected_3d_trajectories(view):
    """A ramp image is interpolated exactly, so blurring it averages the tracked positions."""
    scene = random_sceneflow(SHAPE, 5, view=view, grid=(2, 2), speed=1.5)
    num_samples = 12
    fractions = EXPOSURE.sample_fractions(num_samples)
    tracked = _tracked_reference_positions(scene, fractions)
    y, x = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]].astype(np.float64)
    ramp = np.stack([x, y], axis=-1)  # channel 0: x, channel 1: y
    blurred = homography_blur(
        scene, EXPOSURE, num_samples=num_samples, interpolation="bilinear"
    ).forward(ramp)
    expected = tracked.mean(axis=0)
    inside = np.all((tracked >= 0) & (tracked <= [SHAPE[1] - 1, SHAPE[0] - 1]), axis=(0, 3))
    assert inside.mean() > 0.6
    np.testing.assert_allclose(blurred[inside], expected[inside], atol=1e-3)
    moved = np.abs(tracked[-1] - tracked[0]).max(axis=-1)
    assert np.median(moved[inside]) > 1.0  # trajectories are pixels long


@pytest.mark.parametrize("num_samples", [0, -3, 2.5, True])
def test_bad_num_samples(num_samples):
    scene = random_sceneflow(SHAPE, 0)
    with pytest.raises(ValueError, match="num_samples"):
        homography_blur(scene, EXPOSURE, num_samples=num_samples)


@pytest.mark.parametrize("seed, offset", [(0, 0.0), (1, 0.0), (2, 1.0), (3, -1.0)])
def test_cubic_sparse_equals_numpy_reference(seed, offset):
    scene = random_sceneflow(SHAPE, seed, grid=(3, 4), speed=2.0)
    fast = homography_blur(scene, EXPOSURE, interpolation="cubic", offset=offset).matrix
    slow = homography_blur_reference(scene, EXPOSURE, interpolation="cubic", offset=offset).matrix
    np.testing.assert_array_equal(fast.indptr, slow.indptr)
    np.testing.assert_array_equal(fast.indices, slow.indices)
    np.testing.assert_allclose(fast.data, slow.data, rtol=0, atol=1e-6)
    np.testing.assert_allclose(fast.sum(axis=1), 1.0, atol=1e-5)
    assert fast.nnz > 1.5 * homography_blur(scene, EXPOSURE, interpolation="bilinear").matrix.nnz


def test_cubic_huge_blur_takes_the_sorted_path():
    """Trajectories whose bounding box exceeds the accumulator: the sorted fallback."""
    scene = random_sceneflow((300, 320), 3, grid=(1, 1), speed=400.0)
    fast = homography_blur(scene, EXPOSURE, num_samples=7, interpolation="cubic").matrix
    slow = homography_blur_reference(scene, EXPOSURE, num_samples=7, interpolation="cubic").matrix
    assert abs(fast - slow).max() < 1e-6


@pytest.mark.parametrize("velocity", [(0.3, 0.0), (0.2, -0.25)])
def test_cubic_fronto_parallel_translation_matches_cubic_convolution(velocity):
    """Cubic kernels interpolate like Keys' cubic convolution of the shifted image."""
    from stereodeblur.blur.trajectories import keys_weights

    scene = translation_sceneflow(SHAPE, velocity, 3.0)
    num_samples = 15
    op = homography_blur(scene, EXPOSURE, num_samples=num_samples, interpolation="cubic")
    image = np.random.default_rng(0).random(SHAPE)
    focal = scene.camera.K[[0, 1], [0, 1]]
    padded = np.pad(image, 2, mode="edge")
    expected = np.zeros(SHAPE)
    for s in EXPOSURE.sample_fractions(num_samples):
        dx, dy = s * focal * np.asarray(velocity) / 3.0  # content moves by (dx, dy)
        ix, fx = int(np.floor(-dx)), -dx - np.floor(-dx)
        iy, fy = int(np.floor(-dy)), -dy - np.floor(-dy)
        for ty in range(-1, 3):
            for tx in range(-1, 3):
                w = keys_weights(np.array(fy - ty)) * keys_weights(np.array(fx - tx))
                rows = np.clip(np.arange(SHAPE[0]) + iy + ty, -2, SHAPE[0] + 1) + 2
                cols = np.clip(np.arange(SHAPE[1]) + ix + tx, -2, SHAPE[1] + 1) + 2
                expected += w * padded[np.ix_(rows, cols)]
    expected /= num_samples
    reach = int(np.ceil(EXPOSURE.duty_cycle / 2 * np.abs(focal * velocity / 3.0).max())) + 3
    inner = (slice(reach, -reach), slice(reach, -reach))
    np.testing.assert_allclose(op.forward(image)[inner], expected[inner], atol=2e-5)


def test_bad_interpolation():
    with pytest.raises(ValueError, match="interpolation"):
        homography_blur(random_sceneflow(SHAPE, 0), EXPOSURE, interpolation="nearest")


def test_cubic_operator_passes_the_dot_test():
    from stereodeblur.blur.operator import dot_test

    op = homography_blur(random_sceneflow(SHAPE, 2, speed=2.0), EXPOSURE, interpolation="cubic")
    assert (op.matrix.data < 0).any()  # Keys' lobes
    assert dot_test(op, SHAPE + (3,), seed=1) < 1e-6
