"""Regions where a sharp estimate leaves [0, 1]."""

import numpy as np
import pytest

from stereodeblur.deconv.intensity_range import range_excess, unexplained_regions

CONSTANTS = {"excess": 0.05, "window": 9, "share": 0.2}


def test_excess_is_the_distance_outside_the_range_of_the_worst_channel():
    image = np.array([[[0.5, 1.3, 0.2], [-0.4, 0.5, 1.1]], [[0.0, 1.0, 0.5], [0.9, 0.9, 0.9]]])
    np.testing.assert_allclose(range_excess(image), [[0.3, 0.4], [0.0, 0.0]], atol=1e-6)
    np.testing.assert_allclose(range_excess(image[..., 0]), [[0.0, 0.4], [0.0, 0.0]], atol=1e-6)


def test_a_region_outside_the_range_is_found_and_scattered_pixels_are_not():
    rng = np.random.default_rng(0)
    image = rng.uniform(0.1, 0.9, (60, 80))
    stripes = 0.5 + 0.9 * np.sin(np.arange(20) * 2.0)  # swings to -0.4 and 1.4
    image[10:30, 10:30] = stripes[None, :]
    scattered = rng.random(image.shape) < 0.05
    scattered[:, :40] = False
    image[scattered] = 1.5
    found = unexplained_regions(image, **CONSTANTS)
    assert found[15:25, 15:25].all()
    assert not found[:, 45:].any()
    assert found.mean() < 0.15


@pytest.mark.parametrize(
    "bad",
    [
        {"share": 0.0},
        {"share": 1.0},
        {"excess": -0.1},
        {"window": 0},
        {"area": 1.0},
        {"whole": 0.0},
        {"whole": 1.5},
    ],
)
def test_bad_constants_are_refused(bad):
    with pytest.raises(ValueError, match="need"):
        unexplained_regions(np.zeros((8, 8)), **(CONSTANTS | bad))


def test_regions_smaller_than_the_area_are_dropped():
    image = np.full((100, 100), 0.5)
    image[10:40, 10:40] = np.where(np.arange(30) % 2, -0.5, 1.5)[None, :]  # 9 % of the image
    image[70:78, 70:78] = 1.5  # 0.6 %
    found = unexplained_regions(image, **CONSTANTS)
    assert found[20:30, 20:30].all() and found[72:76, 72:76].all()
    kept = unexplained_regions(image, **CONSTANTS, area=0.02)
    assert kept[20:30, 20:30].all() and not kept[60:, 60:].any()


def test_regions_over_more_than_the_whole_share_take_the_whole_image():
    image = np.full((100, 100), 0.5)
    image[10:40, 10:40] = np.where(np.arange(30) % 2, -0.5, 1.5)[None, :]  # 14 % found
    assert 0.1 < unexplained_regions(image, **CONSTANTS, whole=0.2).mean() < 0.2
    assert unexplained_regions(image, **CONSTANTS, whole=0.1).all()
    assert not unexplained_regions(np.full((100, 100), 0.5), **CONSTANTS, whole=0.05).any()
