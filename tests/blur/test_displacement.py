"""The 2D-displacement (Kim & Lee) operator against independent constructions."""

import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.blur.displacement import (
    MIN_COVERAGE,
    displacement_blur,
    displacement_blur_reference,
)
from stereodeblur.blur.homography import homography_blur
from stereodeblur.errors import InputError

from .scenes import EXPOSURE, smooth_flow, translation_sceneflow

SHAPE = (40, 56)


@pytest.mark.parametrize(
    ("seed", "interpolation"), [(0, "bilinear"), (1, "bilinear"), (2, "bilinear"), (3, "cubic")]
)
def test_sparse_equals_numpy_reference(seed, interpolation):
    forward = smooth_flow(SHAPE, seed, amplitude=10.0)
    backward = smooth_flow(SHAPE, seed + 50, amplitude=10.0)
    fast = displacement_blur(forward, backward, EXPOSURE, interpolation=interpolation).matrix
    slow = displacement_blur_reference(
        forward, backward, EXPOSURE, interpolation=interpolation
    ).matrix
    np.testing.assert_array_equal(fast.indptr, slow.indptr)
    np.testing.assert_array_equal(fast.indices, slow.indices)
    np.testing.assert_allclose(fast.data, slow.data, rtol=0, atol=1e-6)


def test_a_degenerate_flow_gives_a_normalised_operator():
    # Flows of millions of pixels on the border (found with an estimated scene flow) once
    # made a grid of terabytes; beyond the image's size the grid stops.
    forward = smooth_flow(SHAPE, 4, amplitude=5.0)
    forward[:10, -12:] = (3e6, -1e6)
    op = displacement_blur(forward, -forward, EXPOSURE, interpolation="cubic")
    sums = np.asarray(op.matrix.sum(axis=1)).ravel()
    np.testing.assert_allclose(sums, 1.0, atol=1e-5)
    calm = smooth_flow(SHAPE, 4, amplitude=5.0)
    unchanged = displacement_blur(calm, -calm, EXPOSURE, interpolation="cubic").matrix
    far = slice(20 * SHAPE[1], None)  # rows far from the degenerate corner
    assert abs(op.matrix[far] - unchanged[far]).max() < 1e-12


def _diverging_flow(speed=10.0):
    """Left half moves left, right half moves right, at all instants: a hole opens."""
    flow = np.zeros(SHAPE + (2,))
    flow[:, : SHAPE[1] // 2, 0] = -speed
    flow[:, SHAPE[1] // 2 :, 0] = speed
    return flow


def test_uncovered_pixels_get_the_identity():
    flow = _diverging_flow()
    # Backward flow equal to the forward one: content moves away from the centre
    # at every instant. With N = 2 the samples are at |s| = tau / 4 (1.9 px).
    bilinear = {"num_samples": 2, "interpolation": "bilinear"}
    op = displacement_blur(flow, flow, EXPOSURE, **bilinear)
    ref = displacement_blur_reference(flow, flow, EXPOSURE, **bilinear)
    assert abs(op.matrix - ref.matrix).max() < 1e-6
    middle = SHAPE[1] // 2
    for y in (0, 17, SHAPE[0] - 1):
        for x in (middle - 1, middle):
            row = op.matrix[y * SHAPE[1] + x]
            assert row.indices.tolist() == [y * SHAPE[1] + x] and row.data.tolist() == [1.0]
    # Pixels two columns further out are covered by content that moved there.
    covered = op.matrix[5 * SHAPE[1] + middle - 3]
    assert 5 * SHAPE[1] + middle - 3 not in covered.indices
    assert MIN_COVERAGE < 0.01


def test_constant_flow_equals_homography_of_translation():
    """The baseline is treated fairly: same samples, same border rule, same matrix."""
    depth, velocity = 3.0, (0.25, -0.2)
    scene = translation_sceneflow(SHAPE, velocity, depth)
    focal = scene.camera.K[[0, 1], [0, 1]]
    flow = np.broadcast_to(focal * np.asarray(velocity) / depth, SHAPE + (2,))
    np.testing.assert_allclose(scene.flow(), flow, atol=1e-9)
    disp = displacement_blur(flow, -flow, EXPOSURE, interpolation="bilinear").matrix
    hom = homography_blur(scene, EXPOSURE, interpolation="bilinear").matrix
    diff = abs(disp - hom)
    reach = int(np.ceil(EXPOSURE.duty_cycle / 2 * np.abs(flow[0, 0]).max())) + 1
    y, x = np.divmod(np.arange(disp.shape[0]), SHAPE[1])
    interior = (y >= reach) & (y < SHAPE[0] - reach) & (x >= reach) & (x < SHAPE[1] - reach)
    assert diff[interior].max() < 1e-6
    assert diff.max() < 1e-6  # the shared border rule makes the border rows agree too


def test_cubic_constant_flow_equals_cubic_homography_of_translation():
    """Cubic splats of a translation are the cubic gather's taps, away from the border."""
    depth, velocity = 3.0, (0.25, -0.2)
    scene = translation_sceneflow(SHAPE, velocity, depth)
    focal = scene.camera.K[[0, 1], [0, 1]]
    flow = np.broadcast_to(focal * np.asarray(velocity) / depth, SHAPE + (2,))
    disp = displacement_blur(flow, -flow, EXPOSURE, interpolation="cubic").matrix
    hom = homography_blur(scene, EXPOSURE, interpolation="cubic").matrix
    reach = int(np.ceil(EXPOSURE.duty_cycle / 2 * np.abs(flow[0, 0]).max())) + 3
    y, x = np.divmod(np.arange(disp.shape[0]), SHAPE[1])
    interior = (y >= reach) & (y < SHAPE[0] - reach) & (x >= reach) & (x < SHAPE[1] - reach)
    assert abs(disp - hom)[interior].max() < 1e-5
    assert (disp.data < 0).any()


def test_backward_flow_is_used_before_the_frame_centre():
    forward, backward = np.array([4.0, 0.0]), np.array([0.0, 5.0])
    op = displacement_blur(
        np.broadcast_to(forward, SHAPE + (2,)),
        np.broadcast_to(backward, SHAPE + (2,)),
        EXPOSURE,
        num_samples=10,
        interpolation="bilinear",
    )
    image = np.random.default_rng(3).random(SHAPE)
    expected = np.zeros(SHAPE)
    for s in EXPOSURE.sample_fractions(10):
        shift = s * forward if s >= 0 else -s * backward  # (x, y) displacement of content
        expected += ndimage.shift(image, shift[::-1], order=1, mode="nearest")
    expected /= 10
    inner = (slice(3, -3), slice(3, -3))
    np.testing.assert_allclose(op.forward(image)[inner], expected[inner], atol=2e-6)


def test_kernels_collect_sources_whose_lines_pass_through():
    """Supplement Fig. 11b: A[z, y] > 0 iff a sample of y's straight line is within 1 px of z."""
    y, x = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]].astype(np.float64)
    cy, cx = (SHAPE[0] - 1) / 2, (SHAPE[1] - 1) / 2
    angle = 0.3  # flow of a rotation about the image centre: kernels are straight, not arcs
    flow = np.stack(
        [
            (x - cx) * np.cos(angle) - (y - cy) * np.sin(angle) + cx - x,
            (x - cx) * np.sin(angle) + (y - cy) * np.cos(angle) + cy - y,
        ],
        axis=-1,
    )
    fractions = EXPOSURE.sample_fractions(20)
    op = displacement_blur(flow, -flow, EXPOSURE, num_samples=20, interpolation="bilinear")
    # Positions of every in-image source at every instant, (HW, S, 2).
    src = np.stack([x, y], -1).reshape(-1, 1, 2)
    positions = src + fractions[None, :, None] * flow.reshape(-1, 1, 2)
    reach = int(np.ceil(EXPOSURE.duty_cycle / 2 * np.abs(flow).max())) + 1
    rng = np.random.default_rng(0)
    zs = rng.choice(
        np.flatnonzero(
            (y.ravel() >= reach)
            & (y.ravel() < SHAPE[0] - reach)
            & (x.ravel() >= reach)
            & (x.ravel() < SHAPE[1] - reach)
        ),
        40,
        replace=False,
    )
    for z in zs:
        target = np.array([z % SHAPE[1], z // SHAPE[1]], dtype=np.float64)
        near = np.all(np.abs(positions - target) < 1.0, axis=-1)  # bilinear support
        passing = set(np.flatnonzero(near.any(axis=1)).tolist())
        assert set(op.matrix[z].indices.tolist()) == passing
        assert len(passing) > 5


@pytest.mark.parametrize(
    "forward, backward, match",
    [
        (np.zeros((4, 5)), np.zeros((4, 5)), "flow_forward"),
        (np.zeros((4, 5, 2)), np.zeros((4, 6, 2)), "but flow_backward"),
        (np.full((4, 5, 2), np.nan), np.zeros((4, 5, 2)), "finite"),
        (np.zeros((4, 5, 2)), np.zeros((4, 5, 3)), "flow_backward"),
    ],
)
def test_bad_flow_is_an_input_error(forward, backward, match):
    with pytest.raises(InputError, match=match):
        displacement_blur(forward, backward, EXPOSURE)
