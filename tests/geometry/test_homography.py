import numpy as np
import pytest

from stereodeblur.geometry import (
    Exposure,
    StereoCamera,
    disparity_coefficients,
    move_plane,
    plane_disparity,
    plane_from_disparity_coefficients,
    se3_exp,
    trajectory_homographies,
)

CAMERA = StereoCamera([[500.0, 0, 160], [0, 500.0, 120], [0, 0, 1]], 0.12)


def _plane_points(rng, n_plane, count):
    """Random points on the plane P^T n = 1 in front of the camera."""
    x = rng.uniform(0, 320, count)
    y = rng.uniform(0, 240, count)
    rays = np.stack([x, y, np.ones(count)], 1) @ CAMERA.K_inv.T
    return rays / (rays @ n_plane)[:, None]


@pytest.mark.parametrize("view", ["left", "right"])
def test_homography_equals_projection_of_moved_plane(view):
    rng = np.random.default_rng(0)
    n = np.array([0.05, -0.03, 1.0]) / 4.0
    twist = np.array([0.3, -0.1, 0.5, 0.05, 0.2, -0.1])
    fractions = np.array([-0.4, -0.1, 0.0, 0.25, 0.5, 1.0])
    H = trajectory_homographies(CAMERA, n[None], twist[None], fractions, view)[0]
    P = _plane_points(rng, n, 50)
    x_ref = CAMERA.project(P, view)
    for k, s in enumerate(fractions):
        M = se3_exp(s * twist)
        x_t = CAMERA.project(P @ M[:3, :3].T + M[:3, 3], view)
        # H_ref_from_t maps the pixel at instant t back to the reference pixel.
        q = np.concatenate([x_t, np.ones((50, 1))], 1) @ H[k].T
        np.testing.assert_allclose(q[:, :2] / q[:, 2:], x_ref, atol=1e-8)


def test_zero_motion_gives_identity():
    H = trajectory_homographies(
        CAMERA, [[0, 0, 0.2]], [[0] * 6], np.linspace(-0.5, 0.5, 5), "right"
    )
    np.testing.assert_allclose(H, np.broadcast_to(np.eye(3), H.shape), atol=1e-12)


def test_disparity_coefficients_round_trip_and_match_depth():
    rng = np.random.default_rng(1)
    n = np.array([0.02, 0.05, 0.3])
    abc = disparity_coefficients(CAMERA, n)
    np.testing.assert_allclose(plane_from_disparity_coefficients(CAMERA, abc), n)
    P = _plane_points(rng, n, 20)
    x, y = CAMERA.project(P).T
    np.testing.assert_allclose(plane_disparity(CAMERA, n, x, y), CAMERA.depth_to_disparity(P[:, 2]))
    # x_right = x_left - d
    np.testing.assert_allclose(
        CAMERA.project(P, "right")[:, 0], x - CAMERA.depth_to_disparity(P[:, 2])
    )


def test_move_plane():
    rng = np.random.default_rng(2)
    n = np.array([0.1, 0.0, 0.25])
    M = se3_exp([0.2, 0.1, -0.3, 0.1, -0.2, 0.05])
    P = _plane_points(rng, n, 10)
    Q = P @ M[:3, :3].T + M[:3, 3]
    np.testing.assert_allclose(Q @ move_plane(n, M[:3, :3], M[:3, 3]), 1.0)


def test_exposure_validation_and_samples():
    e = Exposure(20.0, 0.04)
    assert e.duty_cycle == pytest.approx(0.8)
    s = e.sample_fractions(4)
    np.testing.assert_allclose(s, [-0.3, -0.1, 0.1, 0.3])
    with pytest.raises(ValueError, match="longer than the frame interval"):
        Exposure(20.0, 0.06)
    with pytest.raises(ValueError, match="baseline"):
        StereoCamera(np.eye(3), -1.0)
    with pytest.raises(ValueError, match="K must"):
        StereoCamera(np.eye(2), 1.0)
