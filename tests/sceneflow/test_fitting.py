import numpy as np
import pytest

from stereodeblur.geometry import se3_exp
from stereodeblur.sceneflow.fitting import fit_rigid, fit_rigid_to_projections

K = np.array([[300.0, 0, 160], [0, 300.0, 120], [0, 0, 1]])


def _patch(seed):
    """Points of a small tilted planar patch 3-4 m ahead and a random rigid motion."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-0.2, 0.2, (2, 50))
    P = np.column_stack([u, v, 3.5 + 0.3 * u - 0.2 * v])
    M = se3_exp(np.concatenate([rng.normal(0, 0.1, 3), rng.normal(0, 0.05, 3)]))
    return P, M[:3, :3], M[:3, 3]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_motion_is_recovered_from_its_projections(seed):
    P, R, T = _patch(seed)
    q = (P @ R.T + T) @ K.T
    xy = q[:, :2] / q[:, 2:]
    fitted_R, fitted_T = fit_rigid_to_projections(P, xy, K)
    np.testing.assert_allclose(fitted_R, R, atol=1e-6)
    np.testing.assert_allclose(fitted_T, T, atol=1e-6)


def test_a_motion_is_recovered_from_3d_correspondences():
    P, R, T = _patch(3)
    fitted_R, fitted_T = fit_rigid(P, P @ R.T + T)
    np.testing.assert_allclose(fitted_R, R, atol=1e-9)
    np.testing.assert_allclose(fitted_T, T, atol=1e-9)


def test_too_few_projections_are_refused():
    with pytest.raises(ValueError, match="at least 3"):
        fit_rigid_to_projections(np.zeros((2, 3)), np.zeros((2, 2)), K)


def test_points_far_away_and_close_together_still_get_a_motion():
    # The sky of a semi-real KITTI clip: a few points at the far clamp, 1 mm apart. OpenCV's
    # SQPnP refuses them (an assertion on their spread); the fit starts from rest instead.
    rng = np.random.default_rng(0)
    P = np.column_stack([rng.uniform(-5e-4, 5e-4, (2, 20)).T, np.full(20, 700.0)])
    R, T = np.eye(3), np.array([0.0, 0.0, -0.5])
    q = (P @ R.T + T) @ K.T
    fitted_R, fitted_T = fit_rigid_to_projections(P, q[:, :2] / q[:, 2:], K)
    residual = (P @ fitted_R.T + fitted_T) @ K.T
    np.testing.assert_allclose(residual[:, :2] / residual[:, 2:], q[:, :2] / q[:, 2:], atol=1e-3)
