import numpy as np
import pytest
import scipy.ndimage as ndi

from stereodeblur.geometry import Exposure, StereoCamera, homography, move_plane, se3_exp, so3_exp
from stereodeblur.synth.render import (
    PlanarObject,
    SceneSetup,
    cast_rays,
    pixel_offsets,
    render_blurred,
    render_instant,
    render_scene,
    sample_texture,
    shade,
    track,
)

SIZE = (96, 72)  # (width, height)
CAMERA = StereoCamera([[80.0, 0, 47.5], [0, 80.0, 35.5], [0, 0, 1]], 0.12)
TILT = so3_exp(np.array([0.08, -0.12, 0.03]))
TWIST = np.array([0.05, -0.03, -0.08, 0.02, -0.03, 0.04])


def _plane(texture, *, distance=2.0, rotation=None, twist=None, texel=0.025, **kw):
    """A plane through (0, 0, distance) with texture axes along the rotated x and y axes."""
    rotation = np.eye(3) if rotation is None else rotation
    twist = np.zeros(6) if twist is None else twist
    unit = rotation @ np.array([0.0, 0.0, 1.0])
    normal = unit / (distance * unit[2])
    origin = np.array([0.0, 0.0, distance])
    return PlanarObject(normal, twist, texture, origin, rotation[:, :2].T, texel, **kw)


def _random_texture(shape=(110, 150), seed=0):
    return np.random.default_rng(seed).random(shape + (3,)).astype(np.float32)


def _ramp_texture(h=110, w=150):
    """A texture whose bilinear lookup returns its own coordinates: (u / (w-1), v / (h-1), 0.5)."""
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([u / (w - 1), v / (h - 1), np.full_like(u, 0.5)], -1).astype(np.float32)


def _texture_from_pixel(obj, view, fraction):
    """Analytic inverse of the map texture (u, v) -> pixel of the plane moved to ``fraction``.

    A texture point is X = origin + (u - cu) s e1 + (v - cv) s e2 in the reference pose,
    R X + T at the instant, and projects to K (R X + T - C): a homography of (u, v, 1).
    """
    h, w = obj.texture.shape[:2]
    s, (e1, e2) = obj.texel_size, obj.axes
    M = se3_exp(fraction * obj.twist)
    R, T = M[:3, :3], M[:3, 3]
    corner = obj.origin - (w - 1) / 2 * s * e1 - (h - 1) / 2 * s * e2
    G = CAMERA.K @ np.stack([R @ (s * e1), R @ (s * e2), R @ corner + T - CAMERA.center(view)], 1)
    return np.linalg.inv(G)


def _apply(H, x, y):
    q = np.stack([x, y, np.ones_like(x)], -1) @ H.T
    return q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]


GRID_Y, GRID_X = np.mgrid[0 : SIZE[1], 0 : SIZE[0]].astype(np.float64)


@pytest.mark.parametrize("view", ["left", "right"])
@pytest.mark.parametrize("fraction", [0.0, 0.7])
def test_instant_image_is_texture_lookup_of_projected_plane(view, fraction):
    obj = _plane(_random_texture(), rotation=TILT, twist=TWIST)
    image = render_instant([obj], CAMERA, view, SIZE, fraction).image
    u, v = _apply(_texture_from_pixel(obj, view, fraction), GRID_X, GRID_Y)
    assert u.min() > 0 and u.max() < 149 and v.min() > 0 and v.max() < 109  # covered
    expected = np.stack(
        [ndi.map_coordinates(obj.texture[..., c], [v, u], order=1) for c in range(3)], -1
    )
    np.testing.assert_allclose(image, expected, atol=2e-6)


def test_sample_texture_is_bilinear_and_clamps():
    texture = _random_texture((5, 7))
    u = np.array([0.0, 6.0, 2.25, -3.0, 9.0, 3.5])
    v = np.array([0.0, 4.0, 1.5, 2.0, 1.0, 7.0])
    expected = np.stack(
        [ndi.map_coordinates(texture[..., c], [v, u], order=1, mode="nearest") for c in range(3)],
        -1,
    )
    np.testing.assert_allclose(sample_texture(texture, u, v), expected, atol=1e-6)


@pytest.mark.parametrize("view", ["left", "right"])
def test_disparity_of_fronto_parallel_plane(view):
    distance, vz = 2.5, -0.3
    obj = _plane(_random_texture(), distance=distance, twist=np.array([0.1, 0, vz, 0, 0, 0]))
    setup = SceneSetup("test", CAMERA, Exposure(20.0, 0.04), SIZE, 2, (obj,))
    scene = render_scene(setup, num_samples=2)
    for i, depth in enumerate([distance, distance + vz]):
        disparity = scene.disparity[view][i]
        np.testing.assert_allclose(disparity, CAMERA.fx * CAMERA.baseline / depth, rtol=1e-6)


def test_flow_equals_plane_homography():
    obj = _plane(_random_texture(), rotation=TILT, twist=TWIST)
    setup = SceneSetup("test", CAMERA, Exposure(20.0, 0.04), SIZE, 3, (obj,))
    scene = render_scene(setup, num_samples=2)
    M = se3_exp(TWIST)
    R, T = M[:3, :3], M[:3, 3]
    n = obj.normal
    for i in range(2):
        # H = K (R + T n^T) K^-1 with n the plane at the centre of frame i.
        x, y = _apply(homography(CAMERA.K, R, T, n), GRID_X, GRID_Y)
        np.testing.assert_allclose(scene.flow[i][..., 0], x - GRID_X, atol=1e-4)
        np.testing.assert_allclose(scene.flow[i][..., 1], y - GRID_Y, atol=1e-4)
        n = move_plane(n, R, T)
    assert len(scene.flow) == 2


def test_right_view_sees_left_point_shifted_by_disparity():
    fraction = 0.3
    obj = _plane(_ramp_texture(), rotation=TILT, twist=TWIST)
    right = render_instant([obj], CAMERA, "right", SIZE, fraction)
    disparity = CAMERA.fx * CAMERA.baseline / right.depth
    # The ramp texture encodes its coordinates: decode the right view's texture points.
    u_right = right.image[..., 0] * 149.0
    v_right = right.image[..., 1] * 109.0
    # The left view at x_left = x_right + d sees the same texture point.
    u_left, v_left = _apply(_texture_from_pixel(obj, "left", fraction), GRID_X + disparity, GRID_Y)
    np.testing.assert_allclose(u_right, u_left, atol=2e-4)
    np.testing.assert_allclose(v_right, v_left, atol=2e-4)
    # Same claim on the 3D points: project the right view's hits into the left view.
    hits = cast_rays([obj], CAMERA, "right", SIZE, fraction)
    x_left = track([obj], CAMERA, "left", hits, [fraction])[0]
    np.testing.assert_allclose(x_left[..., 0] - GRID_X, disparity, atol=1e-9)
    np.testing.assert_allclose(x_left[..., 1], GRID_Y, atol=1e-9)


def test_zero_motion_blur_is_sharp_image():
    obj = _plane(_random_texture(), rotation=TILT)
    exposure = Exposure(20.0, 0.05)
    blurred = render_blurred([obj], CAMERA, exposure, "left", SIZE, 2, num_samples=7)
    sharp = render_instant([obj], CAMERA, "left", SIZE, 2.0).image
    np.testing.assert_array_equal(blurred.image, sharp)
    assert not blurred.mixed.any()


def test_supersampling_averages_the_pixel_area():
    obj = _plane(_random_texture(), rotation=TILT)
    assert pixel_offsets(1) == [(0.0, 0.0)]
    offsets = pixel_offsets(2)
    assert sorted(offsets) == [(-0.25, -0.25), (-0.25, 0.25), (0.25, -0.25), (0.25, 0.25)]
    sharp = render_instant([obj], CAMERA, "left", SIZE, 0.5, supersampling=2)
    centre = render_instant([obj], CAMERA, "left", SIZE, 0.5)
    shifted = [shade([obj], cast_rays([obj], CAMERA, "left", SIZE, 0.5, offset=o)) for o in offsets]
    np.testing.assert_allclose(sharp.image, np.mean(shifted, axis=0), atol=1e-6)
    np.testing.assert_array_equal(sharp.depth, centre.depth)  # geometry at pixel centres
    assert np.abs(sharp.image - centre.image).max() > 0.05  # the random texture is averaged
    # One ray per instant, offsets taken in turn: without motion, the blur is the sharp image.
    exposure = Exposure(20.0, 0.05)
    blurred = render_blurred(
        [obj], CAMERA, exposure, "left", SIZE, 0, num_samples=8, supersampling=2
    )
    still = render_instant([obj], CAMERA, "left", SIZE, 0.0, supersampling=2).image
    np.testing.assert_allclose(blurred.image, still, atol=1e-6)
    assert not blurred.mixed.any()
    with pytest.raises(ValueError, match="supersampling"):
        pixel_offsets(0)


def test_blurred_frame_is_mean_over_exposure():
    obj = _plane(_random_texture(), rotation=TILT, twist=TWIST)
    frame, num_samples = 1, 5
    exposure = Exposure(20.0, 0.03)  # tau = 0.6
    blurred = render_blurred([obj], CAMERA, exposure, "right", SIZE, frame, num_samples=5)
    # Midpoints of 5 equal sub-intervals of [frame - 0.3, frame + 0.3].
    instants = frame - 0.3 + 0.6 * (np.arange(num_samples) + 0.5) / num_samples
    renders = [render_instant([obj], CAMERA, "right", SIZE, s).image for s in instants]
    np.testing.assert_allclose(blurred.image, np.mean(renders, axis=0), atol=1e-6)
    assert np.abs(blurred.image - renders[2]).max() > 0.05  # it is blurred


def test_nearest_object_wins_and_mixed_marks_moving_edges():
    background = _plane(_random_texture(seed=1), distance=3.0)
    square = _plane(
        np.ones((21, 21, 3), np.float32),
        distance=1.5,
        twist=np.array([0.15, 0.0, 0.0, 0.0, 0.0, 0.0]),
        texel=0.01,
        bounded=True,
        name="square",
    )
    objects = [background, square]
    hits = cast_rays(objects, CAMERA, "left", SIZE, 0.0)
    # The square spans +-0.1 m at 1.5 m: +-5.3 px around the principal point.
    inside = (np.abs(GRID_X - 47.5) < 5) & (np.abs(GRID_Y - 35.5) < 5)
    outside = (np.abs(GRID_X - 47.5) > 6) | (np.abs(GRID_Y - 35.5) > 6)
    assert np.all(hits.object_id[inside] == 1) and np.all(hits.object_id[outside] == 0)
    np.testing.assert_allclose(hits.depth[inside], 1.5)
    np.testing.assert_allclose(hits.depth[outside], 3.0)
    # It moves 8 px per frame along x: 3.2 px during a 0.4 exposure.
    blurred = render_blurred(objects, CAMERA, Exposure(20.0, 0.02), "left", SIZE, 0, num_samples=8)
    rows = np.abs(GRID_Y - 35.5) < 4
    left_edge = rows & (np.abs(GRID_X - (47.5 - 5.3)) < 1.2)
    right_edge = rows & (np.abs(GRID_X - (47.5 + 5.3)) < 1.2)
    assert blurred.mixed[left_edge].all() and blurred.mixed[right_edge].all()
    far = (np.abs(GRID_X - 47.5) > 9) | (np.abs(GRID_Y - 35.5) > 7)
    assert not blurred.mixed[far].any()
    assert not blurred.mixed[(np.abs(GRID_X - 47.5) < 2) & rows].any()


def test_invalid_inputs():
    obj = _plane(_random_texture())
    with pytest.raises(ValueError, match="view"):
        render_instant([obj], CAMERA, "middle", SIZE, 0.0)
    with pytest.raises(ValueError, match="size"):
        cast_rays([obj], CAMERA, "left", (1, 5), 0.0)
    with pytest.raises(ValueError, match="num_samples"):
        render_blurred([obj], CAMERA, Exposure(20.0, 0.04), "left", SIZE, 0, num_samples=0)
    with pytest.raises(ValueError, match="origin"):
        PlanarObject(obj.normal, obj.twist, obj.texture, [0, 0, 1.0], obj.axes, 0.025)
    with pytest.raises(ValueError, match="points"):
        track([obj], CAMERA, "left", cast_rays([obj], CAMERA, "left", SIZE, 0, points=False), [1])
