"""Trust in the blur model from the motion's temporal consistency, and the IRLS anchor."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from skimage import data, transform

from stereodeblur.blur.operator import SparseBlur
from stereodeblur.deconv import deblur_irls
from stereodeblur.deconv.noise import auto_alpha
from stereodeblur.deconv.trust import OUTSIDE_WEIGHT, leaves_view, motion_trust, trust_anchor
from stereodeblur.errors import InputError
from stereodeblur.evaluation.metrics import psnr

SHAPE = (72, 96)


def _texture(name="astronaut"):
    image = getattr(data, name)() / 255.0
    return transform.resize(image, (*SHAPE, 3), anti_aliasing=True).astype(np.float32)


def _shift(image, dx, dy=0):
    """``out(y, x) = image(y - dy, x - dx)``, clamped at the borders."""
    ys = np.clip(np.arange(image.shape[0]) - dy, 0, image.shape[0] - 1)
    xs = np.clip(np.arange(image.shape[1]) - dx, 0, image.shape[1] - 1)
    return image[ys][:, xs]


def test_an_exact_translation_is_trusted_where_it_stays_in_view():
    frame = _texture()
    following = _shift(frame, 3, 2)
    flow = np.broadcast_to(np.array([3.0, 2.0]), (*SHAPE, 2))
    trust = motion_trust(frame, following, flow)
    assert trust.dtype == np.float32 and trust.shape == SHAPE
    inside = np.zeros(SHAPE, bool)
    inside[:-2, :-3] = True
    assert np.all(trust[~inside] == 0)  # the flow leaves the view
    assert trust[8:-8, 8:-8].min() > 0.99


def test_a_wrong_flow_is_not_trusted_and_only_there():
    frame = _texture()
    following = _shift(frame, 3, 0)
    flow = np.zeros((*SHAPE, 2))
    flow[..., 0] = 3.0
    flow[20:50, 30:60, 0] = -2.0  # 5 px off
    trust = motion_trust(frame, following, flow)
    assert np.median(trust[25:45, 35:55]) < 0.5
    away = np.ones(SHAPE, bool)
    away[12:58, 22:68] = False
    away[:, -6:] = False
    assert np.mean(trust[away] > 0.95) > 0.95


@pytest.mark.parametrize("sigma", [0.01, 0.02])
def test_noise_alone_leaves_trust_high(sigma):
    rng = np.random.default_rng(4)
    frame = _texture()
    following = _shift(frame, 2, 0)
    noisy = [np.clip(f + rng.normal(0, sigma, f.shape), 0, 1) for f in (frame, following)]
    flow = np.zeros((*SHAPE, 2))
    flow[..., 0] = 2.0
    trust = motion_trust(*noisy, flow)
    assert np.mean(trust[:, :-4] > 0.75) > 0.95


def test_occlusion_is_not_trusted():
    frame = _texture()
    occlusion = np.zeros(SHAPE, bool)
    occlusion[10:20, 10:20] = True
    trust = motion_trust(frame, frame, np.zeros((*SHAPE, 2)), occlusion=occlusion)
    assert np.all(trust[occlusion] == 0)
    near = np.zeros(SHAPE, bool)
    near[4:26, 4:26] = True
    assert trust[near & ~occlusion].max() < 1 and trust[~near].min() > 0.99


def test_anchor_values():
    np.testing.assert_allclose(
        trust_anchor(np.array([[0.0, 0.5, 1.0]]), strength=0.2), [[0.2, 0.1, 0.0]]
    )


def moving_disc(sigma, seed=0, step=10, duty=0.8):
    """A textured disc moving ``step`` px per frame to the right over a static background.

    Frames t and t + 1 average 9 exact instants over the exposure (``duty`` of the frame
    interval); the blur operator of frame t gives every pixel its layer's blur at the
    reference instant (right away from the boundary, wrong where disc and background mix).
    Returns ``(sharp_t, blurred_t, blurred_t1, flow, operator)``.
    """
    height, width = SHAPE
    background, foreground = _texture("astronaut"), _texture("coffee")
    ys, xs = np.mgrid[0:height, 0:width]
    disc = (ys - 36) ** 2 / 18**2 + (xs - 40) ** 2 / 22**2 <= 1
    instants = np.linspace(-duty / 2, duty / 2, 9) * step
    rng = np.random.default_rng(seed)
    blurred = []
    for start in (0, step):
        frames = []
        for s in instants:
            dx = int(round(start + s))
            moved = _shift(disc, dx)
            frames.append(np.where(moved[..., None], _shift(foreground, dx), background))
        noise = rng.normal(0.0, sigma, background.shape)
        blurred.append(np.clip(np.mean(frames, axis=0) + noise, 0, 1).astype(np.float32))
    sharp = np.where(disc[..., None], foreground, background).astype(np.float32)
    flow = np.zeros((*SHAPE, 2))
    flow[disc, 0] = step
    taps = np.where(disc[..., None], np.round(instants).astype(int), 0)
    rows = np.broadcast_to(np.arange(height * width).reshape(SHAPE)[..., None], taps.shape)
    cols = ys[..., None] * width + np.clip(xs[..., None] - taps, 0, width - 1)
    matrix = sp.csr_matrix(
        (np.full(cols.size, 1.0 / instants.size), (rows.ravel(), cols.ravel())),
        shape=(height * width, height * width),
        dtype=np.float32,
    )
    return sharp, blurred[0], blurred[1], flow, SparseBlur(matrix, SHAPE)


@pytest.mark.parametrize("sigma", [0.0, 0.01])
def test_the_anchor_keeps_motion_boundaries_from_ruining_the_deblurring(sigma):
    sharp, blurred, following, flow, blur = moving_disc(sigma)
    alpha = auto_alpha(blurred)
    trust = motion_trust(blurred, following, flow)
    anchored = psnr(
        deblur_irls(blurred, blur, alpha=alpha, anchor=trust_anchor(trust)).image, sharp
    )
    plain = psnr(deblur_irls(blurred, blur, alpha=alpha).image, sharp)
    assert anchored > plain + 0.3
    assert anchored > psnr(blurred, sharp) + 0.5


def test_a_strong_anchor_holds_the_estimate_at_the_blurred_frame():
    sharp, blurred, _, _, blur = moving_disc(0.0)
    anchor = np.zeros(SHAPE, np.float32)
    anchor[:36] = 1e4  # the upper half of the disc
    result = deblur_irls(blurred, blur, alpha=1e-4, num_irls=3, anchor=anchor)
    np.testing.assert_allclose(result.image[:36], blurred[:36], atol=1e-3)
    assert np.abs(result.image - blurred)[40:54, 25:55].max() > 0.05  # deblurred below
    energies = [it.energy for it in result.history]
    assert all(b <= a * (1 + 1e-5) for a, b in zip(energies, energies[1:], strict=False))
    zero = deblur_irls(blurred, blur, alpha=1e-4, num_irls=2, anchor=np.zeros(SHAPE))
    plain = deblur_irls(blurred, blur, alpha=1e-4, num_irls=2)
    np.testing.assert_array_equal(zero.image, plain.image)


def test_bad_inputs():
    frame = _texture()
    with pytest.raises(InputError):
        motion_trust(frame, frame[:10], np.zeros((*SHAPE, 2)))
    with pytest.raises(InputError):
        motion_trust(frame, frame, np.zeros((*SHAPE, 2)), scale=-1.0)
    with pytest.raises(InputError):
        motion_trust(frame, frame, np.zeros((*SHAPE, 2)), occlusion=np.zeros((3, 3), bool))
    with pytest.raises(InputError):
        trust_anchor(np.ones(SHAPE), strength=np.nan)
    with pytest.raises(InputError):
        deblur_irls(
            frame,
            SparseBlur(sp.identity(frame[..., 0].size, format="csr"), SHAPE),
            anchor=-np.ones(SHAPE),
        )


def test_alpha_from_trust_grows_with_the_untrusted_share():
    from stereodeblur.deconv.trust import alpha_from_trust

    trust = np.ones((10, 100))
    assert alpha_from_trust(trust) == 0.0
    trust[0, :10] = 0.2  # 1 % untrusted: half of the paper's alpha
    assert alpha_from_trust(trust) == pytest.approx(5e-4)
    trust[:3] = 0.0  # 30 %: capped at the paper's
    assert alpha_from_trust(trust) == pytest.approx(1e-3)
    with pytest.raises(InputError):
        alpha_from_trust(trust, share=0.0)


def test_only_pixels_near_motion_boundaries_are_in_the_band():
    from stereodeblur.deconv.trust import near_motion_boundaries

    smooth = np.zeros((*SHAPE, 2))
    smooth[..., 0] = np.linspace(0, 8, SHAPE[1])[None, :]  # an approach: no jump anywhere
    assert not near_motion_boundaries(smooth, 0.8).any()
    _, _, _, flow, _ = moving_disc(0.0)  # a 10 px jump at the disc's rim
    band = near_motion_boundaries(flow, 0.8)
    ys, xs = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]]
    rim = np.abs(np.sqrt((ys - 36) ** 2 / 18**2 + (xs - 40) ** 2 / 22**2) - 1) < 0.05
    assert band[rim].all() and not band[:, -10:].any() and not band[36, 38:42].any()
    tiles = np.zeros((*SHAPE, 2))
    tiles[..., 0] = 40.0
    tiles[:, SHAPE[1] // 2 :, 0] += 0.6  # two estimates of one fast surface: 1.5 % apart
    assert not near_motion_boundaries(tiles, 0.8).any()
    assert near_motion_boundaries(tiles, 0.8, relative=0.01).any()


def test_a_translation_leaves_the_view_on_both_sides_along_its_path():
    flow = np.broadcast_to(np.array([3.0, 0.0]), (*SHAPE, 2))  # 1.2 px each way at tau = 0.8
    height, width = SHAPE
    leaves = leaves_view(flow, None, 0.8)
    assert leaves.dtype == bool and leaves.shape == SHAPE
    expected = np.zeros(SHAPE, bool)
    expected[:, [0, 1, width - 2, width - 1]] = True
    np.testing.assert_array_equal(leaves, expected)
    expected[:, [2, width - 3]] = True  # ends within 1 px of the edge
    expected[[0, height - 1]] = True  # the pixels within 1 px of it, whatever their flow
    np.testing.assert_array_equal(leaves_view(flow, None, 0.8, margin=1.0), expected)
    upward = np.zeros((*SHAPE, 2))
    upward[..., 1] = -5.0  # 2.5 px up in the second half of a full exposure, none before
    leaves = leaves_view(upward, np.zeros((*SHAPE, 2)), 1.0)
    expected = np.zeros(SHAPE, bool)
    expected[:3] = True
    np.testing.assert_array_equal(leaves, expected)
    assert not leaves_view(np.zeros((*SHAPE, 2)), None, 1.0).any()


def test_a_roll_leaves_where_a_sampled_path_does():
    height, width = SHAPE
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    forward = 0.2 * np.stack([-(ys - 30.0), xs - 40.0], axis=-1)  # rotation about (40, 30)
    backward = -0.7 * forward + 0.5  # slower before the frame centre, and drifting
    duty, margin = 0.6, 0.5
    out = np.zeros(SHAPE, bool)
    for s in np.linspace(0.0, duty / 2, 31):
        for flow in (forward, backward):
            px, py = xs + s * flow[..., 0], ys + s * flow[..., 1]
            out |= (px < margin) | (px > width - 1 - margin) | (py < margin)
            out |= py > height - 1 - margin
    leaves = leaves_view(forward, backward, duty, margin=margin)
    np.testing.assert_array_equal(leaves, out)
    assert 0 < leaves.mean() < 0.5 and not leaves[20:40, 30:50].any()


def test_leaves_view_counts_unknown_flow_and_checks_its_inputs():
    flow = np.zeros((*SHAPE, 2))
    flow[5, 7] = np.nan
    leaves = leaves_view(flow, None, 0.5, margin=0.0)
    assert leaves[5, 7] and leaves.sum() == 1
    with pytest.raises(InputError):
        leaves_view(flow[..., 0], None, 0.5)
    with pytest.raises(InputError):
        leaves_view(flow, flow[:10], 0.5)
    with pytest.raises(InputError):
        leaves_view(flow, None, 1.5)
    with pytest.raises(InputError):
        leaves_view(flow, None, 0.5, margin=-1.0)


@pytest.mark.parametrize("motion", [(10.0, 0.0), (8.0, 6.0)])
def test_a_low_weight_where_the_path_leaves_the_view_helps_inside(motion):
    from stereodeblur.blur.displacement import displacement_blur
    from stereodeblur.geometry.camera import Exposure

    pad = 12  # the frame is the middle of a wider scene: content enters during the exposure
    scene = transform.resize(
        data.astronaut() / 255.0, (SHAPE[0] + 2 * pad, SHAPE[1] + 2 * pad, 3), anti_aliasing=True
    ).astype(np.float32)
    exposure = Exposure(20.0, 0.04)
    wide = np.broadcast_to(np.array(motion), (*scene.shape[:2], 2))
    view = (slice(pad, -pad), slice(pad, -pad))
    blurred = displacement_blur(wide, -wide, exposure, num_samples=16).forward(scene)[view]
    sharp, flow = scene[view], wide[view]
    blur = displacement_blur(flow, -flow, exposure, num_samples=16)
    outside = leaves_view(flow, None, exposure.duty_cycle)
    weights = np.where(outside, OUTSIDE_WEIGHT, 1).astype(np.float32)
    options = {"alpha": auto_alpha(blurred), "num_irls": 4, "num_cg": 15}
    plain = psnr(deblur_irls(blurred, blur, **options).image, sharp, border=8)
    masked = psnr(deblur_irls(blurred, blur, weights=weights, **options).image, sharp, border=8)
    assert masked > plain + 1.0
