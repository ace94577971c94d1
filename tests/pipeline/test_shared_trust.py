"""Trust maps of several motions computed together equal those computed one by one."""

import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.deconv import trust as trust_module
from stereodeblur.deconv.trust import motion_trust, motion_trusts

SHAPE = (36, 44)


def _frames(seed: int = 0):
    rng = np.random.default_rng(seed)
    frame = rng.random((*SHAPE, 3)).astype(np.float32)
    following = np.roll(frame, (1, 2), axis=(0, 1)) + 0.01 * rng.standard_normal(frame.shape)
    return frame, following.astype(np.float32)


def _flows(seed: int = 1):
    """A smooth flow, the same flow changed in a band (and with a NaN), and a third."""
    rng = np.random.default_rng(seed)
    first = np.zeros((*SHAPE, 2))
    first[..., 0], first[..., 1] = 2.0, 1.0
    first += 0.3 * rng.standard_normal(first.shape)
    second = first.copy()
    second[10:20] = rng.uniform(-6.0, 6.0, second[10:20].shape)
    second[3, 4] = np.nan
    third = -first
    return [first, second, third]


@pytest.mark.parametrize("occluded", [False, True])
@pytest.mark.parametrize("smoothing", [0.0, 2.0])
def test_motion_trusts_equal_motion_trust_of_each_flow(occluded, smoothing):
    frame, following = _frames()
    occlusion = np.zeros(SHAPE, bool)
    occlusion[5:9, 30:] = occluded
    kwargs = dict(occlusion=occlusion, smoothing=smoothing, noise_sigma=0.01)
    flows = _flows()
    together = motion_trusts(frame, following, flows, **kwargs)
    assert len(together) == len(flows)
    for flow, trust in zip(flows, together, strict=True):
        np.testing.assert_array_equal(trust, motion_trust(frame, following, flow, **kwargs))
        assert trust.dtype == np.float32 and trust.shape == SHAPE
    # The flows differ, and so do their maps.
    assert not np.array_equal(together[0], together[1])


def test_motion_trusts_of_the_same_flow_twice_and_of_none():
    frame, following = _frames()
    flow = _flows()[0]
    first, again = motion_trusts(frame, following, [flow, flow.copy()])
    np.testing.assert_array_equal(first, again)
    assert motion_trusts(frame, following, []) == []


@pytest.mark.parametrize("shape", [(480, 64), (7, 5), (1, 9), (2, 2)])
@pytest.mark.parametrize("spread", [0.5, 3.0, 30.0])
def test_the_sampling_equals_map_coordinates_bit_for_bit(shape, spread):
    """Inside, outside, on pixel centres and on the last row and column."""
    rng = np.random.default_rng(int(10 * spread) + shape[0])
    image = rng.random((*shape, 3))
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    ys, xs = y + rng.normal(0, spread, shape), x + rng.normal(0, spread, shape)
    for coordinate, last in ((xs, shape[1] - 1), (ys, shape[0] - 1)):
        pick = rng.random(shape)
        coordinate[pick < 0.1] = np.round(coordinate[pick < 0.1])
        coordinate[pick > 0.95] = last
    expected = np.stack(
        [
            ndimage.map_coordinates(image[..., c], [ys, xs], order=1, mode="nearest")
            for c in range(3)
        ],
        axis=-1,
    )
    np.testing.assert_array_equal(trust_module._moved(image, xs, ys), expected)
