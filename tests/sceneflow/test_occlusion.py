import numpy as np

from stereodeblur.sceneflow.occlusion import motion_boundary_band, occlusion_masks


def test_pixels_leaving_the_view_are_marked():
    H, W = 20, 30
    labels = np.zeros((H, W), np.int32)
    flow = np.zeros((H, W, 2))
    flow[..., 0] = 4.0  # everything moves 4 px right
    d = np.full((H, W), 5.0)
    masks = occlusion_masks(d, flow, d, labels)
    expected = np.zeros((H, W), bool)
    expected[:, W - 4 :] = True  # x + 4 > W - 0.5
    np.testing.assert_array_equal(masks.out_of_view, expected)
    assert not masks.occluded.any()
    assert not masks.motion_boundary.any()
    np.testing.assert_array_equal(masks.combined, expected)


def test_a_near_segment_moving_over_a_far_one_hides_it():
    H, W = 20, 40
    labels = np.zeros((H, W), np.int32)
    labels[:, 10:20] = 1  # near strip
    flow = np.zeros((H, W, 2))
    flow[labels == 1, 0] = 6.0  # moves right over the static background
    d = np.where(labels == 1, 10.0, 2.0)
    masks = occlusion_masks(d, flow, d, labels)
    hidden = masks.occluded
    # Background pixels x = 20..25 are covered by the strip's pixels at t + 1.
    assert hidden[:, 20:26].all()
    assert not hidden[:, :20].any()
    assert not hidden[:, 26:].any()
    # Flow jumps by 6 px at both borders of the strip: a band of radius 3.
    band = masks.motion_boundary
    assert band[:, 7:13].all() and band[:, 17:23].all()
    assert not band[:, :6].any() and not band[:, 24:].any()


def test_right_view_occlusion_from_the_z_buffer():
    H, W = 10, 40
    labels = np.zeros((H, W), np.int32)
    d = np.full((H, W), 2.0)
    d[:, 20:30] = 8.0  # a near strip: background just left of it is hidden in the right view
    masks = occlusion_masks(d, np.zeros((H, W, 2)), d, labels)
    lr = masks.left_right
    assert lr[:, 14:18].all()  # x - 2 lands where the strip (x - 8) lands
    assert not lr[:, :12].any()
    assert not lr[:, 20:].any()
    assert not masks.combined.any()  # not part of the reference view's mask


def test_forward_backward_check():
    H, W = 10, 20
    labels = np.zeros((H, W), np.int32)
    flow = np.zeros((H, W, 2))
    back = np.zeros((H, W, 2))
    back[:, 5:8, 0] = 5.0  # backward flow disagrees there
    initial = flow.copy()
    initial[:, 5:8, 1] = 3.0  # and so does the initial forward flow
    d = np.ones((H, W))
    masks = occlusion_masks(d, flow, d, labels, backward_flow=back, initial_flow=initial)
    assert masks.inconsistent[:, 5:8].all()
    assert masks.inconsistent.sum() == 3 * H


def test_band_radius_grows_with_the_flow_jump():
    labels = np.zeros((1, 60), np.int32)
    labels[:, 30:] = 1
    flow = np.zeros((1, 60, 2))
    flow[:, 30:, 0] = 12.0
    band = motion_boundary_band(labels, flow)
    assert band[0].sum() == 14  # radius 6 around the border pair (29, 30)
    flow[:, 30:, 0] = 0.4  # below the threshold
    assert not motion_boundary_band(labels, flow).any()
