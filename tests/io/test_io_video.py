"""Video pairs read lazily and bit-exactly from lossless encodings; bad pairs: one-line errors."""

import json

import numpy as np
import pytest

from stereodeblur.errors import InputError
from stereodeblur.io import video as video_module
from stereodeblur.io.formats import srgb_to_linear
from stereodeblur.io.sources import open_source
from stereodeblur.io.video import write_video
from tests.io.stereo_layouts import to_u8, write_video_pair

K = np.array([[40.0, 0.0, 15.5], [0.0, 40.0, 11.5], [0.0, 0.0, 1.0]])
NUM_FRAMES = 7


def _clip(seed, size=(24, 32)):
    rng = np.random.default_rng(seed)
    return [to_u8(rng.random((*size, 3))) for _ in range(NUM_FRAMES)]


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    left, right = _clip(1), _clip(2)
    paths = write_video_pair(
        tmp_path_factory.mktemp("pair"), [f / 255 for f in left], [f / 255 for f in right], K,
        0.1, frame_rate=25.0,
    )  # fmt: skip
    return paths, left, right


@pytest.mark.parametrize("codec, suffix", [("FFV1", "mkv"), ("png ", "avi"), ("HFYU", "avi")])
def test_lossless_codecs_read_back_exactly(codec, suffix, tmp_path):
    frames = _clip(3)
    write_video(tmp_path / f"l.{suffix}", frames, frame_rate=20.0, codec=codec)
    write_video(tmp_path / f"r.{suffix}", frames[::-1], frame_rate=20.0, codec=codec)
    calib = tmp_path / "calib.yml"
    calib.write_text(
        "P1: !!opencv-matrix\n  rows: 3\n  cols: 4\n  dt: d\n  data: [40, 0, 15.5, 0, 0, 40, "
        "11.5, 0, 0, 0, 1, 0]\nP2: !!opencv-matrix\n  rows: 3\n  cols: 4\n  dt: d\n  data: [40, "
        "0, 15.5, -4, 0, 40, 11.5, 0, 0, 0, 1, 0]\n"
    )
    source = open_source([tmp_path / f"l.{suffix}", tmp_path / f"r.{suffix}"], calib=calib,
                         exposure=0.01)  # fmt: skip
    assert source.num_frames == NUM_FRAMES and source.info.camera.baseline == pytest.approx(0.1)
    for i in range(NUM_FRAMES):
        np.testing.assert_array_equal(
            source.read_frame("left", i, linear=False), frames[i] / np.float32(255)
        )
        np.testing.assert_array_equal(
            source.read_frame("right", i, linear=False), frames[-1 - i] / np.float32(255)
        )


def test_frames_are_read_lazily_in_any_order(pair, monkeypatch):
    (left_path, right_path, calib), left, right = pair
    source = open_source([left_path, right_path], calib=calib, exposure=0.01)
    assert source.kind == "video" and source.shape == (24, 32) and source.channels == 3
    assert source.info.exposure.frame_rate == 25.0  # from the container
    decoded = []
    original = source._decode
    monkeypatch.setattr(source, "_decode", lambda v, i: decoded.append((v, i)) or original(v, i))
    for i in [5, 1, 2, 6, 0, 2, 3]:
        np.testing.assert_array_equal(
            source.read_frame("left", i, linear=False), left[i] / np.float32(255)
        )
    np.testing.assert_array_equal(
        source.read_frame("right", 4, linear=False), right[4] / np.float32(255)
    )
    # Frame 2 the second time comes from the small cache; nothing is decoded in advance.
    assert decoded == [("left", i) for i in [5, 1, 2, 6, 0, 3]] + [("right", 4)]
    assert all(len(c) <= video_module.CACHE_FRAMES for c in source._cache.values())


def test_a_video_is_srgb_unless_its_calibration_or_color_says(pair, tmp_path):
    """Video files are camera output: sRGB by default (an OpenCV calibration, a camera.json
    without "color"); a camera.json with "color" or color='linear' overrides."""
    (left_path, right_path, calib), left, _ = pair
    stored = left[0] / np.float32(255)
    source = open_source([left_path, right_path], calib=calib, exposure=0.01)
    assert source.info.color == "srgb"
    np.testing.assert_array_equal(source.read_frame("left", 0), srgb_to_linear(stored))
    np.testing.assert_array_equal(source.read_frame("left", 0, linear=False), stored)
    camera = {"format": "stereo-video/1", "K": K.tolist(), "baseline": 0.1,
              "frame_rate": 25.0, "exposure": 0.02}  # fmt: skip
    (tmp_path / "camera.json").write_text(json.dumps(camera))
    source = open_source([left_path, right_path], calib=tmp_path / "camera.json")
    assert source.info.color == "srgb"
    (tmp_path / "camera.json").write_text(json.dumps({**camera, "color": "linear"}))
    source = open_source([left_path, right_path], calib=tmp_path / "camera.json")
    assert source.info.color == "linear"
    np.testing.assert_array_equal(source.read_frame("left", 0), stored)
    source = open_source([left_path, right_path], calib=calib, exposure=0.01, color="linear")
    np.testing.assert_array_equal(source.read_frame("left", 0), stored)


def test_options_and_camera_json_give_timing_and_colour(pair, tmp_path):
    (left_path, right_path, _), left, _ = pair
    camera = {"format": "stereo-video/1", "K": K.tolist(), "baseline": 0.1,
              "frame_rate": 30.0, "exposure": 0.02, "color": "srgb"}  # fmt: skip
    (tmp_path / "camera.json").write_text(json.dumps(camera))
    source = open_source([left_path, right_path], calib=tmp_path / "camera.json")
    assert source.info.exposure.exposure == 0.02 and source.info.color == "srgb"
    assert source.info.exposure.frame_rate == 25.0  # the container's rate wins over the file's
    np.testing.assert_allclose(
        source.read_frame("left", 0), srgb_to_linear(left[0] / np.float32(255)), rtol=1e-6
    )
    source = open_source([left_path, right_path], calib=tmp_path / "camera.json",
                         frame_rate=24.0, exposure=0.01, color="linear")  # fmt: skip
    assert (source.info.exposure.frame_rate, source.info.exposure.exposure) == (24.0, 0.01)
    np.testing.assert_array_equal(source.read_frame("left", 0), left[0] / np.float32(255))


def test_videos_of_different_lengths_use_the_common_frames(pair, tmp_path):
    (left_path, _, calib), _, right = pair
    short = write_video(tmp_path / "short.mkv", right[:5], frame_rate=25.0)
    source = open_source([left_path, short], calib=calib, exposure=0.01)
    assert source.num_frames == 5
    assert len(source.warnings) == 1 and "using the first 5" in source.warnings[0]


@pytest.mark.parametrize(
    "case, fragment",
    [
        ("no calibration", "needs calib"),
        ("not a video", "not a readable video"),
        ("different sizes", "one size"),
        ("different frame rates", "frames per second"),
        ("same file twice", "same file"),
        ("missing exposure", "give exposure in seconds"),
        ("exposure too long", "longer than the frame interval"),
    ],
)
def test_bad_video_pairs(case, fragment, pair, tmp_path):
    (left, right, calib), frames, _ = pair
    options = {"calib": calib, "exposure": 0.01}
    if case == "no calibration":
        options["calib"] = None
    elif case == "not a video":
        right = tmp_path / "notes.mkv"
        right.write_text("not a video")
    elif case == "different sizes":
        right = write_video(tmp_path / "big.mkv", [np.zeros((48, 64, 3), np.uint8)] * 3,
                            frame_rate=25.0)  # fmt: skip
    elif case == "different frame rates":
        right = write_video(tmp_path / "slow.mkv", frames, frame_rate=12.5)
    elif case == "same file twice":
        right = left
    elif case == "missing exposure":
        options["exposure"] = None
    elif case == "exposure too long":
        options["exposure"] = 0.05
    with pytest.raises(InputError, match=fragment) as error:
        open_source([left, right], **options)
    assert "\n" not in str(error.value)
