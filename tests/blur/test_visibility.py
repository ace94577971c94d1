"""The segment each pixel shows at each instant (occlusion-aware blur operator)."""

import numpy as np
import pytest

from stereodeblur.blur.homography import homography_blur, homography_blur_reference
from stereodeblur.blur.visibility import HIDDEN, hidden_fraction, sceneflow_visibility
from stereodeblur.sceneflow.model import SceneFlow

from .scenes import EXPOSURE, camera, random_sceneflow, translation_sceneflow

SHAPE = (40, 56)
ROWS, COLS = slice(10, 30), (20, 35)  # the near rectangle at the reference instant


def _rectangle_over_background(flow_px: float) -> SceneFlow:
    """A static background at depth 4 and a rectangle at depth 2 moving ``flow_px`` to the right."""
    cam = camera(SHAPE)
    labels = np.zeros(SHAPE, np.int32)
    labels[ROWS, COLS[0] : COLS[1] + 1] = 1
    normals = np.array([[0, 0, 1 / 4.0], [0, 0, 1 / 2.0]])
    velocity = flow_px * 2.0 / cam.K[0, 0]
    twists = np.array([np.zeros(6), [velocity, 0, 0, 0, 0, 0]])
    return SceneFlow(cam, labels, normals, twists, np.zeros(SHAPE, bool))


@pytest.mark.parametrize("flow_px", [8.0, -5.0])
def test_moving_rectangle_covers_and_uncovers_the_background(flow_px):
    sf = _rectangle_over_background(flow_px)
    num_samples = 9
    visible = sceneflow_visibility(sf, EXPOSURE, num_samples)
    assert visible.shape == (num_samples,) + SHAPE
    x = np.arange(SHAPE[1])
    expected = np.zeros((num_samples,) + SHAPE, np.int32)
    for k, s in enumerate(EXPOSURE.sample_fractions(num_samples)):
        source = np.floor(x - s * flow_px + 0.5)  # reference column the rectangle shows at x
        on_rectangle = (source >= COLS[0]) & (source <= COLS[1])
        was_rectangle = (x >= COLS[0]) & (x <= COLS[1])
        expected[k, ROWS] = np.where(on_rectangle, 1, np.where(was_rectangle, HIDDEN, 0))
    np.testing.assert_array_equal(visible, expected)
    # The trailing edge uncovers background for up to half the exposure, the leading edge
    # is swept over the background.
    share = hidden_fraction(visible)
    trailing = COLS[0] if flow_px > 0 else COLS[1]
    assert 0.3 < share[20, trailing] <= 0.5
    assert share[20, (COLS[0] + COLS[1]) // 2] == 0
    leading = COLS[1] + 1 if flow_px > 0 else COLS[0] - 1
    assert 0.3 < np.mean(visible[:, 20, leading] == 1) <= 0.5


@pytest.mark.parametrize("offset", [1.0, -1.0])
def test_another_frames_exposure_shows_what_the_reference_frame_covers(offset):
    """The rectangle's exposure one frame later (or earlier), seen from the reference frame:
    the background it uncovers there is hidden, wherever it is at that frame."""
    flow_px = 6.0
    sf = _rectangle_over_background(flow_px)
    num_samples = 9
    own = np.zeros(SHAPE, np.int32)  # the segments at the other frame's centre
    own[ROWS, COLS[0] + int(offset * flow_px) : COLS[1] + int(offset * flow_px) + 1] = 1
    visible = sceneflow_visibility(sf, EXPOSURE, num_samples, offset=offset, own=own)
    x = np.arange(SHAPE[1])
    expected = np.zeros((num_samples,) + SHAPE, np.int32)
    for k, s in enumerate(offset + EXPOSURE.sample_fractions(num_samples)):
        source = np.floor(x - s * flow_px + 0.5)
        on_rectangle = (source >= COLS[0]) & (source <= COLS[1])
        was_rectangle = (x >= COLS[0]) & (x <= COLS[1])
        expected[k, ROWS] = np.where(on_rectangle, 1, np.where(was_rectangle, HIDDEN, 0))
    np.testing.assert_array_equal(visible, expected)
    uncovered = COLS[0] + 2 if offset > 0 else COLS[1] - 2  # behind it, throughout
    assert hidden_fraction(visible)[20, uncovered] == 1


def test_content_from_outside_the_reference_frame_is_hidden_in_another_frame():
    sf = translation_sceneflow(SHAPE, (0.4, 0.0))  # about 10 px to the right per frame
    shift = sf.flow()[0, 0, 0]
    own = np.zeros(SHAPE, np.int32)
    visible = sceneflow_visibility(sf, EXPOSURE, 9, offset=1.0, own=own)
    entering = np.arange(SHAPE[1]) < shift - EXPOSURE.duty_cycle * shift / 2 - 1
    assert np.all(visible[:, :, entering] == HIDDEN)
    inside = np.arange(SHAPE[1]) > shift + EXPOSURE.duty_cycle * shift / 2 + 1
    assert np.all(visible[:, :, inside] == 0)
    assert np.all(sceneflow_visibility(sf, EXPOSURE, 9) == 0)  # its own exposure: the edge's


def test_a_single_surface_shows_itself_and_gives_the_papers_operator():
    sf = translation_sceneflow(SHAPE, (0.4, -0.2))
    visible = sceneflow_visibility(sf, EXPOSURE, 15)
    assert np.all(visible == 0)
    layered = homography_blur(sf, EXPOSURE, num_samples=15, visible=visible).matrix
    paper = homography_blur(sf, EXPOSURE, num_samples=15).matrix
    assert abs(layered - paper).max() == 0


@pytest.mark.parametrize("view", ["left", "right"])
def test_layered_operator_equals_numpy_reference(view):
    sf = random_sceneflow(SHAPE, 3, view=view, grid=(3, 4), speed=2.0)
    visible = sceneflow_visibility(sf, EXPOSURE, 20)
    assert np.any((visible != sf.labels) & (visible != HIDDEN))  # segments do sweep
    assert np.any(visible == HIDDEN)
    fast = homography_blur(sf, EXPOSURE, num_samples=20, visible=visible).matrix
    slow = homography_blur_reference(sf, EXPOSURE, num_samples=20, visible=visible).matrix
    assert abs(fast - slow).max() < 1e-6
    assert abs(fast - homography_blur(sf, EXPOSURE, num_samples=20).matrix).max() > 0.1


def test_visibility_is_deterministic_and_thread_independent(monkeypatch):
    import numba

    sf = random_sceneflow(SHAPE, 4, grid=(3, 4), speed=2.0)
    first = sceneflow_visibility(sf, EXPOSURE, 12)
    monkeypatch.setattr(numba, "get_num_threads", lambda: 1)
    np.testing.assert_array_equal(sceneflow_visibility(sf, EXPOSURE, 12), first)


def test_visible_is_checked():
    sf = translation_sceneflow(SHAPE, (0.4, 0.0))
    with pytest.raises(ValueError, match="visible has shape"):
        homography_blur(sf, EXPOSURE, num_samples=5, visible=np.zeros((4,) + SHAPE, np.int16))
    for bad in (np.ones((5,) + SHAPE, np.int16), np.full((5,) + SHAPE, -2), np.zeros((5,) + SHAPE)):
        with pytest.raises(ValueError, match="segment labels"):
            homography_blur(sf, EXPOSURE, num_samples=5, visible=bad)
    as_int64 = homography_blur(sf, EXPOSURE, num_samples=5, visible=np.zeros((5,) + SHAPE, int))
    assert abs(as_int64.matrix - homography_blur(sf, EXPOSURE, num_samples=5).matrix).max() == 0


def _visible_by_definition(ref_from_t, labels, inverse_depth, own):
    """The module's rule in plain Python: per instant a forward z-buffer of every reference
    pixel, then per pixel its own segment and the splatted segments of its 3 x 3
    neighbourhood; the nearest that covers it (its reference pixel is the segment's) wins,
    the first of equals; outside the reference image only the own segment, and only when
    ``own`` is None."""
    t_from_ref = np.linalg.inv(ref_from_t)
    height, width = labels.shape
    own_labels = labels if own is None else own

    def mapped(h, x, y):
        q = h @ np.array([x, y, 1.0])
        return q[0] / q[2], q[1] / q[2]

    def depth(s, px, py):
        return inverse_depth[s] @ np.array([px, py, 1.0])

    out = np.empty((ref_from_t.shape[1], height, width), np.int64)
    for t in range(ref_from_t.shape[1]):
        nearest, splat = np.full(labels.shape, -np.inf), np.full(labels.shape, HIDDEN)
        for y in range(height):
            for x in range(width):
                s = labels[y, x]
                qx, qy = mapped(t_from_ref[s, t], x, y)
                ix, iy = int(np.floor(qx + 0.5)), int(np.floor(qy + 0.5))
                if 0 <= ix < width and 0 <= iy < height and depth(s, x, y) > nearest[iy, ix]:
                    nearest[iy, ix], splat[iy, ix] = depth(s, x, y), s
        for y in range(height):
            for x in range(width):
                candidates = [own_labels[y, x]] + [
                    splat[ny, nx]
                    for ny in range(max(y - 1, 0), min(y + 2, height))
                    for nx in range(max(x - 1, 0), min(x + 2, width))
                ]
                best, best_d = HIDDEN, -np.inf
                for c in candidates:
                    if c < 0:
                        continue
                    px, py = mapped(ref_from_t[c, t], x, y)
                    ix, iy = int(np.floor(px + 0.5)), int(np.floor(py + 0.5))
                    inside = 0 <= ix < width and 0 <= iy < height
                    if inside and labels[iy, ix] != c:
                        continue
                    if not inside and (c != own_labels[y, x] or own is not None):
                        continue
                    if depth(c, px, py) > best_d:
                        best, best_d = c, depth(c, px, py)
                out[t, y, x] = best
    return out


@pytest.mark.parametrize("with_own", [False, True])
def test_every_pixel_shows_the_segment_the_rule_defines(with_own):
    from stereodeblur.blur.visibility import visible_labels
    from stereodeblur.geometry.plane import plane_in_view

    shape = (18, 24)
    sf = random_sceneflow(shape, 5, grid=(3, 4), speed=3.0)
    fractions = EXPOSURE.sample_fractions(6) + (1.0 if with_own else 0.0)
    ref_from_t = sf.homographies(fractions)
    center = sf.camera.center(sf.view)
    planes = np.stack([plane_in_view(n, center) for n in sf.normals]) @ sf.camera.K_inv
    own = np.roll(sf.labels, 2, axis=1) if with_own else None
    visible = visible_labels(ref_from_t, sf.labels, planes, own=own)
    expected = _visible_by_definition(ref_from_t, sf.labels, planes, own)
    assert (visible == HIDDEN).any() and (visible != sf.labels).mean() > 0.02
    np.testing.assert_array_equal(visible, expected)
