"""Trust maps of several motions computed together equal those computed one by one."""

import numpy as np
import pytest
from scipy import ndimage

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


def _reference_trust(blurred, following, flow, occlusion, sigma, smoothing=2.0):
    """The trust as first written, with ``ndimage.map_coordinates`` and numpy throughout."""
    b = blurred if blurred.ndim == 3 else blurred[..., None]
    b_next = following if following.ndim == 3 else following[..., None]
    b, b_next = b.astype(np.float64), b_next.astype(np.float64)
    H, W = b.shape[:2]
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    xs, ys = x + flow[..., 0], y + flow[..., 1]
    known = np.isfinite(xs) & np.isfinite(ys)
    xs, ys = np.where(known, xs, x), np.where(known, ys, y)
    moved = np.stack(
        [
            ndimage.map_coordinates(b_next[..., c], [ys, xs], order=1, mode="nearest")
            for c in range(b.shape[2])
        ],
        axis=-1,
    )
    leaves = ~known | (xs < 0) | (xs > W - 1) | (ys < 0) | (ys > H - 1) | occlusion
    squared = np.where(leaves, 0.0, np.mean((moved - b) ** 2, axis=2))
    still = np.mean((b_next - b) ** 2, axis=2)
    share = (~leaves).astype(np.float64)
    if smoothing > 0:
        share = ndimage.gaussian_filter(share, smoothing, mode="nearest")
        squared = ndimage.gaussian_filter(squared, smoothing, mode="nearest")
        squared = squared / np.maximum(share, 1e-6)
        still = ndimage.gaussian_filter(still, smoothing, mode="nearest")
    s2 = 0.5**2 * still + 0.005**2 + (3.0 * sigma) ** 2
    trust = share / (1.0 + squared / np.maximum(s2, 1e-24))
    trust[leaves] = 0.0
    return np.clip(trust, 0.0, 1.0).astype(np.float32)


@pytest.mark.parametrize("shape", [(480, 64, 3), (7, 5, 3), (1, 9, 3), (2, 2, 3), (30, 40)])
@pytest.mark.parametrize("spread", [0.5, 3.0, 30.0])
def test_the_trust_equals_the_map_coordinates_reference_bit_for_bit(shape, spread):
    """Samples inside, outside, on pixel centres, on the last row and column; NaN flows."""
    rng = np.random.default_rng(int(10 * spread) + shape[0])
    frame = rng.random(shape).astype(np.float32)
    following = rng.random(shape).astype(np.float32)
    flow = rng.normal(0, spread, (*shape[:2], 2))
    y, x = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float64)
    for axis, (grid, last) in enumerate(((x, shape[1] - 1), (y, shape[0] - 1))):
        pick = rng.random(shape[:2])
        flow[..., axis][pick < 0.1] = np.round(flow[..., axis][pick < 0.1])
        flow[..., axis][pick > 0.95] = (last - grid)[pick > 0.95]
    flow[rng.random(shape[:2]) < 0.02] = np.nan
    occlusion = rng.random(shape[:2]) < 0.05
    for smoothing in (0.0, 2.0):
        expected = _reference_trust(frame, following, flow, occlusion, 0.01, smoothing)
        (trust,) = motion_trusts(
            frame, following, [flow], occlusion=occlusion, noise_sigma=0.01, smoothing=smoothing
        )
        np.testing.assert_array_equal(trust, expected)
