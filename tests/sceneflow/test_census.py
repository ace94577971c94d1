import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.sceneflow.census import (
    NUM_OFFSETS,
    OFFSETS,
    census_cost,
    census_descriptors,
    census_thresholds,
    census_transform,
    dark_noise_level,
    noise_level,
    shot_noise_flattens_the_dark,
    texture_fraction,
    wrong_match_cost,
)
from stereodeblur.sceneflow.preparation import census_encoding, matching_encoding
from stereodeblur.sceneflow.settings import SceneFlowSettings


def _texture(shape=(40, 50), seed=0):
    rng = np.random.default_rng(seed)
    t = ndimage.gaussian_filter(rng.random(shape), 1.0)
    return (t - t.min()) / (t.max() - t.min())


def test_offsets_are_a_checkerboard_of_the_7x7_window():
    assert NUM_OFFSETS == 24
    assert np.all(np.abs(OFFSETS) <= 3)
    assert np.all((OFFSETS.sum(axis=1) % 2) == 1)


def test_codes_match_a_direct_ternary_comparison():
    image = _texture()
    codes = census_transform(image, threshold=0.01)
    padded = np.pad(image, 3, mode="edge")
    y, x = 20, 17
    expected = 0
    for k, (dx, dy) in enumerate(OFFSETS):
        diff = padded[y + 3 + dy, x + 3 + dx] - padded[y + 3, x + 3]
        expected |= (1 if diff > 0.01 else 2 if diff < -0.01 else 0) << (2 * k)
    assert int(codes[y, x]) == expected


def test_gain_and_bias_leave_codes_unchanged():
    image = _texture()
    a = census_transform(image, threshold=0.004)
    b = census_transform(0.5 * image + 0.2, threshold=0.002)
    np.testing.assert_array_equal(a, b)


def test_cost_is_zero_at_the_true_shift_and_not_elsewhere():
    image = _texture((40, 60))
    shifted = np.roll(image, 3, axis=1)  # content moves 3 px right
    a, b = census_transform(image), census_transform(shifted)
    y, x = np.mgrid[5:35, 8:50]
    x, y = x.ravel(), y.ravel()
    right = census_cost(a, b, x, y, x + 3.0, y.astype(float))
    wrong = census_cost(a, b, x, y, x + 1.0, y.astype(float))
    assert np.all(right == 0)
    assert np.mean(wrong) > 0.3


def test_cost_interpolates_between_pixels_and_is_nan_outside():
    image = _texture()
    codes = census_transform(image)
    x, y = np.array([10]), np.array([10])
    c0 = census_cost(codes, codes, x, y, np.array([10.0]), np.array([10.0]))
    c1 = census_cost(codes, codes, x, y, np.array([11.0]), np.array([10.0]))
    half = census_cost(codes, codes, x, y, np.array([10.5]), np.array([10.0]))
    assert c0[0] == 0
    assert half[0] == pytest.approx(0.5 * (c0[0] + c1[0]))
    out = census_cost(codes, codes, x, y, np.array([-0.5]), np.array([10.0]))
    assert np.isnan(out[0])


def test_rejects_colour_images():
    with pytest.raises(ValueError, match="grey"):
        census_transform(np.zeros((4, 4, 3)))


def test_noise_level_recovers_the_noise_of_a_smooth_image():
    rng = np.random.default_rng(1)
    smooth = 0.2 + 0.6 * _texture((120, 160), seed=2)
    smooth = ndimage.gaussian_filter(smooth, 2.0)
    for sigma in (0.005, 0.02):
        noisy = smooth + sigma * rng.standard_normal(smooth.shape)
        assert noise_level(noisy) == pytest.approx(sigma, rel=0.15)
    assert noise_level(smooth) < 0.002


def test_thresholds_shrink_with_brightness_and_stay_above_the_noise():
    image = np.array([[0.0, 0.01, 0.25, 1.0]])
    t = census_thresholds(image, threshold=0.008)
    np.testing.assert_allclose(t[0], 0.008 * np.sqrt(image[0] / 0.25), rtol=1e-6)
    t = census_thresholds(image, threshold=0.008, noise=0.01, noise_factor=1.0)
    np.testing.assert_allclose(t[0], [0.01414, 0.01414, 0.01414, 0.016], rtol=1e-3)


def test_dark_texture_is_matched_with_brightness_relative_thresholds():
    # A dark textured stereo pair (values about 0.005 .. 0.02, shifted by 3 px): with a
    # fixed threshold of 2/255 the codes are flat and every disparity matches equally
    # well; thresholds relative to the brightness tell the true one from a wrong one.
    base = _texture((40, 60), seed=4)
    dark = 0.005 + 0.015 * base
    left, right = dark[:, :-3], dark[:, 3:]  # left x matches right x - 3
    y, x = np.mgrid[0:40, 10:50]
    y, x = y.ravel(), x.ravel()
    a = census_transform(left, threshold=census_thresholds(left))
    b = census_transform(right, threshold=census_thresholds(right))
    true = census_cost(a, b, x, y, x - 3.0, y).mean()
    wrong = census_cost(a, b, x, y, x - 6.0, y).mean()
    assert true < 0.05 and wrong > 0.3


def test_wrong_match_cost_is_low_in_clean_flat_regions_and_high_in_noise():
    rng = np.random.default_rng(5)
    flat = census_transform(np.full((30, 30), 0.5))
    assert np.all(wrong_match_cost(flat) == 0.0)
    noisy = census_transform(0.5 + 0.05 * rng.standard_normal((30, 30)))
    assert wrong_match_cost(noisy).mean() > 0.4
    # Texture: the cost against pixels 4 px away is that of a wrong match.
    tex = census_transform(_texture((30, 30), seed=6))
    assert wrong_match_cost(tex).mean() > 0.3


def test_noisy_frames_are_smoothed_before_the_census():
    # Texture under noise of 0.01 in both views, shifted by 3 px: smoothed first, the true
    # disparity matches far better than without, and still clearly beats a wrong one; a
    # flat noisy region reads as flat (every match cheap) instead of as random texture.
    rng = np.random.default_rng(7)
    base = 0.2 + 0.1 * _texture((60, 80), seed=8)
    left = base[:, :-3] + 0.01 * rng.standard_normal((60, 77))
    right = base[:, 3:] + 0.01 * rng.standard_normal((60, 77))
    y, x = np.mgrid[5:55, 12:70]
    y, x = y.ravel(), x.ravel()

    def costs(denoise):
        a, b = census_descriptors(left, denoise=denoise), census_descriptors(right, denoise=denoise)
        return [census_cost(a, b, x, y, x - s, y).mean() for s in (3.0, 6.0)]

    (true, wrong), (raw_true, _) = costs(1.5), costs(0.0)
    assert true < 0.5 * raw_true and wrong - true > 0.2
    flat = 0.2 + 0.01 * rng.standard_normal((40, 40))
    assert wrong_match_cost(census_descriptors(flat)).mean() < 0.05
    assert wrong_match_cost(census_descriptors(flat, denoise=0.0)).mean() > 0.4
    clean = census_descriptors(base)  # no noise: no smoothing, the plain census
    np.testing.assert_array_equal(clean, census_transform(base, threshold=census_thresholds(base)))


def test_shot_noise_of_bright_regions_does_not_flatten_dark_texture():
    # Three quarters bright, one quarter a dark texture (0.004 .. 0.012, a hedge in shade),
    # under shot noise (deviation 0.01 times the square root of the brightness), shifted by
    # 3 px between the views. Linear light with the image's one noise level (the bright
    # part's) reads the dark quarter as flat, where every disparity matches; the square root,
    # where shot noise is equally strong everywhere, keeps its texture and its true match.
    rng = np.random.default_rng(7)
    clean = np.concatenate(
        [np.full((40, 180), 0.5), 0.004 + 0.008 * _texture((40, 60), seed=8)], axis=1
    )
    views = [clean + 0.01 * np.sqrt(clean) * rng.standard_normal(clean.shape) for _ in range(2)]
    left, right = views[0][:, :-3], np.roll(views[1], -3, axis=1)[:, :-3]
    y, x = np.mgrid[0:40, 190:230]
    y, x = y.ravel(), x.ravel()
    seen = {}
    for gamma in (1.0, 0.5):
        a, b = (
            census_descriptors(matching_encoding(v, gamma), relative=gamma == 1.0)
            for v in (left, right)
        )
        fraction = np.mean([texture_fraction(c) for c in a[y, x]])
        true = census_cost(a, b, x, y, x - 3.0, y).mean()
        wrong = census_cost(a, b, x, y, x - 6.0, y).mean()
        seen[gamma] = fraction, wrong - true
    assert seen[1.0][0] < 0.05 and abs(seen[1.0][1]) < 0.02
    assert seen[0.5][0] > 0.3 and seen[0.5][1] > 0.1


def _bright_and_dark(shape=(120, 160), dark=0.004):
    """Three quarters a bright texture, one quarter a dark one (``dark`` of full scale)."""
    image = 0.3 + 0.4 * _texture(shape, seed=3)
    image[:, : shape[1] // 4] = dark * (0.5 + _texture((shape[0], shape[1] // 4), seed=4))
    return image


@pytest.mark.parametrize("sigma", [0.003, 0.01, 0.02])
def test_additive_noise_does_not_count_as_shot_noise(sigma):
    # Additive noise is as strong in the dark as in the bright parts; clipped at black it
    # reads about half as strong there, still above a third of the image's level.
    rng = np.random.default_rng(11)
    for dark in (0.0, 0.004, 0.05):
        noisy = np.clip(_bright_and_dark(dark=dark) + sigma * rng.standard_normal((120, 160)), 0, 1)
        assert dark_noise_level(noisy) > noise_level(noisy) / 3
        assert not shot_noise_flattens_the_dark(noisy)
        assert census_encoding(noisy, SceneFlowSettings()) == 1.0


def test_shot_noise_over_a_dark_region_counts_and_picks_the_square_root():
    rng = np.random.default_rng(12)
    clean = _bright_and_dark()
    noisy = np.clip(clean + np.sqrt(1e-3 * clean) * rng.standard_normal(clean.shape), 0, 1)
    assert shot_noise_flattens_the_dark(noisy)
    assert census_encoding(noisy, SceneFlowSettings()) == 0.5
    assert census_encoding(noisy, SceneFlowSettings(census_gamma=1.0)) == 1.0  # as asked
    # The dark quarter's own noise: 0.03 * sqrt(0.004 .. 0.006), far below the image's level.
    assert dark_noise_level(noisy) < 0.004 < noise_level(noisy)
    # Without a dark region the same noise leaves the linear census alone.
    bright = np.clip(0.3 + 0.4 * _texture((120, 160), seed=3), 0, 1)
    bright = bright + np.sqrt(1e-3 * bright) * rng.standard_normal(bright.shape)
    assert not shot_noise_flattens_the_dark(bright)


def test_a_noiseless_flat_image_keeps_the_linear_census():
    assert not shot_noise_flattens_the_dark(np.full((32, 32), 0.2))
    assert census_encoding(np.zeros((32, 32)), SceneFlowSettings()) == 1.0
