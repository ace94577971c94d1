import numpy as np
import pytest

from stereodeblur.geometry import se3_exp
from stereodeblur.geometry.plane import disparity_coefficients
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.sceneflow.proposals import (
    dominant_motion,
    fit_motions,
    fit_planes,
    global_proposals,
    predict,
)

from .scenes import CAMERA

NORMALS = np.array([[0.05, -0.1, 0.5], [-0.08, 0.02, 0.3], [0.0, 0.12, 0.45]])
TWISTS = np.array(
    [
        [0.05, -0.02, -0.1, 0.01, 0.02, -0.01],
        [-0.03, 0.04, 0.06, -0.02, 0.01, 0.015],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ]
)


def _truth():
    labels = np.zeros((60, 90), np.int32)
    labels[:, 30:] = 1
    labels[40:, 60:] = 2
    return SceneFlow(CAMERA, labels, NORMALS, TWISTS, np.zeros(labels.shape, bool))


def _observations(truth):
    H, W = truth.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    flow = truth.flow()
    return (
        x.ravel(),
        y.ravel(),
        truth.labels.ravel().astype(np.int64),
        truth.disparity().ravel(),
        (x + flow[..., 0]).ravel(),
        (y + flow[..., 1]).ravel(),
        truth.disparity_next().ravel(),
    )


def test_predict_matches_the_scene_flow_model():
    truth = _truth()
    x, y, seg, d0, x1, y1, d1 = _observations(truth)
    abc = disparity_coefficients(CAMERA, NORMALS)[seg]
    M = se3_exp(TWISTS)[seg]
    p0, px, py, pd = predict(CAMERA, abc, M[:, :3, :3], M[:, :3, 3], x, y)
    np.testing.assert_allclose(p0, d0, atol=1e-9)
    np.testing.assert_allclose(px, x1, atol=1e-9)
    np.testing.assert_allclose(py, y1, atol=1e-9)
    np.testing.assert_allclose(pd, d1, atol=1e-9)


def test_plane_fit_ignores_outliers():
    truth = _truth()
    x, y, seg, d0, *_ = _observations(truth)
    rng = np.random.default_rng(1)
    noisy = d0 + rng.normal(0, 0.05, d0.shape)
    bad = rng.random(d0.shape) < 0.2
    noisy[bad] += rng.uniform(-20, 20, bad.sum())
    abc, ok = fit_planes(seg, 3, x, y, noisy, rng=rng)
    assert ok.all()
    fitted = abc[seg, 0] * x + abc[seg, 1] * y + abc[seg, 2]
    assert np.max(np.abs(fitted - d0)) < 0.03  # noise 0.05 px, 20 % gross outliers


def test_motion_fit_recovers_each_segment_from_noisy_correspondences():
    truth = _truth()
    x, y, seg, d0, x1, y1, d1 = _observations(truth)
    rng = np.random.default_rng(2)
    x1 = x1 + rng.normal(0, 0.05, x1.shape)
    y1 = y1 + rng.normal(0, 0.05, y1.shape)
    bad = rng.random(x1.shape) < 0.1
    x1[bad] += rng.uniform(-15, 15, bad.sum())
    d1 = np.where(rng.random(d1.shape) < 0.2, np.nan, d1)
    R, T, ok = fit_motions(CAMERA, seg, 3, x, y, d0, x1, y1, d1)
    assert ok.all()
    M = se3_exp(TWISTS)
    for k in range(3):
        angle = np.degrees(np.arccos(np.clip((np.trace(R[k] @ M[k, :3, :3].T) - 1) / 2, -1, 1)))
        assert angle < 0.2
        np.testing.assert_allclose(T[k], M[k, :3, 3], atol=5e-3)


def test_dominant_motion_and_global_proposal_find_the_largest_rigid_part():
    truth = _truth()
    x, y, seg, d0, x1, y1, d1 = _observations(truth)
    abc_seg = disparity_coefficients(CAMERA, NORMALS)
    M = se3_exp(TWISTS)
    rng = np.random.default_rng(3)
    R, T, fraction = dominant_motion(
        CAMERA,
        abc_seg[seg],
        M[:, :3, :3],
        M[:, :3, 3],
        np.arange(3),
        x,
        y,
        x1,
        y1,
        d1 - d0,
        rng=rng,
    )
    np.testing.assert_allclose(R, M[1, :3, :3], atol=1e-6)  # segment 1 is the largest
    np.testing.assert_allclose(T, M[1, :3, 3], atol=1e-6)
    assert fraction == pytest.approx((seg == 1).mean(), abs=0.02)
    g_abc, g_R, g_T = global_proposals(
        CAMERA,
        abc_seg,
        M[:, :3, :3],
        M[:, :3, 3],
        np.arange(3),
        x,
        y,
        d0,
        x1,
        y1,
        d1 - d0,
        rng=rng,
    )
    assert len(g_abc) == 3
    np.testing.assert_allclose(g_abc[0], abc_seg[1], atol=1e-6)
