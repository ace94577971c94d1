import numpy as np
from scipy import ndimage

from stereodeblur.geometry import se3_exp
from stereodeblur.geometry.plane import disparity_coefficients
from stereodeblur.sceneflow.blur_balance import blur_length_change, cross_blur
from stereodeblur.sceneflow.fusion import ProposalSet
from stereodeblur.sceneflow.proposals import predict

from .scenes import CAMERA, SIZE, frames, render_views

NORMAL = np.array([0.0, 0.0, 0.5])  # fronto-parallel plane at 2 m
APPROACH = np.array([0.0, 0.0, -0.4, 0.0, 0.0, 0.0])  # fast approach
DUTY = 0.8


def _proposal(twist):
    M = se3_exp(twist)
    return ProposalSet(
        disparity_coefficients(CAMERA, NORMAL[None]), M[None, :3, :3], M[None, :3, 3]
    )


def test_cross_blur_makes_the_frames_of_an_approach_agree():
    images = list(frames(render_views(NORMAL, APPROACH, duty_cycle=DUTY, num_instants=24)))
    groups = np.zeros(SIZE, np.int64)
    props = _proposal(APPROACH)
    balanced, valid = cross_blur(CAMERA, images, groups, props, duty_cycle=DUTY, num_samples=24)
    y, x = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    d0, x1, y1, d1 = predict(CAMERA, props.abc[0], props.R[0], props.T[0], x, y)

    def gap(ims, ok):
        ref = ims[0]
        g = []
        for i, (px, py) in zip((1, 2, 3), ((x - d0, y), (x1, y1), (x1 - d1, y1)), strict=True):
            sample = ndimage.map_coordinates(ims[i], [py, px], order=1, mode="nearest")
            inside = ndimage.map_coordinates(ok[i].astype(float), [py, px], order=0) > 0
            use = ok[0] & inside & (px >= 0) & (px <= SIZE[1] - 1) & (py >= 0) & (py <= SIZE[0] - 1)
            g.append(np.abs(sample - ref)[use].mean())
        return np.array(g)

    assert all(v.mean() > 0.3 for v in valid)
    before = gap(images, valid)
    after = gap(balanced, valid)
    # Frames t and t + 1 differ in blur: balancing removes most of the difference (same
    # view; across views the blurs of this wide-baseline camera differ in themselves).
    assert after[1] < 0.5 * before[1]
    assert after[0] < 0.02


def test_blur_length_change_of_an_approach_and_a_sideways_motion():
    groups = np.zeros(SIZE, np.int64)
    change = blur_length_change(CAMERA, groups, _proposal(APPROACH), duty_cycle=DUTY)
    # Analytic: a point at image offset r from the principal point and depth 2 m is
    # at r * 2 / (2 - 0.4 u) at instant u.
    y, x = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    r = np.hypot(x - CAMERA.K[0, 2], y - CAMERA.K[1, 2])

    def pos(u):
        return r * 2.0 / (2.0 - 0.4 * u)

    h = DUTY / 2
    expected = (pos(1 + h) - pos(1 - h)) - (pos(h) - pos(-h))
    np.testing.assert_allclose(change, expected, atol=1e-6)
    longer = np.maximum(pos(1 + h) - pos(1 - h), pos(h) - pos(-h))
    relative = blur_length_change(
        CAMERA, groups, _proposal(APPROACH), duty_cycle=DUTY, relative=True
    )
    np.testing.assert_allclose(relative, expected / np.maximum(longer, 1.0), atol=1e-6)
    sideways = blur_length_change(
        CAMERA, groups, _proposal(np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0])), duty_cycle=DUTY
    )
    np.testing.assert_allclose(sideways, 0.0, atol=1e-9)


def test_refinement_ignores_pixels_marked_invalid():
    from stereodeblur.sceneflow.refine import refine_proposals

    twist = np.array([0.05, -0.03, -0.08, 0.01, 0.015, -0.01])
    images = list(frames(render_views(NORMAL, twist, num_instants=5)))
    M = se3_exp(twist + np.array([0.01, 0, 0.01, 0, 0.002, 0]))
    start = ProposalSet(
        disparity_coefficients(CAMERA, NORMAL[None] * 1.02), M[None, :3, :3], M[None, :3, 3]
    )
    valid = [np.ones(SIZE, bool) for _ in range(4)]
    valid[1][:, :45] = False  # corruption below spreads ~20 px by the contrast normalisation
    corrupted = [im.copy() for im in images]
    corrupted[1][:, :20] = np.random.default_rng(1).random((SIZE[0], 20))
    groups = np.zeros(SIZE, np.int64)
    clean = refine_proposals(CAMERA, images, groups, start, valid=valid)
    noisy = refine_proposals(CAMERA, corrupted, groups, start, valid=valid)
    unmasked = refine_proposals(CAMERA, corrupted, groups, start)
    np.testing.assert_allclose(noisy.abc, clean.abc, rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(noisy.T, clean.T, rtol=1e-5, atol=1e-8)
    assert not np.allclose(unmasked.abc, clean.abc, rtol=1e-3, atol=1e-5)
