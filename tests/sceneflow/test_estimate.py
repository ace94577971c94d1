import numpy as np
import pytest
from scipy import ndimage

from stereodeblur.errors import InputError
from stereodeblur.geometry import se3_exp, so3_log
from stereodeblur.progress import Progress
from stereodeblur.sceneflow import SceneFlowEstimate, SceneFlowWarning, estimate_scene_flow
from stereodeblur.sceneflow.settings import SceneFlowSettings

from .scenes import CAMERA, SIZE, frames, render_views

NORMAL = np.array([0.12, -0.08, 0.5])  # tilted by about 16 degrees, 2 m away
TWIST = np.array([0.06, -0.03, -0.1, 0.01, 0.02, -0.01])


@pytest.fixture(scope="module")
def moving_plane():
    views = render_views(NORMAL, TWIST, num_instants=9)
    return estimate_scene_flow(*frames(views), CAMERA, seed=0)


def test_single_moving_plane_recovers_normal_and_motion(moving_plane):
    est = moving_plane
    assert isinstance(est, SceneFlowEstimate)
    assert est.warnings == ()
    sf = est.sceneflow
    sizes = np.bincount(sf.labels.ravel(), minlength=sf.num_segments)
    cos = sf.normals @ NORMAL / (np.linalg.norm(sf.normals, axis=1) * np.linalg.norm(NORMAL))
    normal_deg = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    M = se3_exp(TWIST)
    M_est = se3_exp(sf.twists)
    rotation_deg = np.degrees(np.linalg.norm(so3_log(M_est[:, :3, :3] @ M[:3, :3].T), axis=1))
    translation = np.linalg.norm(M_est[:, :3, 3] - M[:3, 3], axis=1) / np.linalg.norm(M[:3, 3])
    # Every pixel's segment, except at most 5 % (e.g. at the border where content leaves).
    good = (normal_deg < 1.0) & (rotation_deg < 1.0) & (translation < 0.02)
    assert sizes[good].sum() >= 0.95 * sizes.sum()


def test_single_moving_plane_dense_maps(moving_plane):
    from stereodeblur.sceneflow.model import SceneFlow

    truth = SceneFlow(
        CAMERA, np.zeros(SIZE, np.int32), NORMAL[None], TWIST[None], np.zeros(SIZE, bool)
    )
    sf = moving_plane.sceneflow
    assert np.abs(sf.disparity() - truth.disparity()).mean() < 0.1
    assert np.linalg.norm(sf.flow() - truth.flow(), axis=-1).mean() < 0.1
    assert moving_plane.initial_flow.shape == SIZE + (2,)
    assert moving_plane.initial_disparity.shape == SIZE
    assert moving_plane.initial_disparity_next.shape == SIZE
    assert set(moving_plane.timings) >= {"initial", "fusion", "refine"}
    # The occlusion mask is mostly the content leaving the view at the borders.
    assert sf.occlusion.mean() < 0.3


def _texture(shape, seed=0):
    rng = np.random.default_rng(seed)
    t = ndimage.gaussian_filter(rng.random(shape), 1.2)
    return ((t - t.min()) / (t.max() - t.min())).astype(np.float32)


def test_constant_horizontal_shift_gives_that_disparity_everywhere():
    tex = _texture((SIZE[0], SIZE[1] + 40))
    left, right = tex[:, 20 : 20 + SIZE[1]], tex[:, 25 : 25 + SIZE[1]]  # disparity 5 px
    with pytest.warns(SceneFlowWarning, match="identical"):
        est = estimate_scene_flow(left, right, left, right, CAMERA)
    d = est.sceneflow.disparity()
    assert np.abs(d - 5.0).max() < 0.25
    assert np.abs(d - 5.0).mean() < 0.05
    assert np.abs(est.sceneflow.flow()).max() < 0.1  # same frames: no motion


DEGENERATE = {
    "textureless": (lambda: [np.full(SIZE, 0.5, np.float32)] * 4, "textureless"),
    "black": (lambda: [np.zeros(SIZE + (3,), np.float32)] * 4, "textureless"),
    "identical": (lambda: [_texture(SIZE, 3)] * 4, "identical"),
    "no overlap": (
        lambda: [
            _texture(SIZE, 1),
            np.roll(_texture(SIZE, 1), -3, 1),
            _texture(SIZE, 2),
            np.roll(_texture(SIZE, 2), -3, 1),
        ],
        "overlap",
    ),
}


@pytest.mark.parametrize("case", list(DEGENERATE))
def test_degenerate_input_gives_a_finite_result_and_a_warning(case):
    make, pattern = DEGENERATE[case]
    with pytest.warns(SceneFlowWarning) as caught:  # several may apply; all are collected
        est = estimate_scene_flow(*make(), CAMERA)
    sf = est.sceneflow
    assert any(pattern in w for w in est.warnings)
    assert [str(w.message) for w in caught] == list(est.warnings)
    for array in (sf.normals, sf.twists, sf.disparity(), sf.flow(), sf.disparity_next()):
        assert np.all(np.isfinite(array))
    assert np.all(sf.disparity() > 0)


def test_bad_input_is_rejected():
    image = np.zeros(SIZE, np.float32)
    with pytest.raises(InputError, match="right_t"):
        estimate_scene_flow(image, np.zeros((10, 10)), image, image, CAMERA)
    with pytest.raises(InputError, match="left_next"):
        estimate_scene_flow(image, image, np.full(SIZE, np.nan), image, CAMERA)
    with pytest.raises(InputError, match="camera"):
        estimate_scene_flow(image, image, image, image, "camera")
    with pytest.raises(InputError, match="num_segments"):
        estimate_scene_flow(image, image, image, image, CAMERA, num_segments=0)
    with pytest.raises(InputError, match="settings"):
        estimate_scene_flow(image, image, image, image, CAMERA, settings={"smoothness": 1.0})


def test_settings_reach_the_stages():
    tex = _texture((SIZE[0], SIZE[1] + 20), 5)
    frames = tex[:, 10 : 10 + SIZE[1]], tex[:, 13 : 13 + SIZE[1]]
    frames += tex[:, 12 : 12 + SIZE[1]], tex[:, 15 : 15 + SIZE[1]]
    few = estimate_scene_flow(*frames, CAMERA, settings=SceneFlowSettings(num_segments=12))
    many = estimate_scene_flow(*frames, CAMERA, settings=SceneFlowSettings(num_segments=60))
    assert len(np.unique(few.sceneflow.labels)) < len(np.unique(many.sceneflow.labels))
    # The keyword overrides the settings' count.
    same = estimate_scene_flow(
        *frames, CAMERA, settings=SceneFlowSettings(num_segments=60), num_segments=12
    )
    assert np.array_equal(same.sceneflow.labels, few.sceneflow.labels)


def test_progress_and_debug_pictures(tmp_path):
    from stereodeblur.io.formats import read_png

    tex = _texture((SIZE[0], SIZE[1] + 20), 5)
    left, right = tex[:, 10 : 10 + SIZE[1]], tex[:, 13 : 13 + SIZE[1]]
    left1, right1 = tex[:, 12 : 12 + SIZE[1]], tex[:, 15 : 15 + SIZE[1]]
    calls = []
    estimate_scene_flow(
        left,
        right,
        left1,
        right1,
        CAMERA,
        progress=calls.append,
        debug_dir=tmp_path,
    )
    assert all(isinstance(p, Progress) and p.stage.startswith("scene flow: ") for p in calls)
    assert [p.done for p in calls] == list(range(1, len(calls) + 1))
    assert calls[-1].done == calls[-1].total == 8
    for name in ("segments", "disparity", "flow", "occlusion", "initial_flow"):
        picture = read_png(tmp_path / f"{name}.png")
        # The picture of the frame's size under a caption strip.
        assert picture.shape[0] > SIZE[0] and picture.shape[1:] == (SIZE[1], 3)
