import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.sceneflow import initial_optical_flow
from stereodeblur.sceneflow.initial import default_max_disparity, initial_disparity, to_gray


def _texture(shape, seed=0):
    rng = np.random.default_rng(seed)
    t = ndimage.gaussian_filter(rng.random(shape), 1.2)
    return ((t - t.min()) / (t.max() - t.min())).astype(np.float32)


def test_sgbm_finds_a_constant_shift():
    tex = _texture((80, 150))
    left, right = tex[:, 20:140], tex[:, 26:146]  # x_right = x_left - 6
    d = initial_disparity(left, right)
    valid = np.isfinite(d)
    assert valid[:, 10:].mean() > 0.9
    assert np.median(np.abs(d[valid] - 6.0)) < 0.25


def test_dis_finds_a_translation():
    tex = _texture((100, 150), seed=1)
    a = tex[10:90, 10:130]
    b = tex[12:92, 7:127]  # content moves by (+3, -2)
    flow = initial_optical_flow(a, b)
    assert flow.shape == (80, 120, 2)
    inner = flow[10:-10, 10:-10]
    assert np.median(inner[..., 0]) == pytest.approx(3.0, abs=0.2)
    assert np.median(inner[..., 1]) == pytest.approx(-2.0, abs=0.2)


def test_gray_of_rgb_uses_luma_weights():
    rgb = np.zeros((2, 2, 3), np.float32)
    rgb[..., 1] = 1.0
    assert np.allclose(to_gray(rgb), 0.587)
    with pytest.raises(ValueError):
        to_gray(np.zeros((2, 2, 4)))


def test_default_search_range():
    assert default_max_disparity(640) == 160
    assert default_max_disparity(40) == 16
    assert default_max_disparity(5000) == 256
