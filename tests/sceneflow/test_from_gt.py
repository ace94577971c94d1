import numpy as np

from stereodeblur.geometry import StereoCamera, move_plane, plane_disparity, se3_exp
from stereodeblur.sceneflow.from_gt import sceneflow_from_gt, split_at_discontinuities
from stereodeblur.sceneflow.model import SceneFlow
from stereodeblur.sceneflow.superpixels import slic_segments

CAMERA = StereoCamera([[120.0, 0, 40], [0, 120.0, 30], [0, 0, 1]], 0.1)


def _truth(shape=(60, 80)):
    labels = np.zeros(shape, dtype=np.int32)
    labels[:, 40:] = 1
    normals = np.array([[0.02, -0.01, 0.33], [-0.03, 0.0, 0.4]])
    # The planes move apart (no occlusion at t + 1: occluded points have no true disparity).
    twists = np.array([[-0.05, 0.02, -0.1, 0.01, 0.03, -0.02], [0.04, 0.0, 0.08, 0.0, -0.02, 0.01]])
    return SceneFlow(CAMERA, labels, normals, twists, np.zeros(shape, bool))


def _next_disparity_map(truth):
    """Exact left disparity at t + 1: z-buffer of the moved planes, each where it came from."""
    H, W = truth.shape
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    out = np.full((H, W), np.nan)
    Hs = truth.homographies(np.array([1.0]))[:, 0]  # H_ref_from_t1 per plane
    for k in range(truth.num_segments):
        R, T = se3_exp(truth.twists[k])[:3, :3], se3_exp(truth.twists[k])[:3, 3]
        d = plane_disparity(CAMERA, move_plane(truth.normals[k], R, T), x, y)
        q = np.stack([x, y, np.ones_like(x)], -1) @ Hs[k].T
        xr, yr = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
        inside = (xr >= -0.5) & (xr < W - 0.5) & (yr >= -0.5) & (yr < H - 0.5)
        src = np.zeros((H, W), bool)
        src[inside] = (
            truth.labels[np.round(yr[inside]).astype(int), np.round(xr[inside]).astype(int)] == k
        )
        better = src & ~(out >= d)
        out[better] = d[better]
    return out


def test_fit_recovers_planes_and_motions():
    truth = _truth()
    d0 = truth.disparity()
    d1 = _next_disparity_map(truth)
    labels = (np.arange(80)[None, :] // 10).repeat(60, 0).astype(np.int32)  # 8 vertical strips
    fitted = sceneflow_from_gt(CAMERA, d0, d1, truth.flow(), labels)
    interior = np.zeros(truth.shape, bool)
    interior[5:-5, 5:-5] = True
    np.testing.assert_allclose(fitted.disparity()[interior], d0[interior], atol=1e-6)
    np.testing.assert_allclose(fitted.flow()[interior], truth.flow()[interior], atol=2e-3)
    for k in range(8):
        ref = truth.twists[0 if k < 4 else 1]
        np.testing.assert_allclose(fitted.twists[k], ref, atol=1e-3)


def test_superpixels_count():
    from skimage.data import astronaut
    from skimage.transform import resize

    img = resize(astronaut(), (60, 80), anti_aliasing=True).astype(np.float32)
    labels = slic_segments(img, 48)
    assert labels.min() == 0 and labels.max() + 1 == len(np.unique(labels))
    assert 20 <= labels.max() + 1 <= 100


def test_unknown_flow_is_occluded_not_an_error():
    truth = _truth()
    flow = truth.flow()
    flow[10:20, 10:20] = np.nan
    labels = (np.arange(80)[None, :] // 10).repeat(60, 0).astype(np.int32)
    fitted = sceneflow_from_gt(CAMERA, truth.disparity(), _next_disparity_map(truth), flow, labels)
    assert fitted.occlusion[10:20, 10:20].all()
    assert np.all(np.isfinite(fitted.twists))


def test_split_cuts_segments_at_jumps_and_merges_slivers():
    shape = (30, 40)
    labels = np.zeros(shape, np.int32)
    disparity = np.where(np.arange(40)[None, :] < 20, 5.0, 10.0) * np.ones(shape)
    flow = np.zeros((*shape, 2))
    flow[:, 20:, 0] = 2.0
    flow[10:12, 5:7, 0] = 1.0  # a 4-pixel sliver moving differently, inside the left part
    split = split_at_discontinuities(labels, disparity, flow)
    assert split.max() + 1 == 2
    assert np.all(split[:, :20] == split[0, 0]) and np.all(split[:, 20:] == split[0, 39])
    assert split[0, 0] != split[0, 39]


def test_background_covered_at_t1_keeps_its_own_motion():
    shape = (40, 80)
    labels = np.zeros(shape, dtype=np.int32)
    labels[:, 40:] = 1
    normals = np.array([[0.0, 0.0, 0.2], [0.0, 0.0, 0.5]])  # background 5 m, foreground 2 m
    twists = np.array([[0.0] * 6, [-0.1, 0.0, 0.0, 0.0, 0.0, 0.0]])  # foreground 6 px left
    truth = SceneFlow(CAMERA, labels, normals, twists, np.zeros(shape, bool))
    strips = (np.arange(80)[None, :] // 10).repeat(40, 0).astype(np.int32)
    fitted = sceneflow_from_gt(
        CAMERA, truth.disparity(), _next_disparity_map(truth), truth.flow(), strips
    )
    # Strip 3 (x = 30..39) is 60 % covered by the foreground at t + 1.
    np.testing.assert_allclose(fitted.twists[3], 0.0, atol=1e-6)
    np.testing.assert_allclose(fitted.twists[4], twists[1], atol=1e-6)


def test_a_segment_covered_entirely_at_t1_keeps_its_own_motion():
    """The foreground (x >= 40) moves 27 px left and covers strips 2 and 3 (x = 20..39)
    entirely at t + 1: they have no true disparity at t + 1, only their true flow."""
    shape = (40, 80)
    labels = np.zeros(shape, dtype=np.int32)
    labels[:, 40:] = 1
    normals = np.array([[0.0, 0.0, 0.2], [0.0, 0.0, 0.5]])  # background 5 m, foreground 2 m
    twists = np.array([[0.0] * 6, [-0.45, 0.0, 0.0, 0.0, 0.0, 0.0]])
    truth = SceneFlow(CAMERA, labels, normals, twists, np.zeros(shape, bool))
    d1 = _next_disparity_map(truth)
    assert np.all(d1[:, 20:40] == 6.0)  # the foreground's disparity at t + 1
    strips = (np.arange(80)[None, :] // 10).repeat(40, 0).astype(np.int32)
    fitted = sceneflow_from_gt(CAMERA, truth.disparity(), d1, truth.flow(), strips)
    np.testing.assert_allclose(fitted.twists[2:4], 0.0, atol=1e-6)
    np.testing.assert_allclose(fitted.flow(), truth.flow(), atol=1e-4)


def test_a_steep_smooth_flow_is_one_surface():
    """A ground plane under fast forward motion: its flow grows by more than 1 px per pixel
    towards the image bottom, smoothly; it is not cut, and its motion is recovered."""
    shape = (60, 80)
    camera = StereoCamera([[120.0, 0, 40], [0, 120.0, -10], [0, 0, 1]], 0.1)  # looks down
    normals = np.array([[0.0, 1 / 1.5, 0.0]])  # the road, 1.5 m below the camera
    twists = np.array([[0.0, 0.0, -0.8, 0.0, 0.0, 0.0]])  # 0.8 m forward per frame
    truth = SceneFlow(camera, np.zeros(shape, np.int32), normals, twists, np.zeros(shape, bool))
    flow = truth.flow()
    assert np.abs(np.diff(flow[..., 1], axis=0)).max() > 1.0
    blocks = ((np.arange(60)[:, None] // 15) * 4 + np.arange(80)[None, :] // 20).astype(np.int32)
    split = split_at_discontinuities(blocks, truth.disparity(), flow)
    assert split.max() + 1 == 16
    fitted = sceneflow_from_gt(camera, truth.disparity(), np.full(shape, np.nan), flow, split)
    np.testing.assert_allclose(fitted.flow(), flow, atol=1e-3)


def test_small_patches_keep_their_pose():
    """Small segments of a plane under forward motion: each projects almost alike under
    a second pose (tilted, about 1 rad of rotation); their points seen at t + 1 decide."""
    shape = (60, 80)
    labels = np.zeros(shape, dtype=np.int32)
    normals = np.array([[-0.016, -0.0096, 1 / 3]])
    twists = np.array([[0.0, 0.0, -0.12, 0.0, 0.0, 0.0]])
    truth = SceneFlow(CAMERA, labels, normals, twists, np.zeros(shape, bool))
    blocks = ((np.arange(60)[:, None] // 6) * 10 + np.arange(80)[None, :] // 8).astype(np.int32)
    fitted = sceneflow_from_gt(
        CAMERA, truth.disparity(), _next_disparity_map(truth), truth.flow(), blocks
    )
    np.testing.assert_allclose(fitted.twists, np.repeat(twists, 100, axis=0), atol=1e-4)
