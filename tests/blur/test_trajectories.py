"""The sampling rules: scalar (numba) and vectorised (numpy) forms agree; border rule."""

import numpy as np
import pytest
from numba import njit

from stereodeblur.blur.trajectories import (
    SNAP,
    bilinear_taps,
    clamp,
    displacement_margin,
    displacement_point,
    displacement_positions,
    extended_grid,
    homography_point,
    homography_positions,
    split_coordinate,
)

SHAPE = (7, 9)


@njit
def _scalar_taps(px, py, height, width, clamped):
    """The four (x, y, weight) taps the kernels use, from the scalar helpers."""
    out = np.zeros((px.size, 4, 3))
    for i in range(px.size):
        x, y = px[i], py[i]
        if clamped:
            x, y = clamp(x, width - 1), clamp(y, height - 1)
        x0, fx = split_coordinate(x)
        y0, fy = split_coordinate(y)
        for t in range(4):
            wx = fx if t & 1 else 1.0 - fx
            wy = fy if t >> 1 else 1.0 - fy
            out[i, t, 0] = x0 + (t & 1)
            out[i, t, 1] = y0 + (t >> 1)
            out[i, t, 2] = wx * wy
    return out


def _positions(seed, n=400):
    rng = np.random.default_rng(seed)
    p = rng.uniform([-4, -4], [SHAPE[1] + 4, SHAPE[0] + 4], (n, 2))
    p[: n // 4] = np.round(p[: n // 4])  # exact pixel centres
    p[n // 4 : n // 2] = np.round(p[n // 4 : n // 2]) + rng.choice([-1, 1], (n // 4, 2)) * 1e-12
    return p


@pytest.mark.parametrize("border", ["clamp", "drop"])
def test_scalar_and_vectorised_taps_agree(border):
    p = _positions(0)
    index, weight, valid = bilinear_taps(p, SHAPE, border=border)
    scalar = _scalar_taps(p[:, 0], p[:, 1], SHAPE[0], SHAPE[1], border == "clamp")
    sx, sy, sw = scalar[..., 0].astype(int), scalar[..., 1].astype(int), scalar[..., 2]
    inside = (sx >= 0) & (sx < SHAPE[1]) & (sy >= 0) & (sy < SHAPE[0]) & (sw > 0)
    np.testing.assert_array_equal(valid, inside)
    np.testing.assert_array_equal(index[valid], (sy * SHAPE[1] + sx)[valid])
    np.testing.assert_allclose(weight, np.where(inside, sw, 0.0), rtol=0, atol=1e-15)


def test_clamped_taps_interpolate_affine_functions_of_the_clamped_position():
    p = _positions(1)
    index, weight, _ = bilinear_taps(p, SHAPE, border="clamp")
    f = 3.0 * (index % SHAPE[1]) - 2.0 * (index // SHAPE[1]) + 1.0
    clamped = np.clip(p, 0, [SHAPE[1] - 1, SHAPE[0] - 1])
    np.testing.assert_allclose(weight.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(
        (weight * f).sum(axis=1), 3.0 * clamped[:, 0] - 2.0 * clamped[:, 1] + 1.0, atol=1e-7
    )


def test_positions_at_pixel_centres_snap_to_one_tap():
    p = np.array([[3.0 + SNAP / 10, 2.0 - SNAP / 10]])
    index, weight, valid = bilinear_taps(p, SHAPE, border="drop")
    assert valid.sum() == 1 and index[valid][0] == 2 * SHAPE[1] + 3 and weight[valid][0] == 1.0


def test_drop_keeps_only_taps_inside():
    p = np.array([[-0.25, 3.0], [SHAPE[1] - 0.5, 3.0], [-1.5, 3.0]])
    index, weight, valid = bilinear_taps(p, SHAPE, border="drop")
    np.testing.assert_allclose(weight.sum(axis=1), [0.75, 0.5, 0.0])
    assert index[0][valid[0]].tolist() == [3 * SHAPE[1]]


def test_bad_border_rule():
    with pytest.raises(ValueError, match="border"):
        bilinear_taps(np.zeros((1, 2)), SHAPE, border="wrap")


@njit
def _scalar_homography_positions(homographies, labels):
    height, width = labels.shape
    out = np.empty((height, width, homographies.shape[1], 2))
    for y in range(height):
        for x in range(width):
            for s in range(homographies.shape[1]):
                px, py = homography_point(homographies, labels[y, x], s, float(x), float(y))
                out[y, x, s, 0] = px
                out[y, x, s, 1] = py
    return out


def test_homography_positions_agree_and_fall_back_behind_the_camera():
    rng = np.random.default_rng(2)
    homographies = np.eye(3) + rng.normal(0, 0.05, (2, 3, 3, 3))
    homographies[1, 2, 2] = [-0.1, -0.2, -1.0]  # instant 2: depth < 0 everywhere
    labels = (np.arange(SHAPE[1])[None, :] >= 4).astype(np.int32) * np.ones(SHAPE, np.int32)
    vector = homography_positions(homographies, labels)
    scalar = _scalar_homography_positions(homographies, labels)
    np.testing.assert_allclose(vector, scalar, rtol=1e-13, atol=1e-12)
    y, x = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]]
    fallback = (labels == 1)[..., None]
    np.testing.assert_array_equal(vector[..., 2, 0][fallback[..., 0]], x[labels == 1])
    np.testing.assert_array_equal(vector[..., 2, 1][fallback[..., 0]], y[labels == 1])
    # Valid instants of the same segment are real projections.
    h = homographies[1, 0]
    q = h @ np.array([5.0, 3.0, 1.0])
    np.testing.assert_allclose(vector[3, 5, 0], q[:2] / q[2])


@njit
def _scalar_displacement(x, y, fractions, f, b):
    out = np.empty((fractions.size, 2))
    for k in range(fractions.size):
        px, py = displacement_point(x, y, fractions[k], f[0], f[1], b[0], b[1])
        out[k, 0] = px
        out[k, 1] = py
    return out


def test_displacement_positions_use_forward_then_backward_flow():
    fractions = np.array([-0.3, -0.1, 0.0, 0.2])
    f, b = np.array([2.0, -1.0]), np.array([-3.0, 0.5])
    vector = displacement_positions(np.array(4.0), np.array(5.0), f, b, fractions)
    expected = [[4 - 0.9, 5 + 0.15], [4 - 0.3, 5 + 0.05], [4, 5], [4.4, 4.8]]
    np.testing.assert_allclose(vector, expected)
    np.testing.assert_allclose(_scalar_displacement(4.0, 5.0, fractions, f, b), expected)


def test_margin_depends_only_on_border_flow():
    fractions = np.array([-0.25, 0.25])
    flow = np.zeros(SHAPE + (2,))
    flow[3, 4] = 100.0  # interior: cannot carry content in from outside
    assert displacement_margin(flow, flow, fractions) == 1
    flow[0, 2, 1] = -6.0
    assert displacement_margin(flow, np.zeros_like(flow), fractions) == 3  # ceil(1.5) + 1
    assert displacement_margin(np.zeros_like(flow), flow, fractions) == 3


def test_margin_stops_at_the_image_size():
    fractions = np.array([-0.25, 0.25])
    flow = np.zeros(SHAPE + (2,))
    flow[0, 2, 1] = -4e6  # a degenerate motion: an estimated plane through the camera
    assert displacement_margin(flow, flow, fractions) == max(SHAPE) + 1
    assert displacement_margin(flow, flow, fractions, cubic=True) == max(SHAPE) + 2


def test_extended_grid_maps_to_nearest_pixel_in_source_order():
    margin = 2
    x, y, source = extended_grid(SHAPE, margin)
    assert x.size == (SHAPE[0] + 2 * margin) * (SHAPE[1] + 2 * margin)
    assert np.all(np.diff(source) >= 0)
    np.testing.assert_array_equal(
        source, np.clip(y, 0, SHAPE[0] - 1) * SHAPE[1] + np.clip(x, 0, SHAPE[1] - 1)
    )
    assert len(set(zip(x.tolist(), y.tolist(), strict=True))) == x.size
    # A corner pixel stands for the (margin + 1)^2 extended pixels around it.
    assert np.count_nonzero(source == 0) == (margin + 1) ** 2
