import json

import numpy as np
import pytest

from stereodeblur.geometry import StereoCamera, se3_exp, so3_exp
from stereodeblur.synth.objects import (
    NOISE_SIGMA,
    OBJECT_SCENES,
    add_noise,
    make_object_scene,
    object_setup,
    write_object_set,
)
from stereodeblur.synth.render import (
    BoxObject,
    CylinderObject,
    SphereObject,
    cast_rays,
    periodic_texture,
    render_blurred,
)

SIZE = (96, 72)
CAMERA = StereoCamera([[80.0, 0, 47.5], [0, 80.0, 35.5], [0, 0, 1]], 0.12)
TWIST = np.array([0.04, -0.02, -0.05, 0.1, -0.15, 0.2])
FRAME = so3_exp(np.array([0.3, -0.2, 0.5]))


def _texture(shape=(20, 30), seed=0):
    rng = np.random.default_rng(seed)
    return periodic_texture(rng.random(shape + (3,)).astype(np.float32))


def _rays(view):
    y, x = np.mgrid[0 : SIZE[1], 0 : SIZE[0]].astype(np.float64)
    return np.stack([x, y, np.ones_like(x)], -1) @ CAMERA.K_inv.T, CAMERA.center(view)


@pytest.mark.parametrize("view", ["left", "right"])
@pytest.mark.parametrize("fraction", [0.0, 0.7])
def test_sphere_depth_is_the_analytic_ray_sphere_intersection(view, fraction):
    center, radius = np.array([0.1, -0.05, 2.0]), 0.45
    sphere = SphereObject(center, radius, FRAME, TWIST, _texture())
    full = cast_rays([sphere], CAMERA, view, SIZE, fraction)
    depth, ids, points = full.depth[::3, ::3], full.object_id[::3, ::3], full.points[::3, ::3]
    # The sphere's centre at that instant; ray C + Z d with d = K^-1 (x, y, 1).
    M = se3_exp(fraction * TWIST)
    c = M[:3, :3] @ center + M[:3, 3] - CAMERA.center(view)
    d, _ = _rays(view)
    d = d[::3, ::3]  # every third pixel
    expected = np.full(d.shape[:2], np.inf)
    for i, j in np.ndindex(*expected.shape):
        roots = np.roots([d[i, j] @ d[i, j], -2 * d[i, j] @ c, c @ c - radius**2])
        real = roots[np.isreal(roots)].real
        if real.size and real.min() > 0:
            expected[i, j] = real.min()
    seen = np.isfinite(expected)
    assert 0.1 < seen.mean() < 0.9
    # Silhouette pixels graze the sphere: a disagreement there is rounding only.
    grazing = np.abs(np.linalg.norm(np.cross(d, c), axis=-1) / np.linalg.norm(d, axis=-1) - radius)
    agree = np.isfinite(depth) == seen
    assert np.all(agree | (grazing < 1e-9))
    both = seen & np.isfinite(depth)
    np.testing.assert_allclose(depth[both], expected[both], rtol=1e-9)
    assert np.all(ids[seen & agree] == 0) and np.all(ids[~seen & agree] == -1)
    # The hit points, moved back to the reference pose, lie on the reference sphere.
    np.testing.assert_allclose(np.linalg.norm(points[both] - center, axis=-1), radius)


def test_cylinder_and_box_hits_lie_on_their_surfaces():
    cylinder = CylinderObject([0.3, 0.0, 2.5], 0.3, 0.4, FRAME, TWIST, _texture())
    box_texture = np.random.default_rng(1).random((30, 30, 3)).astype(np.float32)
    box = BoxObject([-0.4, 0.1, 2.2], [0.2, 0.3, 0.25], FRAME.T, TWIST, box_texture, 0.02)
    for obj in (cylinder, box):
        hits = cast_rays([obj], CAMERA, "left", SIZE, 0.4)
        hit = np.isfinite(hits.depth)
        assert hit.mean() > 0.05
        local = (hits.points[hit] - obj.center) @ obj.frame  # local coordinates
        if obj is cylinder:
            side = np.abs(np.hypot(local[:, 0], local[:, 1]) - 0.3) < 1e-9
            cap = np.abs(np.abs(local[:, 2]) - 0.4) < 1e-9
            assert np.all(side | cap) and side.any() and cap.any()
            assert np.all(np.abs(local[:, 2]) <= 0.4 + 1e-9)
        else:
            assert np.allclose(np.max(np.abs(local) / obj.half_sizes, axis=1), 1.0)
        # A ray through a pixel just outside the image of the solid misses it: the
        # hits are the nearest intersection, so the depth is below the centre's.
        M = se3_exp(0.4 * TWIST)
        centre_depth = (M[:3, :3] @ obj.center + M[:3, 3])[2]
        assert np.median(hits.depth[hit]) < centre_depth


def _small_scene(name="spheres", **kw):
    return make_object_scene(name, size=(64, 48), num_samples=12, **kw)


def test_mixed_is_exactly_where_the_object_changes_during_the_exposure():
    setup = object_setup("squares", size=(64, 48))
    blurred = render_blurred(
        setup.objects, setup.camera, setup.exposure, "left", setup.size, 1, num_samples=12
    )
    ids = np.stack(
        [
            cast_rays(setup.objects, setup.camera, "left", setup.size, s, points=False).object_id
            for s in 1 + setup.exposure.sample_fractions(12)
        ]
    )
    expected = np.any(ids != ids[:1], axis=0)
    np.testing.assert_array_equal(blurred.mixed, expected)
    assert 0 < expected.mean() < 0.3


def test_flow_of_a_point_on_a_moving_object_is_its_tracked_projection():
    scene = _small_scene("spheres")
    setup = object_setup("spheres", size=(64, 48))
    ids = scene.object_ids["left"][0]
    sphere = setup.objects[1]
    assert isinstance(sphere, SphereObject)
    ys, xs = np.nonzero(ids == 1)
    assert ys.size > 20
    for y, x in zip(ys[::7], xs[::7], strict=False):
        # The visible point of the sphere at pixel (x, y) at instant 0, analytically.
        d = setup.camera.K_inv @ np.array([x, y, 1.0])
        c = sphere.center
        b = d @ c
        Z = (b - np.sqrt(b * b - (d @ d) * (c @ c - sphere.radius**2))) / (d @ d)
        P = Z * d
        M = se3_exp(sphere.twist)  # one frame interval later
        q = setup.camera.K @ (M[:3, :3] @ P + M[:3, 3])
        expected = q[:2] / q[2] - [x, y]
        np.testing.assert_allclose(scene.flow[0][y, x], expected, atol=1e-4)
        disparity = setup.camera.fx * setup.camera.baseline / Z
        assert scene.disparity["left"][0][y, x] == pytest.approx(disparity, rel=1e-5)


def test_noise_variant_differs_only_by_the_seeded_noise():
    clean = _small_scene("cylinder_mix")
    noisy = _small_scene("cylinder_mix_noisy", seed=3)
    assert noisy.name == "cylinder_mix_noisy"
    for key in ("sharp", "disparity", "mixed", "object_ids"):
        for view in ("left", "right"):
            for a, b in zip(getattr(clean, key)[view], getattr(noisy, key)[view], strict=True):
                np.testing.assert_array_equal(a, b)
    for a, b in zip(clean.flow, noisy.flow, strict=True):
        np.testing.assert_array_equal(a, b)
    rng = np.random.default_rng(3)
    for view in ("left", "right"):
        for a, b in zip(clean.frames[view], noisy.frames[view], strict=True):
            expected = np.clip(a + NOISE_SIGMA * rng.standard_normal(a.shape), 0, 1)
            np.testing.assert_allclose(b, expected, atol=1e-6)
            inside = (expected > 0) & (expected < 1)
            assert np.std((b - a)[inside]) == pytest.approx(NOISE_SIGMA, rel=0.1)
    other = add_noise(clean, NOISE_SIGMA, seed=4)
    assert not np.array_equal(other.frames["left"][0], noisy.frames["left"][0])


@pytest.mark.parametrize("name", list(OBJECT_SCENES))
def test_every_scene_has_several_moving_objects_and_a_curved_one_somewhere(name):
    setup = object_setup(name, size=(64, 48))
    assert len(setup.objects) >= 4
    hits = cast_rays(setup.objects, setup.camera, "left", setup.size, 1.0, points=False)
    seen = np.unique(hits.object_id)
    assert -1 not in seen and len(seen) == len(setup.objects)
    twists = {tuple(np.round(o.twist, 9)) for o in setup.objects[1:]}
    assert len(twists) == len(setup.objects) - 1  # independent motions


def test_write_object_set_writes_clean_and_noisy_scenes(tmp_path):
    from stereodeblur.io.scene import open_scene

    paths = write_object_set(tmp_path, size=(48, 32), names=["boxes"], num_samples=4)
    assert [p.name for p in paths] == ["boxes", "boxes_noisy"]
    clean, noisy = open_scene(paths[0]), open_scene(paths[1])
    assert clean.num_frames == noisy.num_frames == 3
    assert clean.has_gt("mixed", "left", 1) and clean.has_gt("flow", "left", 1)
    np.testing.assert_array_equal(clean.read_gt_sharp("left", 1), noisy.read_gt_sharp("left", 1))
    assert not np.array_equal(clean.read_frame("left", 1), noisy.read_frame("left", 1))
    objects = json.loads((paths[0] / "gt" / "objects.json").read_text())["objects"]
    assert [o["kind"] for o in objects[1:]] == ["box", "box", "box"]
    assert "normal" in objects[0] and objects[0]["name"] == "background"


def test_unknown_scene_and_bad_solids_are_rejected():
    with pytest.raises(ValueError, match="unknown object scene"):
        object_setup("teapot")
    with pytest.raises(ValueError, match="radius"):
        SphereObject([0, 0, 2], -1.0, np.eye(3), np.zeros(6), _texture())
    with pytest.raises(ValueError, match="rotation"):
        SphereObject([0, 0, 2], 1.0, -np.eye(3), np.zeros(6), _texture())
    with pytest.raises(ValueError, match="half_sizes"):
        BoxObject([0, 0, 2], [0.1, 0, 0.1], np.eye(3), np.zeros(6), _texture(), 0.01)
