import numpy as np
import pytest

from stereodeblur.viz import (
    color_wheel,
    disparity_to_color,
    flow_to_color,
    mask_to_image,
    segment_overlay,
)


def _color_of(u, v, max_flow=1.0):
    flow = np.array([[[u, v]]], dtype=np.float64)
    return flow_to_color(flow, max_flow=max_flow)[0, 0].astype(int)


def test_colour_wheel_has_the_middlebury_segments():
    wheel = color_wheel()
    assert wheel.shape == (55, 3)
    np.testing.assert_array_equal(wheel[0], [255, 0, 0])  # red
    np.testing.assert_array_equal(wheel[15], [255, 255, 0])  # yellow
    np.testing.assert_array_equal(wheel[21], [0, 255, 0])  # green
    np.testing.assert_array_equal(wheel[25], [0, 255, 255])  # cyan
    np.testing.assert_array_equal(wheel[36], [0, 0, 255])  # blue
    np.testing.assert_array_equal(wheel[49], [255, 0, 255])  # magenta


def test_known_flow_colours():
    right = _color_of(1, 0)  # Middlebury: flow to the right is red
    assert right[0] == 255 and right[1] < 20 and right[2] < 20
    left = _color_of(-1, 0)  # to the left: cyan-ish (green + blue)
    assert left[0] < 60 and left[1] > 180 and left[2] > 180
    up = _color_of(0, -1)  # up: blue-ish
    assert up[2] > 200 and up[0] < 150 and up[1] < 150
    down = _color_of(0, 1)  # down: yellow-green
    assert down[0] > 150 and down[1] > 200 and down[2] < 50
    zero = _color_of(0, 0)
    np.testing.assert_array_equal(zero, [255, 255, 255])  # no motion is white
    half = _color_of(0.5, 0)  # half the maximum: a paler red
    assert half[0] == 255 and 100 < half[1] < 160 and half[1] == half[2]


def test_flow_image_shape_and_holes():
    flow = np.zeros((4, 5, 2))
    flow[1, 2] = np.nan
    rgb = flow_to_color(flow)
    assert rgb.shape == (4, 5, 3) and rgb.dtype == np.uint8
    np.testing.assert_array_equal(rgb[1, 2], [0, 0, 0])
    with pytest.raises(ValueError):
        flow_to_color(np.zeros((4, 5)))


def test_disparity_colours_are_ordered_and_holes_black():
    d = np.array([[1.0, 5.0, 10.0, np.nan, -1.0]])
    rgb = disparity_to_color(d, max_disparity=10.0)
    assert rgb.dtype == np.uint8
    assert rgb[0, 2, 0] > rgb[0, 0, 0]  # near is red
    assert rgb[0, 0, 2] > rgb[0, 2, 2]  # far is blue
    np.testing.assert_array_equal(rgb[0, 3], [0, 0, 0])
    np.testing.assert_array_equal(rgb[0, 4], [0, 0, 0])


def test_segment_overlay_marks_boundaries_only():
    image = np.full((6, 6), 0.5, np.float32)
    labels = np.zeros((6, 6), np.int32)
    labels[:, 3:] = 1
    rgb = segment_overlay(image, labels, color=(255, 0, 0))
    marked = np.all(rgb == [255, 0, 0], axis=-1)
    assert marked[:, 2].all()
    assert not marked[:, [0, 1, 3, 4, 5]].any()
    np.testing.assert_array_equal(rgb[0, 0], [128, 128, 128])


def test_mask_picture_plain_and_tinted():
    mask = np.array([[True, False]])
    np.testing.assert_array_equal(mask_to_image(mask), [[[255] * 3, [0] * 3]])
    tinted = mask_to_image(mask, np.zeros((1, 2)), color=(255, 0, 0), opacity=1.0)
    np.testing.assert_array_equal(tinted, [[[255, 0, 0], [0, 0, 0]]])


def test_caption_sits_above_the_unchanged_picture():
    from stereodeblur.viz import caption_strip, disparity_key, flow_key, with_caption

    picture = disparity_to_color(np.linspace(0.5, 9.0, 48 * 64).reshape(48, 64))
    lines = ["Disparity, left view.", "Colour: turbo scale from 0 px to 9 px; black: unknown."]
    out = with_caption(picture, lines, key=disparity_key(9.0, 64))
    strip = out.shape[0] - picture.shape[0]
    assert out.shape[1:] == picture.shape[1:] and strip > 30
    np.testing.assert_array_equal(out[strip:], picture)
    assert (out[:strip] > 200).all(axis=-1).sum() > 50  # white letters on the dark strip
    # A narrow picture wraps its caption onto more lines instead of cutting it.
    assert caption_strip(lines, 64).shape[0] > caption_strip(lines, 640).shape[0]
    key = flow_key(4.0)
    np.testing.assert_array_equal(key[20, 20], [255, 255, 255])  # zero flow at the centre
    assert key[20, 40][0] < 255 * 0.8 and key[20, 40][0] > key[20, 40][2]  # right: dark red
