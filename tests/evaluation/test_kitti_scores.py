"""KITTI's outlier rule (over 3 px and over 5 %), holes, and the ground-truth PNG encodings."""

import cv2
import numpy as np
import pytest

from stereodeblur.evaluation.kitti_scores import (
    disparity_errors,
    flow_errors,
    interpolate_background,
    is_outlier,
    read_kitti_disparity,
    read_kitti_flow,
    sceneflow_outliers,
    warp_disparity_next,
)


def test_outlier_needs_both_3px_and_5_percent():
    error = np.array([2.9, 3.1, 3.1, 5.0, 5.0])
    truth = np.array([10.0, 10.0, 70.0, 99.0, 101.0])
    # 3.1 px of 70 px is 4.4 %: not an outlier; 5 px of 101 px is 4.95 %: not one either.
    assert is_outlier(error, truth).tolist() == [False, True, False, True, False]


def test_disparity_rates_and_holes():
    truth = np.array([[10.0, 10.0, 80.0, np.nan], [20.0, 20.0, 50.0, 5.0]])
    estimate = np.array([[10.5, 14.0, 83.5, 1.0], [np.nan, 20.0, 60.0, 5.0]])
    errors = disparity_errors(estimate, truth)
    assert errors.known.sum() == 7
    # Outliers: 14 vs 10 (4 px, 40 %), the hole at 20, 60 vs 50; not 83.5 vs 80 (4.4 %).
    assert errors.outlier.sum() == 3
    assert errors.outlier_rate == pytest.approx(3 / 7)
    assert errors.hole_rate == pytest.approx(1 / 7)
    # The hole counts as zero: its error is the whole truth, 20 px.
    assert errors.mean_endpoint == pytest.approx((0.5 + 4 + 3.5 + 20 + 0 + 10 + 0) / 7)


def test_flow_rule_uses_the_vector_length():
    truth = np.zeros((1, 3, 2))
    truth[0, 0] = (60.0, 80.0)  # 100 px: 4 px off is under 5 %
    truth[0, 1] = (3.0, 4.0)  # 5 px: 4 px off is an outlier
    truth[0, 2] = np.nan
    estimate = truth + np.array([0.0, 4.0])
    estimate[0, 2] = np.nan
    errors = flow_errors(estimate, truth)
    assert errors.outlier[0].tolist() == [False, True, False]
    assert errors.outlier_rate == pytest.approx(0.5)
    assert errors.mean_endpoint == pytest.approx(4.0)


def test_sceneflow_outlier_is_any_where_all_known():
    truth_d = np.array([[10.0, 10.0, 10.0]])
    truth_f = np.zeros((1, 3, 2))
    truth_f[0, 2] = np.nan
    d1 = disparity_errors(np.array([[10.0, 20.0, 20.0]]), truth_d)
    d2 = disparity_errors(np.array([[10.0, 10.0, 10.0]]), truth_d)
    fl = flow_errors(truth_f + 0.0, truth_f)
    sf = sceneflow_outliers(d1, d2, fl)
    assert sf.known.tolist() == [[True, True, False]]
    assert sf.outlier_rate == pytest.approx(0.5)


def test_png_encodings(tmp_path):
    disparity = np.array([[0, 256 * 10 + 128]], dtype=np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), disparity)
    assert np.isnan(read_kitti_disparity(tmp_path / "d.png")[0, 0])
    assert read_kitti_disparity(tmp_path / "d.png")[0, 1] == pytest.approx(10.5)
    flow = np.zeros((1, 2, 3), dtype=np.uint16)  # BGR on disk order: valid, v, u
    flow[0, 0] = (1, 2**15 - 64 * 2, 2**15 + 64 * 3)
    flow[0, 1] = (0, 2**15, 2**15)
    cv2.imwrite(str(tmp_path / "f.png"), flow)
    read = read_kitti_flow(tmp_path / "f.png")
    assert read[0, 0].tolist() == [3.0, -2.0]
    assert np.isnan(read[0, 1]).all()


def test_warp_and_background_fill():
    disparity_next = np.tile(np.arange(6, dtype=np.float64), (4, 1))
    flow = np.zeros((4, 6, 2))
    flow[..., 0] = 1.5
    warped = warp_disparity_next(disparity_next, flow)
    assert warped[1, 0] == pytest.approx(1.5)
    assert np.isnan(warped[1, 5])  # read outside the image
    holes = np.array([[np.nan, 30.0, np.nan, np.nan, 10.0, np.nan]])
    assert interpolate_background(holes)[0].tolist() == [30, 30, 10, 10, 10, 10]
