import pickle

import numpy as np
import pytest

from stereodeblur.geometry import StereoCamera
from stereodeblur.sceneflow.model import SceneFlow

CAMERA = StereoCamera([[80.0, 0.0, 31.5], [0.0, 80.0, 23.5], [0.0, 0.0, 1.0]], 0.2)


def _sceneflow():
    rng = np.random.default_rng(1)
    labels = np.zeros((24, 32), np.int32)
    labels[:, 16:] = 1
    normals = np.array([[0.01, -0.02, 0.4], [0.0, 0.03, 0.3]])
    twists = rng.normal(0, 0.02, (2, 6))
    return SceneFlow(CAMERA, labels, normals, twists, np.zeros(labels.shape, bool))


def test_geometry_is_computed_once_and_read_only():
    sf = _sceneflow()
    assert sf.points() is sf.points()
    assert sf.points_at(1.0) is sf.points_at(1.0)
    with pytest.raises(ValueError):
        sf.points()[0, 0, 0] = 1.0
    fresh = _sceneflow()
    np.testing.assert_array_equal(sf.flow(), fresh.flow())
    np.testing.assert_array_equal(sf.disparity_next(), fresh.disparity_next())
    assert not np.array_equal(sf.points_at(0.5), sf.points_at(1.0))


def test_with_occlusion_shares_the_geometry_and_pickles_without_it():
    sf = _sceneflow()
    flow = sf.flow()
    mask = np.ones(sf.shape, bool)
    other = sf.with_occlusion(mask)
    assert other.points() is sf.points()
    assert other.occlusion.all() and not sf.occlusion.any()
    back = pickle.loads(pickle.dumps(other))
    assert "_geometry" not in back.__dict__
    np.testing.assert_array_equal(back.flow(), flow)
