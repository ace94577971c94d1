import numpy as np
import pytest

from stereodeblur.geometry.rigid import RigidMotion, se3_exp, se3_log, so3_exp, so3_log


def _random_twists(rng, n, max_angle):
    xi = rng.standard_normal((n, 6))
    axis = xi[:, 3:] / np.linalg.norm(xi[:, 3:], axis=1, keepdims=True)
    xi[:, 3:] = axis * rng.uniform(0, max_angle, (n, 1))
    return xi


@pytest.mark.parametrize("dtype,tol", [(np.float64, 1e-9), (np.float32, 2e-4)])
def test_log_of_exp_random(dtype, tol):
    rng = np.random.default_rng(0)
    xi = _random_twists(rng, 500, np.pi - 1e-3).astype(dtype)
    back = se3_log(se3_exp(xi))
    assert back.dtype == dtype
    np.testing.assert_allclose(back, xi, atol=tol * 10)


@pytest.mark.parametrize(
    "angle", [0.0, 1e-12, 1e-8, 1e-5, 1e-3, 0.5, np.pi - 1e-3, np.pi - 1e-6, np.pi]
)
def test_round_trips_at_critical_angles(angle):
    rng = np.random.default_rng(1)
    for _ in range(20):
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        xi = np.concatenate([rng.standard_normal(3), axis * angle])
        M = se3_exp(xi)
        R = M[:3, :3]
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
        # exp(log(M)) == M holds everywhere; log(exp(xi)) == xi up to the sign ambiguity at pi.
        np.testing.assert_allclose(se3_exp(se3_log(M)), M, atol=1e-9)
        if angle < np.pi - 1e-7:
            np.testing.assert_allclose(se3_log(M), xi, atol=1e-7)


def test_exp_of_log_random_rotations():
    rng = np.random.default_rng(2)
    q = rng.standard_normal((300, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )
    np.testing.assert_allclose(so3_exp(so3_log(R)), R, atol=1e-9)


def test_exp_matches_matrix_exponential():
    from scipy.linalg import expm

    rng = np.random.default_rng(3)
    for xi in _random_twists(rng, 20, 3.0):
        X = np.zeros((4, 4))
        v, w = xi[:3], xi[3:]
        X[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
        X[:3, 3] = v
        np.testing.assert_allclose(se3_exp(xi), expm(X), atol=1e-10)


def test_fractions_compose():
    motion = RigidMotion([0.1, -0.2, 0.3, 0.2, 0.1, -0.3])
    np.testing.assert_allclose(
        motion.matrix(0.3) @ motion.matrix(0.7), motion.matrix(1.0), atol=1e-12
    )
    np.testing.assert_allclose(motion.matrix(-0.5) @ motion.matrix(0.5), np.eye(4), atol=1e-12)


def test_rigid_motion_validates():
    with pytest.raises(ValueError, match="twist"):
        RigidMotion([1, 2, 3])
    with pytest.raises(ValueError, match="twist"):
        RigidMotion([0, 0, np.nan, 0, 0, 0])
