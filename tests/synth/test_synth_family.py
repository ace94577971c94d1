import json

import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.errors import InputError
from stereodeblur.geometry import Exposure
from stereodeblur.io.scene import open_scene
from stereodeblur.synth.blurlength import longest_blur, scale_for_blur
from stereodeblur.synth.family import (
    BLUR_RANGE,
    NOISE_MAX,
    family_scene,
    family_setup,
    seeds_of,
    split,
    write_family_scene,
)
from stereodeblur.synth.patterns import TEXTURE_KINDS, SurfaceTexture, make_texture
from stereodeblur.synth.planar import planar_camera
from stereodeblur.synth.render import PlanarObject, cast_rays
from stereodeblur.synth.street import street_scene

SMALL = (80, 60)
TINY = (64, 48)


@pytest.fixture(scope="module")
def specs():
    family = [family_scene(seed, size=SMALL) for seed in range(20)]
    street = [street_scene(seed, size=SMALL) for seed in (0, 1, 1000, 1001)]
    return family, street


def test_split_rule_is_fixed():
    assert [split(s) for s in (0, 1, 999, 1000, 1049, 1999)] == ["train"] * 3 + ["test"] * 3
    for bad in (-1, 2000, 1.5, True):
        with pytest.raises(InputError, match="seed"):
            split(bad)
    assert seeds_of("train", 3) == [0, 1, 2] and seeds_of("test", 2) == [1000, 1001]
    with pytest.raises(InputError, match="split"):
        seeds_of("validation", 3)


def test_specs_are_deterministic_and_carry_their_split(specs):
    family, street = specs
    assert family_scene(5, size=SMALL) == family[5]
    assert street_scene(1001, size=SMALL) == street[3]
    assert family[0] != family[1]
    assert {s.split for s in street} == {"train", "test"}
    assert all(s.split == split(s.seed) for s in family + street)
    assert family_scene(1003, size=SMALL).split == "test"


def test_family_covers_the_required_ranges(specs):
    family, street = specs
    blurs = [s.blur_px for s in family + street]
    low, high = BLUR_RANGE
    assert all(low <= b <= high for b in blurs)
    assert min(blurs) < 10 and max(blurs) > 50
    for s in family + street:
        assert s.blur_px == pytest.approx(s.blur_target, rel=0.01)
    noises = [s.noise for s in family + street]
    assert all(0 <= n <= NOISE_MAX for n in noises)
    assert 0.0 in noises and max(noises) > 0.015
    textures = [t for s in family for t in s.textures()]
    assert {t.kind for t in textures} == set(TEXTURE_KINDS)
    periods = [t.period for t in textures if t.kind in ("stripes", "hatching")]
    angles = {round(np.degrees(t.angle) / 30) for t in textures if t.kind == "stripes"}
    assert min(periods) >= 2 and max(periods) <= 8 and max(periods) - min(periods) > 3
    assert len(angles) >= 3
    # Camera motions: forward (z), roll (wz), yaw (wy) and lateral (x) components, combined.
    twists = np.array([s.camera_twist for s in family])
    for axis in (0, 2, 4, 5):
        assert np.count_nonzero(twists[:, axis]) >= 3
    assert max(np.count_nonzero(t[[0, 2, 4, 5]]) for t in twists) >= 3
    assert any(any(p.solid.velocity != (0.0, 0.0, 0.0) for p in s.parts) for s in family)
    assert all(s.camera_twist[2] > 0 for s in street)  # driving forward
    assert {s.kind for s in street} == {"street"}


def test_stripes_have_their_period_and_patterns_stay_in_range():
    texture = SurfaceTexture("stripes", period=4.0, angle=0.0, level=0.5, contrast=0.8)
    image = make_texture(texture, 256, 8)
    profile = image[4, :, 0] - image[4, :, 0].mean()
    peak = np.argmax(np.abs(np.fft.rfft(profile)))
    assert 256 / peak == pytest.approx(4.0)
    for kind in TEXTURE_KINDS:
        extra = {"photo": "brick"} if kind in ("photo", "bright") else {}
        level, contrast = (0.9, 0.1) if kind == "bright" else (0.5, 0.02 if kind == "flat" else 0.8)
        spec = SurfaceTexture(kind, period=3.0, level=level, contrast=contrast, seed=1, **extra)
        image = make_texture(spec, 40, 30)
        assert image.shape == (30, 40, 3) and image.dtype == np.float32
        assert 0 <= image.min() and image.max() <= 1
    with pytest.raises(InputError, match="kind"):
        SurfaceTexture("plaid")


def test_longest_blur_of_a_sideways_translation_and_its_scale():
    size, depth, speed, duty = (80, 60), 2.0, 0.05, 0.8
    camera = planar_camera(size)
    normal = np.array([0.0, 0.0, 1.0 / depth])
    axes = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    plane = PlanarObject(
        normal, [speed, 0, 0, 0, 0, 0], np.zeros((4, 4, 3)), [0, 0, depth], axes, 0.1
    )
    expected = camera.fx * speed * duty / depth
    assert longest_blur([plane], camera, size, duty) == pytest.approx(expected, rel=1e-6)
    k, blur = scale_for_blur([plane], camera, size, duty, 30.0)
    assert k == pytest.approx(30.0 / expected, rel=0.003) and blur == pytest.approx(30, rel=0.003)


def _write(spec, root, samples=3):
    return write_family_scene(spec, root, num_samples=samples)


def test_tiny_render_is_a_valid_scene_and_writing_is_deterministic(tmp_path):
    spec = family_scene(2, size=TINY)
    first = _write(spec, tmp_path / "a")
    second = _write(spec, tmp_path / "b")
    files = sorted(p.relative_to(first) for p in first.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(second) for p in second.rglob("*") if p.is_file())
    for name in files:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    scene = open_scene(first)
    assert scene.num_frames == 3
    for kind in ("sharp", "disparity", "mixed"):
        assert scene.has_gt(kind, "left", 1) and scene.has_gt(kind, "right", 1)
    assert scene.has_gt("flow", "left", 0) and scene.has_gt("flow", "left", 1)
    record = json.loads((first / "gt" / "family.json").read_text())
    assert record["name"] == "family_0002" and record["blur_px"] == spec.blur_px
    with pytest.raises(InputError, match="exists"):
        _write(spec, first)
    assert not (tmp_path / "a.partial").exists()


def _coordinates_at(hits, ids, x, y):
    """Texture coordinates bilinearly interpolated at (x, y) where all four taps see ``ids``."""
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    h, w = hits.object_id.shape
    inside = (x0 >= 0) & (y0 >= 0) & (x0 < w - 1) & (y0 < h - 1)
    x0, y0 = np.clip(x0, 0, w - 2), np.clip(y0, 0, h - 2)
    same = inside.copy()
    for dy in (0, 1):
        for dx in (0, 1):
            same &= hits.object_id[y0 + dy, x0 + dx] == ids
    values = []
    for field in (hits.texture_u, hits.texture_v):
        values.append(ndimage.map_coordinates(np.nan_to_num(field), [y, x], order=1))
        taps = [field[y0 + dy, x0 + dx] for dy in (0, 1) for dx in (0, 1)]
        same &= np.ptp(taps, axis=0) < 3  # no texture seam between the taps
    return same, values


@pytest.mark.parametrize("maker,seed", [(family_scene, 3), (street_scene, 4)])
def test_gt_flow_and_disparity_follow_the_rendered_surfaces(tmp_path, maker, seed):
    spec = maker(seed, size=TINY)
    scene = open_scene(_write(spec, tmp_path / "s", samples=2))
    setup = family_setup(spec)
    camera = setup.camera
    assert scene.info.exposure == Exposure(20.0, spec.duty_cycle / 20.0)
    now = cast_rays(setup.objects, camera, "left", TINY, 1.0)
    later = cast_rays(setup.objects, camera, "left", TINY, 2.0)
    right = cast_rays(setup.objects, camera, "right", TINY, 1.0)
    y, x = np.mgrid[0 : TINY[1], 0 : TINY[0]].astype(np.float64)
    flow = scene.read_gt_flow("left", 1)
    disparity = scene.read_gt_disparity("left", 1)
    checks = [
        (later, x + flow[..., 0], y + flow[..., 1]),  # the point seen at frame 2's centre
        (right, x - disparity, y),  # the point seen in the right view
    ]
    for hits, tx, ty in checks:
        same, (u, v) = _coordinates_at(hits, now.object_id, tx, ty)
        assert same.mean() > 0.3
        error = np.hypot(u - now.texture_u, v - now.texture_v)[same]
        # A few pixels see another face of the same object there (self-occlusion, box edges).
        assert np.mean(error < 0.05) > 0.97 and np.median(error) < 0.01
    sharp = scene.read_gt_sharp("left", 1)
    assert sharp.shape == (TINY[1], TINY[0], 3) and sharp.max() > 0
